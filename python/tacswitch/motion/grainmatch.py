"""The gel's lateral motion between two real frames, measured by local block matching of its grain.

A real gel's coating carries a weak fixed-pattern grain (on taxim's GelSight and GelSight Mini
presses about 0.3 grey levels under 0.5 of temporal noise) that moves with the gel. Each patch
(``patch`` px square) of the high-passed reference is located in the high-passed frame by
normalised cross-correlation over a ``+-search`` px window (``cv2.matchTemplate``, one integer
peak refined by a parabola per axis): a purely local estimate, unlike coarse-to-fine variational
flow (DIS), whose large motion at the imprint can leak outward. Used to measure the real gel's
motion around real presses (``benches/studies/bench_press_calibration.py``), which calibrates the
simulator's press law (:mod:`tacswitch.sim.presets`, ``GELSIGHT_PRESS_DILATION``...).

Conventions: frames ``H x W x 3`` uint8 BGR (or ``H x W`` grey), points ``(x, y)`` px with pixel
centres at integers, displacement ``(dx, dy)`` px: the gel at ``X`` in ``ref`` is at ``X + d``
in ``img``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["fit_similarity", "highpass", "match_patches", "press_profile", "radial_rings",
           "robust_lstsq", "similarity_at", "similarity_rows"]


def highpass(img: NDArray[np.uint8], sigma: float = 3.0) -> NDArray[np.float32]:
    """Grey level minus its Gaussian blur (``sigma`` px): the grain, without the shading."""
    import cv2

    a: Any = np.asarray(img)
    if a.ndim == 3:
        a = cv2.cvtColor(a, cv2.COLOR_BGR2GRAY)
    g = np.asarray(a, np.float32)
    return (g - cv2.GaussianBlur(g, (0, 0), sigma)).astype(np.float32)


def _parabola(m: float, c: float, p: float) -> float:
    den = m - 2 * c + p
    return 0.0 if den >= 0 else float(np.clip(0.5 * (m - p) / den, -0.5, 0.5))


def match_patches(ref_hp: NDArray[np.float32], img_hp: NDArray[np.float32], pts: NDArray,
                  *, patch: int = 48, search: int = 8
                  ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Displacement ``N x 2`` (px) of the ``patch``-px square of ``ref_hp`` centred at each point
    of ``pts`` (rounded to a pixel) in ``img_hp``, and its correlation peak ``N`` (in [-1, 1]);
    points whose window leaves the frame give NaN. Inputs are :func:`highpass` images."""
    import cv2

    if patch < 8 or search < 1:
        raise ValueError(f"patch, search: need patch >= 8 and search >= 1; got {patch}, {search}")
    h, w = ref_hp.shape
    half = patch // 2
    out = np.full((len(pts), 2), np.nan, np.float32)
    peak = np.full(len(pts), np.nan, np.float32)
    for n, (x, y) in enumerate(np.rint(np.asarray(pts, np.float64)).astype(int)):
        x0, y0 = x - half, y - half
        if x0 - search < 0 or y0 - search < 0 or x0 + patch + search > w or \
                y0 + patch + search > h:
            continue
        tpl = ref_hp[y0:y0 + patch, x0:x0 + patch]
        reg = img_hp[y0 - search:y0 + patch + search, x0 - search:x0 + patch + search]
        cc = cv2.matchTemplate(reg, tpl, cv2.TM_CCOEFF_NORMED)
        iy, ix = np.unravel_index(int(np.argmax(cc)), cc.shape)
        dx = dy = 0.0
        if 0 < ix < cc.shape[1] - 1:
            dx = _parabola(cc[iy, ix - 1], cc[iy, ix], cc[iy, ix + 1])
        if 0 < iy < cc.shape[0] - 1:
            dy = _parabola(cc[iy - 1, ix], cc[iy, ix], cc[iy + 1, ix])
        out[n] = (ix - search + dx, iy - search + dy)
        peak[n] = cc[iy, ix]
    return out, peak


