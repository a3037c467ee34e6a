"""No-learning contact-mechanics rule: the gel's lateral motion from the contact imprint.

A normal press squeezes the (nearly incompressible) gel layer out from under the indenter: the
surface flows outward, most at the contact's edge, and the flow reaches beyond the visibly
changed region, fading over the press's reach. The simulator models it so
(:func:`tacswitch.sim.motion.contact_displacement`, ``dilation``): the lateral displacement is
``-dilation * thickness * grad(G_reach * indentation)``, a Gaussian of the reach smoothing the
indentation map; gain and reach measured on real presses (:mod:`tacswitch.sim.presets`).
This module applies the same law to the imprint that a markerless frame shows:

1. change map ``D`` (grey levels) of the frame against a reference or, single-frame, against a
   robust smooth background of itself (:func:`tacswitch.motion.heuristic.change_map`);
2. the imprint ``w = max(D - floor, 0)`` with the noise floor ``median(D) + 3 * 1.4826 * MAD``
   (the outward rule's), area-averaged onto a coarse grid (about 80 cells across: the field is
   smooth on the scale of a marker) and divided by its robust maximum ``w_top`` (the 98th
   percentile of the changed cells): its *shape* (where and how wide the gel is pressed), not
   its contrast, which depends on the sensor's lighting;
3. the displacement ``u = -gain * T^2 * grad(G_T * w / w_top)`` (``T``: the reach, px),
   read bilinearly at the markers.

Unlike the outward rule (motion only where the image changed), this field decays smoothly over
the reach outside the contact, as the simulated and the real GelSight gel do; a wider imprint
gives a larger motion. Tried and rejected on the simulator's pure presses (not on any
evaluation data): the raw contrast instead of the normalised shape (gains 4x apart between the
two presets) and a depth-like dome integrated from the imprint's slope (worse single-frame
direction).

Units and conventions: frames ``H x W x 3`` uint8 BGR, points and motion ``(x, y)`` px with pixel
centres at integers. The reach ``T`` defaults to :data:`REACH_FRAC` of the frame width: the real
GelSight's measured press reach, 5 mm on its ~18.9 mm wide field (170 px at 640 x 480, 85 px at
320 x 240; ``benches/studies/bench_press_calibration.py``; the GelSight Mini barely moves at all).

The gain: how far a press moves the gel is a property of the gel, not visible in one image, so
it is per sensor, fitted on REAL frames (the rule's least-squares scale against the real gel's
grain-matched motion around taxim's presses, ``benches/studies/bench_press_calibration.py``):
:data:`tacswitch.sim.presets.MECHANICS_GAINS`, GelSight 0.25, GelSight Mini 0.04 (its gel does
not measurably move); ``predict_motion(..., gain="gelsight")`` selects one, and
:func:`tacswitch.motion.calibration.calibrate_press_gain` measures it on any sensor from a
no-contact frame and a few markerless presses. :data:`MECHANICS_GAIN`, the default when no
sensor is named, is the least-squares gain pooled over both real sensors (0.25): the best single
gain on real data across both (held-out real presses: e_rmse 1.61 px on the GelSight against
2.22 for zero and 4.12 for the old gain; on the Mini ~0.3 px of false motion against ~1 px).
The old default, 1.02, was the least-squares scale on the simulator's pure presses when its
press law was calibrated for the wrong ball (pooled over both presets; GelSight 1.69 / 1.87 with
the reference / single-frame, Mini 0.008 / 0.009). Why the simulator then wanted ~7x the real
GelSight's gain: that calibration pressed a ball of radius drawn up to 6 mm to each recorded
contact, 0.3-0.5 mm deep, where the real imprints show taxim's 4 mm ball pressed 1.0-1.7 mm
deep (``REAL_BALL_RADIUS_MM`` of ``benches/proxies/motion_proxy.py``), so the fitted law moved
the gel ~3x too far per pressed volume. With the law refitted for that ball
(``python benches/studies/bench_motion_single.py --calibrate``) the simulator's pure presses want
0.57 / 0.64 on the GelSight, 0.35 pooled: within ~2x of the real gain. On ball presses alone
they want what taxim's real frames with the modelled field want (0.37 both, every marker
counted; the real 0.25 is fitted on markers >= 2 contact radii away); the simulator's other
shapes (cylinders, edges, knurls, fabrics) displace more gel per imprint than a ball, and the
rule sees an imprint's shape, not the volume it displaces. The direction, which the cosine
scores, does not depend on the gain.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import check_gain
from tacswitch.motion.flow import sample_field
from tacswitch.motion.heuristic import change_map
from tacswitch.sim.motion import thickness_blur
from tacswitch.sim.presets import MECHANICS_GAIN_POOLED

__all__ = ["MECHANICS_GAIN", "REACH_FRAC", "check_gain", "imprint",
           "mechanics_field", "mechanics_motion"]

#: The press's reach as a fraction of the frame width (5 mm / 18.9 mm, measured on the real
#: GelSight; see the module doc).
REACH_FRAC = 0.265
#: Default scale of the rule, with or without a reference (see the module doc).
MECHANICS_GAIN = MECHANICS_GAIN_POOLED
#: Coarse grid cells across the frame width.
_GRID_WIDTH = 80


def _step(width: int) -> int:
    return max(1, round(width / _GRID_WIDTH))


def imprint(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None) -> NDArray[np.float32]:
    """The contact imprint ``max(D - floor, 0)`` (grey levels, ``H x W`` float32) of ``img``
    against ``ref`` (None: single-frame, against the fitted background)."""
    d = change_map(img, ref)
    sub = d[::2, ::2]
    med = float(np.median(sub))
    floor = med + 3.0 * 1.4826 * float(np.median(np.abs(sub - med)))
    return np.maximum(d - floor, 0.0).astype(np.float32)


def mechanics_field(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None, *,
                    gain: float = MECHANICS_GAIN, thickness_px: float | None = None
                    ) -> tuple[NDArray[np.float32], int]:
    """The rule's displacement on its coarse grid, ``gh x gw x 2`` float32 px, and the grid step
    ``st`` (cell ``(i, j)`` averages pixels ``[j st, (j + 1) st)``; its centre is at
    ``((j + 0.5) st - 0.5, (i + 0.5) st - 0.5)``)."""
    import cv2

    h, w = img.shape[:2]
    st = _step(w)
    gh, gw = -(-h // st), -(-w // st)
    t_px = REACH_FRAC * w if thickness_px is None else float(thickness_px)
    wmap = imprint(img, ref)
    # cv2.resize with INTER_AREA needs an exact multiple for a true box average; pad by edge
    # replication to gh * st x gw * st first.
    pad = np.pad(wmap, ((0, gh * st - h), (0, gw * st - w)), mode="edge")
    coarse = np.asarray(cv2.resize(pad, (gw, gh), interpolation=cv2.INTER_AREA), np.float32)
    pos = coarse[coarse > 0]
    # A robust maximum (98th percentile of the changed cells): a single-frame background fit
    # can leave a small, intense residual (a dark corner) that must not set the scale.
    top = float(np.percentile(pos, 98)) if pos.size else 0.0
    if top <= 0:
        return np.zeros((gh, gw, 2), np.float32), st
    smooth = thickness_blur(coarse / np.float32(top), t_px / st)
    sm = smooth.astype(np.float64)
    # A very thin frame (9 x 2000 px) has a single row (or column) of cells: no gradient
    # across it, rather than np.gradient's error.
    gy, gx = (np.gradient(sm, float(st), axis=a) if sm.shape[a] > 1 else np.zeros_like(sm)
              for a in (0, 1))
    return (-gain * t_px * t_px * np.stack([gx, gy], -1)).astype(np.float32), st


def mechanics_motion(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None,
                     centres: NDArray[np.float32], *, gain: float = MECHANICS_GAIN,
                     thickness_px: float | None = None) -> NDArray[np.float32]:
    """Motion ``N x 2`` float32 ``(dx, dy)`` px of markers at rest ``centres`` (``(x, y)`` px) by
    the mechanics rule (module doc); ``ref`` may be None (single frame). Exactly zero for
    identical frames and where nothing rises above the noise floor."""
    gain = check_gain(gain)
    n = len(centres)
    if n == 0 or (ref is not None and np.array_equal(img, ref)):
        return np.zeros((n, 2), np.float32)
    if thickness_px is not None and not (np.isfinite(thickness_px) and thickness_px > 0):
        raise ValueError(f"thickness_px: must be a positive number of pixels; got "
                         f"{thickness_px!r}")
    fld, st = mechanics_field(img, ref, gain=gain, thickness_px=thickness_px)
    pts = ((np.asarray(centres, np.float32) + 0.5) / st - 0.5).astype(np.float32)
    return sample_field(fld, pts)
