"""No-learning baseline: every marker moves outward from the contact, by the local image change.

A press pushes the gel outward around the contact, so "outward from the contact centroid, more
where the image changed more" is the motion a markerless frame suggests without any training
(issue 15 reports 0.67 mean direction cosine for such a rule on real GelSight frames). It is the
baseline learned methods must beat, implemented here as well as it can be without learning:

1. change map ``D``: with a reference frame, the colour distance between ``img`` (its global
   per-channel gain matched to ``ref`` first, so an exposure change is not contact) and ``ref``;
   single-frame, the distance between ``img`` and a smooth background estimate of the gel (a robust
   per-channel cubic polynomial fit, outliers — the imprint — rejected iteratively);
2. contact weights ``max(D - floor, 0)`` with the noise floor ``median(D) + 3 * 1.4826 * MAD``,
   smoothed over about a quarter of the marker pitch; the contact centre is their centroid;
3. each marker at ``X`` moves along ``(X - centre) / |X - centre|`` by
   ``OUTWARD_GAIN * pitch * w(X) / w_max``: the largest motion is ``OUTWARD_GAIN`` of the
   marker pitch (estimated from the centres), where the change is largest.

``OUTWARD_GAIN`` is not fitted to any evaluation data: it is the least-squares scale of this rule's
output against the true marker motion of the simulator's pure presses (40 per sensor, against the
no-contact frame: 0.030 pitch for the GelSight Mini preset, 0.023 for the GelSight; single-frame
0.027 and 0.043; ``python benches/bench_motion_real.py --calibrate-outward``). Pure presses move
the gel little sideways, hence the small scale. The direction, which the cosine metric scores,
does not depend on it.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["OUTWARD_GAIN", "background", "change_map", "outward_motion"]

#: Largest outward motion as a fraction of the marker pitch (see the module doc).
OUTWARD_GAIN = 0.03
#: Grid on which the single-frame background is fitted (cells across the width).
_FIT_WIDTH = 64


def _poly_terms(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y, x ** 3, x * x * y, x * y * y,
                     y ** 3], -1)


@functools.lru_cache(maxsize=8)
def _fit_basis(sh: int, sw: int) -> NDArray[np.float64]:
    """The cubic terms at the ``sh x sw`` fit grid's nodes (cached: a camera's frames share
    one size), read-only."""
    ys, xs = np.mgrid[0:sh, 0:sw].astype(np.float64)
    basis = _poly_terms(2 * xs.ravel() / max(sw - 1, 1) - 1, 2 * ys.ravel() / max(sh - 1, 1) - 1)
    basis.flags.writeable = False
    return basis


def background(img: NDArray[np.uint8], iterations: int = 4) -> NDArray[np.float32]:
    """Smooth background estimate of the gel, ``H x W x C`` float32: a per-channel cubic
    polynomial in ``(x, y)`` fitted on a coarse grid, refitted ``iterations`` times without the
    pixels whose residual exceeds 2.5 robust sigmas (the contact imprint, dust)."""
    import cv2

    h, w = img.shape[:2]
    a = img.reshape(h, w, -1).astype(np.float32)
    sw = min(_FIT_WIDTH, w)
    sh = max(1, round(h * sw / w))
    small = np.asarray(cv2.resize(a, (sw, sh), interpolation=cv2.INTER_AREA),
                       np.float64).reshape(sh, sw, -1)
    basis = _fit_basis(sh, sw)
    vals = small.reshape(-1, small.shape[2])
    keep = np.ones(len(vals), bool)
    coef: NDArray[Any] = np.zeros((basis.shape[1], vals.shape[1]))
    for _ in range(iterations + 1):
        # Normal equations: 10 cubic terms on [-1, 1] are well conditioned, and solving the
        # 10 x 10 system is several times cheaper than an SVD least squares on every refit.
        bk = basis[keep]
        coef = np.linalg.solve(bk.T @ bk, bk.T @ vals[keep])
        res = np.linalg.norm(vals - basis @ coef, axis=1)
        sigma = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep]))) + 1e-6
        new = res < np.median(res[keep]) + 2.5 * sigma
        if new.sum() < basis.shape[1] * 3 or np.array_equal(new, keep):
            break
        keep = new
    # The fit at the coarse nodes, bilinearly upsampled (INTER_LINEAR maps node centres to the
    # full frame's pixel centres as INTER_AREA averaged them): a cubic is smooth at this scale.
    fit = (basis @ coef).astype(np.float32).reshape(sh, sw, -1)
    out = cv2.resize(fit, (w, h), interpolation=cv2.INTER_LINEAR)
    return np.asarray(out, np.float32).reshape(h, w, -1)


def change_map(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None) -> NDArray[np.float32]:
    """Per-pixel colour distance ``H x W`` float32 (grey levels) between ``img`` and ``ref``
    (gain-matched) or, without ``ref``, the :func:`background` estimate of ``img``."""
    a = img.reshape(img.shape[0], img.shape[1], -1).astype(np.float32)
    if ref is None:
        b = background(img)
    else:
        b = ref.reshape(a.shape).astype(np.float32)
        # Global per-channel gain (exposure / white balance) matched on the whole frame: a
        # contact changes a small part of it, a drift all of it.
        gain = b.reshape(-1, a.shape[2]).mean(0) / np.maximum(a.reshape(-1, a.shape[2]).mean(0),
                                                              1.0)
        a = a * gain.astype(np.float32)
    # OpenCV's per-pixel arithmetic: the same distance, faster than numpy's temporaries.
    import cv2

    diff = cv2.subtract(a, b)
    sq = cv2.multiply(diff, diff).reshape(a.shape[0], a.shape[1], a.shape[2])
    total = cv2.transform(sq, np.ones((1, a.shape[2]), np.float32))
    return np.asarray(cv2.sqrt(total), np.float32).reshape(a.shape[:2])


def _pitch(centres: NDArray[np.float32]) -> float:
    if len(centres) < 2:
        return 1.0
    d = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(1)))


def outward_motion(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None,
                   centres: NDArray[np.float32], *, gain: float = OUTWARD_GAIN
                   ) -> NDArray[np.float32]:
    """Motion ``N x 2`` float32 ``(dx, dy)`` px of markers at rest ``centres`` (``(x, y)`` px) by
    the outward-from-contact rule (module doc); ``ref`` may be None (single frame). Zero where
    no pixel rises above the noise floor (no contact)."""
    import cv2

    from tacswitch.motion.mechanics import check_gain

    gain = check_gain(gain)
    n = len(centres)
    if n == 0 or (ref is not None and np.array_equal(img, ref)):
        return np.zeros((n, 2), np.float32)
    pitch = _pitch(centres)
    d = change_map(img, ref)
    sub = d[::2, ::2]
    med = float(np.median(sub))
    floor = med + 3.0 * 1.4826 * float(np.median(np.abs(sub - med)))
    wmap = np.maximum(d - floor, 0.0).astype(np.float32)
    wmap = cv2.GaussianBlur(wmap, (0, 0), max(1.0, pitch / 4))
    total = float(wmap.sum())
    wmax = float(wmap.max())
    if total <= 0 or wmax <= 0:
        return np.zeros((n, 2), np.float32)
    ys, xs = np.mgrid[0:d.shape[0], 0:d.shape[1]]
    centre = np.array([(wmap * xs).sum() / total, (wmap * ys).sum() / total], np.float32)
    from tacswitch.motion.flow import sample_field

    local = sample_field(np.repeat(wmap[..., None], 2, axis=2), centres)[:, 0] / wmax
    v = centres - centre
    r = np.linalg.norm(v, axis=1, keepdims=True)
    unit = np.divide(v, r, out=np.zeros_like(v), where=r > 1e-6)
    return (unit * (gain * pitch * local)[:, None]).astype(np.float32)