def fit_similarity(pts: NDArray, disp: NDArray, about: tuple[float, float]
                   ) -> NDArray[np.float64]:
    """Least-squares small similarity ``(tx, ty, zoom, rot)`` of displacements ``disp`` at
    ``pts``: ``d = t + zoom * (X - about) + rot * perp(X - about)`` (NaN rows ignored)."""
    ok = np.isfinite(disp).all(1)
    rel = np.asarray(pts, np.float64)[ok] - np.asarray(about, np.float64)
    n = len(rel)
    if n < 3:
        return np.zeros(4)
    a = np.zeros((2 * n, 4))
    a[:n, 0] = 1
    a[n:, 1] = 1
    a[:n, 2], a[n:, 2] = rel[:, 0], rel[:, 1]
    a[:n, 3], a[n:, 3] = -rel[:, 1], rel[:, 0]
    b = np.concatenate([disp[ok, 0], disp[ok, 1]]).astype(np.float64)
    return np.asarray(np.linalg.lstsq(a, b, rcond=None)[0], np.float64)


def similarity_at(params: NDArray, pts: NDArray, about: tuple[float, float]
                  ) -> NDArray[np.float64]:
    """The displacement ``N x 2`` of :func:`fit_similarity`'s ``params`` at ``pts``."""
    tx, ty, z, r = params
    rel = np.asarray(pts, np.float64) - np.asarray(about, np.float64)
    return np.stack([tx + z * rel[:, 0] - r * rel[:, 1], ty + z * rel[:, 1] + r * rel[:, 0]], 1)


