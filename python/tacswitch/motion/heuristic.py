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
   smoothed over about a quarter of the marker pitch (on a box-averaged map where that blur
   would be wide on a big frame, :func:`_blur_factor`); the contact centre is their centroid;
3. each marker at ``X`` moves along ``(X - centre) / |X - centre|`` by
   ``OUTWARD_GAIN * pitch * w(X) / w_max``: the largest motion is ``OUTWARD_GAIN`` of the
   marker pitch (the centres' median nearest-neighbour distance, :func:`_pitch`), where the
   change is largest.

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

from tacswitch._checks import check_gain
from tacswitch.motion.flow import sample_field

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
        try:
            coef = np.linalg.solve(bk.T @ bk, bk.T @ vals[keep])
        except np.linalg.LinAlgError:
            # A fit grid too thin to fix every cubic term (a 9 x 2000 frame gives one row of
            # nodes: no y dependence to fit): the least-squares fit of minimum norm instead.
            coef = np.linalg.lstsq(bk, vals[keep], rcond=None)[0]
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


#: :func:`_pitch` measures every centre's nearest neighbour up to this many centres, and this
#: many evenly strided ones beyond (a median needs no more).
PITCH_QUERIES = 4096
#: Distances computed at once by a brute-force pass (bounds its memory, ~4 bytes each).
_CHUNK = 1 << 21


def _brute_nearest(pts: NDArray[np.float32], queries: NDArray[np.intp]) -> NDArray[np.float32]:
    """Distance from ``pts[queries]`` to their nearest other point (0 for a duplicate), against
    every point, in chunks of :data:`_CHUNK` distances."""
    out = np.empty(len(queries), np.float32)
    step = max(1, _CHUNK // len(pts))
    for i in range(0, len(queries), step):
        with np.errstate(over="ignore"):  # points 3e38 apart: an infinite distance
            d = np.linalg.norm(pts[queries[i:i + step], None, :] - pts[None, :, :], axis=2)
        # The smallest distance is the query to itself (0); the next its nearest other point,
        # 0 for a duplicate, as the N x N minimum with the diagonal excluded gave.
        out[i:i + step] = np.partition(d, 1, axis=1)[:, 1]
    return out


def _nearest(pts: NDArray[np.float32], queries: NDArray[np.intp]) -> NDArray[np.float32]:
    """:func:`_brute_nearest`'s distances, found among the points of the 3 x 3 cells of a
    grid around each query (cells 1.5 mean spacings wide, so a grid of markers has its
    neighbours there); a query whose nearest found lies farther than a cell, which the cells
    cannot vouch for, is measured against every point. Float32 distances computed as the
    brute force computes them: the same values."""
    n = len(pts)
    if not np.isfinite(pts).all():
        return _brute_nearest(pts, queries)
    lo = pts.min(0).astype(np.float64)
    ext = pts.max(0).astype(np.float64) - lo
    cell = 1.5 * float(np.sqrt(max(ext[0] * ext[1], 1.0) / n))
    # At most 2**20 cells a side (points spread along a line, or over 1e30 px).
    cell = max(cell, float(ext.max()) / 2**20, 1e-6)
    if not np.isfinite(cell):
        return _brute_nearest(pts, queries)
    ncol, nrow = int(ext[0] // cell) + 1, int(ext[1] // cell) + 1
    ix = np.clip(((pts[:, 0] - lo[0]) // cell).astype(np.int64), 0, ncol - 1)
    iy = np.clip(((pts[:, 1] - lo[1]) // cell).astype(np.int64), 0, nrow - 1)
    order = np.argsort(iy * ncol + ix, kind="stable")
    keys = (iy * ncol + ix)[order]
    qx, qy = ix[queries], iy[queries]
    rep_q, rep_p = [], []
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            cx, cy = qx + dx, qy + dy
            ok = (cx >= 0) & (cx < ncol) & (cy >= 0) & (cy < nrow)
            k = cy * ncol + cx
            start = np.searchsorted(keys, k, "left")
            count = np.where(ok, np.searchsorted(keys, k, "right") - start, 0)
            total = int(count.sum())
            if total > _CHUNK * 8:  # points piled in a few cells: no use for the grid
                return _brute_nearest(pts, queries)
            offs = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
            rep_q.append(np.repeat(np.arange(len(queries)), count))
            rep_p.append(order[np.repeat(start, count) + offs])
    q_all, p_all = np.concatenate(rep_q), np.concatenate(rep_p)
    with np.errstate(over="ignore"):
        d = np.linalg.norm(pts[queries][q_all] - pts[p_all], axis=1)
    srt = np.lexsort((d, q_all))
    first = np.searchsorted(q_all[srt], np.arange(len(queries)))
    has_two = np.bincount(q_all, minlength=len(queries)) >= 2
    out = np.full(len(queries), np.inf, np.float32)
    out[has_two] = d[srt][first[has_two] + 1]
    # Within 0.99 cell (float margin) the cells hold every closer point: the nearest is exact.
    far = ~(out <= 0.99 * cell)
    if far.any():
        out[far] = _brute_nearest(pts, queries[far])
    return out


def _pitch(centres: NDArray[np.float32]) -> float:
    """The median distance (px) from a centre to its nearest other centre (a duplicate counts:
    distance 0); 1.0 for fewer than two.

    Up to :data:`PITCH_QUERIES` centres, every one is measured (the value the N x N array it
    replaced gave); beyond, an even stride of that many is, against all centres. No N x N
    array: a grid finds the neighbours (:func:`_nearest`).
    """
    n = len(centres)
    if n < 2:
        return 1.0
    pts = np.ascontiguousarray(centres, np.float32)
    queries = np.arange(0, n, max(1, -(-n // PITCH_QUERIES)))
    return float(np.median(_nearest(pts, queries)))


#: Largest full-size blur :func:`outward_motion` runs, in pixels x kernel taps (a 640 x 480
#: frame up to sigma ~40 px, ~0.3 s); wider ones run on a box-averaged map.
_BLUR_BUDGET = 1e8


def _blur_factor(h: int, w: int, sigma: float) -> int:
    """Box-averaging factor before a Gaussian of ``sigma`` px on an ``h x w`` map: 1 (full size)
    within :data:`_BLUR_BUDGET`, else ``sigma // 4`` (at least 2), which leaves sigma >= 4 px."""
    taps = 2 * round(4 * sigma) + 1  # OpenCV's float kernel: +-4 sigma
    if h * w * taps <= _BLUR_BUDGET:
        return 1
    return max(2, int(sigma // 4))


def outward_motion(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None,
                   centres: NDArray[np.float32], *, gain: float = OUTWARD_GAIN
                   ) -> NDArray[np.float32]:
    """Motion ``N x 2`` float32 ``(dx, dy)`` px of markers at rest ``centres`` (``(x, y)`` px) by
    the outward-from-contact rule (module doc); ``ref`` may be None (single frame). Zero where
    no pixel rises above the noise floor (no contact)."""
    import cv2

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
    del d
    sigma = max(1.0, pitch / 4)
    h, w = wmap.shape
    k = _blur_factor(h, w, sigma)
    if k > 1:
        # A wide blur of a big frame (4000 x 4000 px, sigma ~90 px: minutes at full size) runs
        # on the k x k box average instead, sigma / k >= 4 px there: the map is smooth at that
        # scale, so its centroid, maximum and samples at the centres barely change.
        wmap = np.asarray(cv2.resize(wmap, (max(1, w // k), max(1, h // k)),
                                     interpolation=cv2.INTER_AREA), np.float32)
    wmap = cv2.GaussianBlur(wmap, (0, 0), sigma / k if k > 1 else sigma)
    total = float(wmap.sum())
    wmax = float(wmap.max())
    if total <= 0 or wmax <= 0:
        return np.zeros((n, 2), np.float32)
    # Centroid from the row and column sums (no H x W coordinate grids).
    cx = float(wmap.sum(0, dtype=np.float64) @ np.arange(wmap.shape[1])) / total
    cy = float(wmap.sum(1, dtype=np.float64) @ np.arange(wmap.shape[0])) / total
    # Pixel centres at integers on both grids: x = (x_small + 0.5) * sx - 0.5.
    sx, sy = w / wmap.shape[1], h / wmap.shape[0]
    centre = np.array([(cx + 0.5) * sx - 0.5, (cy + 0.5) * sy - 0.5], np.float32)
    at = centres if k == 1 else ((centres + 0.5) / np.array([sx, sy], np.float32)
                                 - 0.5).astype(np.float32)
    local = sample_field(np.repeat(wmap[..., None], 2, axis=2), at)[:, 0] / wmax
    v = centres - centre
    r = np.linalg.norm(v, axis=1, keepdims=True)
    unit = np.divide(v, r, out=np.zeros_like(v), where=r > 1e-6)
    return (unit * (gain * pitch * local)[:, None]).astype(np.float32)
