"""Gel backgrounds, marker grids and anti-aliased marker rendering."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tacswitch.sim.presets import SensorPreset


def _rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def marker_grid(
    height: int,
    width: int,
    rows: int,
    cols: int,
    pitch: float,
    *,
    jitter: float = 0.0,
    seed: int | np.random.Generator | None = None,
) -> NDArray[np.float32]:
    """Centres ``(x, y)`` of a ``rows x cols`` grid with spacing ``pitch``, centred in the image.

    ``jitter`` adds Gaussian placement error (pixels, sigma), as on hand-painted gels.
    Returned in raster order (row by row), ``rows * cols x 2`` float32.
    """
    xs = (width - 1) / 2 + (np.arange(cols) - (cols - 1) / 2) * pitch
    ys = (height - 1) / 2 + (np.arange(rows) - (rows - 1) / 2) * pitch
    gx, gy = np.meshgrid(xs, ys)
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    if jitter > 0:
        pts = pts + _rng(seed).normal(0.0, jitter, pts.shape)
    return pts.astype(np.float32)


def gel_background(
    height: int,
    width: int,
    *,
    seed: int | np.random.Generator | None = None,
    base: tuple[float, float, float] = (175.0, 170.0, 180.0),
    gradient: float = 35.0,
) -> NDArray[np.float32]:
    """A GelSight-like no-contact background, ``H x W x 3`` float32 BGR in 0..255.

    Coloured LEDs on different sides give smooth per-channel gradients; ``gradient`` is their
    amplitude in grey levels. The direction of each channel's gradient is drawn from ``seed``.
    """
    rng = _rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    u, v = x / max(width - 1, 1) - 0.5, y / max(height - 1, 1) - 0.5
    img = np.empty((height, width, 3), np.float32)
    for c in range(3):
        angle = rng.uniform(0, 2 * np.pi)
        ramp = np.cos(angle) * u + np.sin(angle) * v
        vignette = 1.0 - 0.25 * (u * u + v * v)
        img[:, :, c] = (base[c] + gradient * ramp * rng.uniform(0.6, 1.4)) * vignette
    return img


def render_markers(
    background: NDArray,
    centres: NDArray,
    diameter: float | NDArray,
    *,
    darkness: float = 0.85,
    edge_px: float = 1.5,
    noise_sigma: float = 0.0,
    seed: int | np.random.Generator | None = None,
) -> NDArray[np.uint8]:
    """Paints soft round markers on a background and returns uint8 BGR.

    Each marker multiplies the background by ``1 - darkness * coverage``, where coverage rises
    linearly from 0 to 1 across a band of ``edge_px`` pixels centred on the dot's radius — the
    soft, partly transparent dots of real gels. Markers may overlap or leave the frame.

    Args:
        background: ``H x W x 3`` (or ``H x W``) float or uint8 background, 0..255.
        centres: ``N x 2`` marker centres ``(x, y)``, pixels.
        diameter: dot diameter in pixels, scalar or one per marker.
        darkness: fraction of the background removed at the centre (1 = black); negative values
            paint bright markers (-1 doubles the brightness at the centre).
        edge_px: width of the soft edge, pixels (> 0).
        noise_sigma: Gaussian camera noise added after painting, grey levels.
        seed: randomness for the noise.
    """
    img = np.array(background, dtype=np.float32, copy=True)
    h, w = img.shape[:2]
    pts = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    diam = np.broadcast_to(np.asarray(diameter, dtype=np.float64), (pts.shape[0],))
    edge = max(float(edge_px), 1e-3)
    shade = np.ones((h, w), np.float32)
    for (cx, cy), d in zip(pts, diam, strict=True):
        r = d / 2
        reach = r + edge
        x0, x1 = max(int(np.floor(cx - reach)), 0), min(int(np.ceil(cx + reach)), w - 1)
        y0, y1 = max(int(np.floor(cy - reach)), 0), min(int(np.ceil(cy + reach)), h - 1)
        if x0 > x1 or y0 > y1:
            continue
        yy, xx = np.mgrid[y0 : y1 + 1, x0 : x1 + 1]
        dist = np.hypot(xx - cx, yy - cy)
        cover = np.clip(0.5 - (dist - r) / edge, 0.0, 1.0).astype(np.float32)
        patch = shade[y0 : y1 + 1, x0 : x1 + 1]
        # Overlapping dots do not darken twice: the strongest one wins.
        combine = np.minimum if darkness >= 0 else np.maximum
        combine(patch, 1.0 - darkness * cover, out=patch)
    img *= shade if img.ndim == 2 else shade[:, :, None]
    if noise_sigma > 0:
        img += _rng(seed).normal(0.0, noise_sigma, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def render_preset(
    preset: SensorPreset,
    centres: NDArray | None = None,
    *,
    background: NDArray | None = None,
    noise: bool = True,
    seed: int | np.random.Generator | None = None,
) -> NDArray[np.uint8]:
    """Renders a preset's markers (at ``centres``, default its rest grid) on its background."""
    rng = _rng(seed)
    if background is None:
        background = gel_background(preset.height, preset.width, seed=rng)
    if centres is None:
        centres = marker_grid(preset.height, preset.width, preset.rows, preset.cols, preset.pitch)
    return render_markers(
        background,
        centres,
        preset.diameter,
        darkness=preset.darkness,
        edge_px=preset.edge_px,
        noise_sigma=preset.noise_sigma if noise else 0.0,
        seed=rng,
    )