def radial_rings(ref_hp: NDArray[np.float32], img_hp: NDArray[np.float32],
                 centre: tuple[float, float], radii: NDArray, *, patch: int = 48,
                 search: int = 8, min_peak: float = 0.08,
                 background: NDArray | None = None, about: tuple[float, float] = (0.0, 0.0)
                 ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Mean radial displacement (px, + = away from ``centre``) of patches on circles of each
    radius in ``radii`` (px) about ``centre``, patches spaced half a patch apart along the
    circle, inside the frame and with a correlation peak of at least ``min_peak``; with
    ``background`` (similarity params of :func:`fit_similarity` about ``about``) that motion is
    removed first. Returns the ring means (NaN for an empty ring) and the patches used."""
    means = np.full(len(radii), np.nan)
    counts = np.zeros(len(radii), np.int64)
    c = np.asarray(centre, np.float64)
    for k, r in enumerate(np.asarray(radii, np.float64)):
        m = max(8, int(2 * np.pi * r / (patch / 2)))
        ang = np.arange(m) * 2 * np.pi / m
        unit = np.stack([np.cos(ang), np.sin(ang)], 1)
        pts = c + r * unit
        found, pk = match_patches(ref_hp, img_hp, pts, patch=patch, search=search)
        d = found.astype(np.float64)
        if background is not None:
            d = d - similarity_at(background, pts, about)
        ok = np.isfinite(d).all(1) & (pk >= min_peak)
        counts[k] = int(ok.sum())
        if ok.any():
            means[k] = float((d[ok] * unit[ok]).sum(1).mean())
    return means, counts


def _hats(q: NDArray, knots: NDArray) -> NDArray[np.float64]:
    """Piecewise-linear (hat) basis ``len(q) x (len(knots) - 1)`` on ``knots``: the profile is
    linear between knots, flat inside the first and zero from the last knot on."""
    k = len(knots) - 1
    out = np.zeros((len(q), k))
    for j in range(k):
        hi = knots[j + 1]
        down = np.clip((hi - q) / (hi - knots[j]), 0.0, 1.0)
        if j == 0:
            out[:, j] = np.where(q < knots[0], 1.0, down)
        else:
            up = np.clip((q - knots[j - 1]) / (knots[j] - knots[j - 1]), 0.0, 1.0)
            out[:, j] = np.where(q < knots[j], up, down)
    return out


def press_profile(f0: NDArray[np.uint8], imgs: NDArray[np.uint8], centres: NDArray,
                  radii: NDArray, knots: NDArray, *, patch: int = 48, step: int = 16,
                  min_peak: float = 0.08, inner: float = 1.5
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The radial press profile shared by presses, separated from each capture's own motion.

    Every press ``imgs[i]`` is block-matched against the no-contact frame ``f0`` on a grid of
    patches (``step`` px apart, :func:`match_patches`); patches at ``r >= inner * a_i`` from the
    press's contact (``centres[i]``, radius ``radii[i]``, px) are fitted jointly, robustly (Huber
    weights, 3 reweightings), by a per-press similarity about the image centre (a shift / zoom /
    roll between the two captures) plus ``g(r / a_i)`` along the outward unit vector, ``g``
    piecewise linear in ``r / a`` on ``knots`` and zero from the last knot on (the assumption
    that separates a long-range press field from a zoom; the contacts' spread over the frame
    separates the rest). Returns ``g`` at ``knots[:-1]`` (px) and the per-press similarities
    ``P x 4`` (:func:`fit_similarity`'s parameters, about the image centre)."""
    knots = np.asarray(knots, np.float64)
    h, w = f0.shape[:2]
    cc = np.array([(w - 1) / 2, (h - 1) / 2])
    ys, xs = np.mgrid[patch:h - patch:step, patch:w - patch:step]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    hp0 = highpass(f0)
    n_p, n_k = len(imgs), len(knots) - 1
    blocks, rhs = [], []
    for j in range(n_p):
        d, pk = match_patches(hp0, highpass(imgs[j]), pts, patch=patch)
        rel = pts - np.asarray(centres[j], np.float64)
        r = np.hypot(rel[:, 0], rel[:, 1])
        ok = np.isfinite(d).all(1) & (pk >= min_peak) & (r >= inner * radii[j])
        unit = rel[ok] / r[ok, None]
        basis = _hats(r[ok] / radii[j], knots)
        relc = pts[ok] - cc
        for ax in (0, 1):
            a = similarity_rows(relc, j, ax, 4 * n_p + n_k)
            a[:, 4 * n_p:] = basis * unit[:, ax:ax + 1]
            blocks.append(a)
            rhs.append(d[ok, ax].astype(np.float64))
    x, _ = robust_lstsq(np.concatenate(blocks), np.concatenate(rhs))
    return x[4 * n_p:], x[:4 * n_p].reshape(n_p, 4)


def similarity_rows(rel: NDArray[np.float64], j: int, ax: int, n_cols: int
                    ) -> NDArray[np.float64]:
    """Design-matrix rows (``len(rel) x n_cols``) of displacement component ``ax`` (0: x,
    1: y) for frame ``j``'s small similarity (columns ``4 j .. 4 j + 3``: shift x, shift y,
    zoom, roll, as :func:`fit_similarity`) at points ``rel`` relative to its centre; the other
    columns are zero, for the caller's own terms."""
    a = np.zeros((len(rel), n_cols))
    a[:, 4 * j + ax] = 1.0
    a[:, 4 * j + 2] = rel[:, ax]
    a[:, 4 * j + 3] = -rel[:, 1] if ax == 0 else rel[:, 0]
    return a


def robust_lstsq(a: NDArray[np.float64], b: NDArray[np.float64], iterations: int = 4
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least squares ``a x ~ b`` reweighted ``iterations`` times with Huber weights at 1.5
    robust sigmas (MAD of the residuals), so the few grain patches that matched the wrong peak
    do not pull the fit. Returns ``(x, weights)`` (the weights of the last solve)."""
    wt: NDArray[np.float64] = np.ones(len(b))
    x: NDArray[np.float64] = np.zeros(a.shape[1])
    for _ in range(iterations):
        sw = np.sqrt(wt)
        x = np.asarray(np.linalg.lstsq(a * sw[:, None], b * sw, rcond=None)[0], np.float64)
        res = np.abs(b - a @ x)
        s = 1.4826 * float(np.median(res)) + 1e-9
        wt = np.minimum(1.0, 1.5 * s / np.maximum(res, 1e-12))
    return x, wt
