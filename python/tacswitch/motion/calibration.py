"""Self-calibration of the press gain on the user's own sensor, without markers.

How far a press moves the gel is a property of the gel (the real GelSight's gel moves outward
~2.5-3 px around a press, the real GelSight Mini's not measurably), not something one image
shows, so :func:`tacswitch.motion.mechanics.mechanics_motion` needs a per-sensor gain. This
module measures it from what every markerless sensor can record: one no-contact frame and a
few press frames. The gel's coating grain moves with the gel; block matching it
(:mod:`tacswitch.motion.grainmatch`) measures the real lateral motion ``d`` at patches away from
the imprint, and the gain is fitted jointly with a per-frame similarity (shift / zoom / roll
between the captures, about the image centre)::

    d_j(X) = s_j(X) + g * p_j(X)

``p_j``: the single-frame prediction at unit gain of the method the gain is for: the ensemble
(default, what ``predict_motion`` runs: ``ensemble_motion(frame, None, X, gain=1)``) or the
rule alone (``mechanics_motion(frame, None, X, gain=1)``). Robust least squares (Huber weights,
as :func:`~tacswitch.motion.grainmatch.press_profile`), ``g`` clamped at 0 (a gel that does
not move, or moves inward, gets 0: the rule then predicts zero, which is right for it).

Patches: every ``step`` px on the frame (``patch`` px squares, NCC peak >= ``min_peak``),
except where the imprint (the frame's change against the no-contact frame,
:func:`tacswitch.motion.mechanics.imprint`) covers more than 5 % of the patch: there the
shading change, not the grain, drives the match.

Units and conventions: frames ``H x W x 3`` uint8 BGR of one sensor at one size (any size: the
gain is dimensionless, the rule's output and the motion both scale with the frame width),
points ``(x, y)`` px with pixel centres at integers. Measured on taxim's real presses (even /
odd halves, 640 x 480), the rule: GelSight 0.284 / 0.300, Mini 0.036 / 0.036; the ensemble:
GelSight 0.288 / 0.303, Mini 0.039 / 0.037, explaining more of the grain's motion (0.64 / 0.64
vs 0.61 / 0.63 of it on GelSight, 0.16 / 0.15 vs 0.08 / 0.09 on the Mini). The rule,
area-downsampled to 320 x 240 (even half): GelSight 0.246 (``patch=48``) / 0.265
(``patch=24``), Mini 0.033 / 0.033 — the shipped gains
(:data:`tacswitch.sim.presets.MECHANICS_GAINS`, fitted at the marker grid >= 2 contact radii
away by ``benches/studies/bench_press_calibration.py``) are 0.25 and 0.04.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["PressGain", "calibrate_press_gain"]

#: Largest share of a patch the imprint may cover (the shading change corrupts the match).
MAX_IMPRINT_SHARE = 0.05


@dataclass(frozen=True)
class PressGain:
    """Result of :func:`calibrate_press_gain`.

    Attributes:
        gain: the gain to pass as ``predict_motion(..., gain=gain)`` (>= 0; for the method it
            was fitted for, :attr:`method`).
        raw_gain: the unclamped least-squares value (negative: the gel moved inward on
            average, or nothing measurable).
        stderr: its standard error (robust residual scale; patches treated as independent,
            so optimistic where neighbouring patches share grain).
        n_frames: press frames used; ``n_patches``: patches used over all frames.
        explained: share of the grain-matched motion (similarity removed) that ``raw_gain``
            times the rule explains, ``1 - |res|^2 / |d - s|^2`` (robust weights); near 0 when
            the gel does not move or the grain is too weak.
        peak: median NCC peak of the patches used (the grain's strength; taxim's real frames
            ~0.2-0.3).
    """

    gain: float
    raw_gain: float
    stderr: float
    n_frames: int
    n_patches: int
    explained: float
    peak: float
    method: str = "ensemble"


def _frame(img: Any, name: str) -> NDArray[np.uint8]:
    from tacswitch._checks import as_image_u8

    arr = as_image_u8(img, name)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"{name}: expected BGR H x W x 3 uint8 frames; got shape {arr.shape}")
    return arr


def _unit_prediction(method: str) -> Any:
    """``fn(frame, points)``: the single-frame motion of ``method`` at gain 1."""
    if method == "mechanics":
        from tacswitch.motion.mechanics import mechanics_motion

        return lambda im, pts: mechanics_motion(im, None, pts, gain=1.0)
    from tacswitch.motion.ensemble import ensemble_motion

    return lambda im, pts: ensemble_motion(im, None, pts, gain=1.0)


def calibrate_press_gain(no_contact: Any, frames: Any, centres: Any = None, *,
                         patch: int = 48, step: int = 16, min_peak: float = 0.08,
                         method: str = "ensemble") -> PressGain:
    """The press gain for this sensor, from a no-contact frame and press frames.

    Args:
        no_contact: the sensor's markerless no-contact frame, ``H x W x 3`` uint8 BGR.
        frames: markerless press frames of the same sensor and size (a sequence or an
            ``F x H x W x 3`` array): normal presses at different places (a few are enough:
            taxim's 24 GelSight presses pin the gain within ~10 %); shear or slip would be
            taken for press motion.
        centres: ``N x 2`` points ``(x, y)`` px where the gel's motion is measured (default: a
            grid every ``step`` px); those whose patch leaves the frame or meets the imprint
            are skipped.
        patch: block-matching patch side, px (>= 8; 48 at 640 x 480, the measurement's).
        step: default grid spacing, px (>= 1).
        min_peak: smallest NCC peak accepted, in [-1, 1).
        method: whose gain: ``"ensemble"`` (default: what ``predict_motion`` runs on a single
            frame or against the no-contact frame, :mod:`tacswitch.motion.ensemble`; its
            unit-gain prediction is the mean of the rule's and the learned model's, both scaled
            as ``gain=1`` scales them) or ``"mechanics"`` (the rule alone).

    Returns:
        :class:`PressGain`.

    Raises:
        ValueError: bad arguments, or fewer than 10 usable patches (no grain to match).
    """
    from tacswitch._checks import as_count, as_number, as_points
    from tacswitch.motion import grainmatch as gm
    from tacswitch.motion.mechanics import imprint

    if method not in ("ensemble", "mechanics"):
        raise ValueError(f"method: unknown {method!r}; choose 'ensemble' or 'mechanics'")
    predict = _unit_prediction(method)
    f0 = _frame(no_contact, "no_contact")
    if isinstance(frames, np.ndarray) and frames.ndim == 3:
        raise ValueError(f"frames: expected a sequence of H x W x 3 frames; got one array of "
                         f"shape {frames.shape}")
    try:
        imgs = [_frame(f, "frames") for f in frames]
    except TypeError:
        raise TypeError(f"frames: expected a sequence of BGR frames; got "
                        f"{type(frames).__name__}") from None
    if not imgs:
        raise ValueError("frames: need at least one press frame")
    for im in imgs:
        if im.shape != f0.shape:
            raise ValueError(f"frames: shape {im.shape} does not match no_contact {f0.shape}")
    h, w = f0.shape[:2]
    patch = as_count(patch, "patch", 8)
    if patch > min(h, w):
        raise ValueError(f"patch: a {patch} px patch does not fit the {h} x {w} frames")
    step = as_count(step, "step", 1)
    min_peak = as_number(min_peak, "min_peak", -1.0, 1.0)
    if min_peak >= 1:
        raise ValueError(f"min_peak: need a value in [-1, 1); got {min_peak!r}")
    if centres is None:
        ys, xs = np.mgrid[patch // 2:h - patch // 2:step, patch // 2:w - patch // 2:step]
        pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    else:
        pts = as_points(centres, "centres")
    if len(pts) == 0:
        raise ValueError("centres: no points")
    import cv2

    about = np.array([(w - 1) / 2, (h - 1) / 2])
    hp0 = gm.highpass(f0)
    ij = np.rint(pts).astype(int)
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
    ij = np.clip(ij, 0, [w - 1, h - 1])
    n_f = len(imgs)
    blocks, rhs, peaks = [], [], []
    for j, im in enumerate(imgs):
        changed = (imprint(im, f0) > 0).astype(np.float32)
        if not changed.any():
            continue  # the no-contact frame itself: nothing pressed
        d, pk = gm.match_patches(hp0, gm.highpass(im), pts, patch=patch)
        share = cv2.blur(changed, (patch, patch))[ij[:, 1], ij[:, 0]]
        ok = inside & np.isfinite(d).all(1) & (pk >= min_peak) & (share <= MAX_IMPRINT_SHARE)
        if not ok.any():
            continue
        p = predict(im, pts[ok]).astype(np.float64)
        rel = pts[ok].astype(np.float64) - about
        for ax in (0, 1):
            a = gm.similarity_rows(rel, j, ax, 4 * n_f + 1)
            a[:, -1] = p[:, ax]
            blocks.append(a)
            rhs.append(d[ok, ax].astype(np.float64))
        peaks.append(pk[ok])
    if not rhs:
        raise ValueError("frames: no press visible against no_contact (no imprint above the "
                         "noise floor in any frame)")
    n_patches = int(sum(len(b) for b in rhs) // 2)
    if n_patches < 10:
        raise ValueError(f"frames: only {n_patches} usable grain patches (NCC peak >= "
                         f"{min_peak}); the grain is too weak or the frames differ too much")
    a, b = np.concatenate(blocks), np.concatenate(rhs)
    used = np.abs(a).sum(0) > 0
    if not used[-1]:
        raise ValueError("frames: the rule predicts no motion on these frames (no imprint above "
                         "the noise floor: no press visible)")
    a = a[:, used]
    x, wt = gm.robust_lstsq(a, b)
    g = float(x[-1])
    res = b - a @ x
    moved = res + a[:, -1] * g
    explained = 1.0 - float((wt * res ** 2).sum()) / max(float((wt * moved ** 2).sum()), 1e-12)
    ata = (a * wt[:, None]).T @ a
    var = float(np.linalg.pinv(ata)[-1, -1])
    sigma2 = float((wt * res ** 2).sum()) / max(float(wt.sum()) - a.shape[1], 1.0)
    return PressGain(gain=max(0.0, g), raw_gain=g, stderr=float(np.sqrt(sigma2 * var)),
                     n_frames=n_f, n_patches=n_patches, explained=explained,
                     peak=float(np.median(np.concatenate(peaks))), method=method)