def marker_layer(
    height: int,
    width: int,
    centres: NDArray,
    diameters: NDArray,
    darkness: NDArray,
    *,
    edge_px: float = 2.5,
    shape: NDArray | None = None,
) -> NDArray[np.float32]:
    """Transmittance of painted markers, ``H x W`` float32: 1 off the markers, ``1 - darkness``
    at a dot's centre.

    Each dot is an ellipse: the unit circle mapped by ``shape[n]`` (2x2, px per unit radius of
    a round dot; identity for a round dot: it carries the size/shape jitter of the painting and the
    local strain of the gel) times ``diameters[n] / 2``; its edge ramps linearly over ``edge_px``
    (soft, partly transparent edges of real dots). Overlapping dots do not darken twice: the
    darkest wins.

    Args:
        centres: ``N x 2`` ``(x, y)`` px. diameters, darkness: ``N``. shape: ``N x 2 x 2``.
    """
    pts = np.asarray(centres, np.float64).reshape(-1, 2)
    n = pts.shape[0]
    diam = np.broadcast_to(np.asarray(diameters, np.float64), (n,))
    dark = np.broadcast_to(np.asarray(darkness, np.float64), (n,))
    mats = np.broadcast_to(np.eye(2), (n, 2, 2)) if shape is None else np.asarray(shape)
    edge = max(float(edge_px), 1e-3)
    trans = np.ones((height, width), np.float32)
    for (cx, cy), d, k, a in zip(pts, diam, dark, mats, strict=True):
        r = d / 2
        inv = np.linalg.inv(a)
        # Reach of the ellipse plus its soft edge along x and y.
        reach = np.abs(a).sum(axis=1) * r + edge
        x0, x1 = max(int(np.floor(cx - reach[0])), 0), min(int(np.ceil(cx + reach[0])), width - 1)
        y0, y1 = max(int(np.floor(cy - reach[1])), 0), min(int(np.ceil(cy + reach[1])), height - 1)
        if x0 > x1 or y0 > y1:
            continue
        yy, xx = np.mgrid[y0 : y1 + 1, x0 : x1 + 1]
        qx = inv[0, 0] * (xx - cx) + inv[0, 1] * (yy - cy)
        qy = inv[1, 0] * (xx - cx) + inv[1, 1] * (yy - cy)
        # Distance from the ellipse rim in px, to first order (|q| - r scaled by the local size).
        qn = np.hypot(qx, qy)
        scale = np.hypot(*(a @ np.stack([qx.ravel(), qy.ravel()]))).reshape(qn.shape) / np.maximum(
            qn, 1e-9)
        dist = (qn - r) * np.where(qn > 1e-9, scale, 1.0)
        cover = np.clip(0.5 - dist / edge, 0.0, 1.0)
        patch = trans[y0 : y1 + 1, x0 : x1 + 1]
        np.minimum(patch, (1.0 - k * cover).astype(np.float32), out=patch)
    return trans
