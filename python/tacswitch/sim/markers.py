"""Gel backgrounds, marker grids, marker rendering, and realistic markers painted on any clean
frame (:func:`paint_markers`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch.sim.presets import SensorPreset, as_preset


def _rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    from tacswitch._checks import as_rng

    return as_rng(seed, "seed")


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
    pts = _centres(centres)
    img = np.array(background, dtype=np.float32, copy=True)
    h, w = img.shape[:2]
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


def _centres(centres: Any) -> NDArray[np.float64]:
    """``centres`` as ``N x 2`` float64 ``(x, y)`` (any array of 2N numbers); errors name it."""
    try:
        arr = np.asarray(centres, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise TypeError(f"centres: expected an N x 2 array of (x, y) points ({exc})") from None
    if arr.size % 2:
        raise ValueError(f"centres: expected an N x 2 array of (x, y) points; got shape "
                         f"{arr.shape}")
    pts = arr.reshape(-1, 2)
    bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if bad.size:
        raise ValueError(f"centres: point {int(bad[0])} is not finite "
                         f"({pts[bad[0], 0]}, {pts[bad[0], 1]})")
    return pts


def render_preset(
    preset: SensorPreset | str,
    centres: NDArray | None = None,
    *,
    background: NDArray | None = None,
    noise: bool = True,
    seed: int | np.random.Generator | None = None,
) -> NDArray[np.uint8]:
    """Renders a preset's markers (at ``centres``, default its rest grid) on its background;
    ``preset``: a :class:`SensorPreset` or its name."""
    preset = as_preset(preset)
    if centres is not None:
        centres = _centres(centres)
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


# --- Realistic marker appearance on any clean frame ------------------------------------------

#: Width of an erf edge from 10 % to 90 % coverage, in units of its Gaussian sigma.
_ERF_10_90 = 2.5631
#: A pixel belongs to a marker's footprint when painting changes it by more than this (grey
#: levels, any channel, before rounding): the pixels a fill must restore.
FOOTPRINT_LEVEL = 0.5

MarkerKind = Literal["pasted", "painted"]


def _erfc(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Complementary error function (Abramowitz & Stegun 7.1.26, absolute error < 1.5e-7;
    numpy has no erf and scipy is not a dependency)."""
    a = np.abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027
                                                                           + t * 1.061405429))))
    e = poly * np.exp(-a * a)
    return np.where(x >= 0, e, 2.0 - e)


@dataclass(frozen=True)
class MarkerStyle:
    """How a gel's markers look, for :func:`paint_markers`.

    A dot multiplies the clean frame by its transmittance ``T = 1 - darkness * core - halo``:

    - ``core`` rises from 0 to 1 across the rim with an erf profile whose 10-90 % width is
      ``edge_px`` (paint edges and lens blur are soft; real dots are not antialiased discs);
    - ``halo`` is a faint darkening just outside the rim, ``halo * exp(-(d - r) / halo_px)``,
      fading inside the dot (paint bleeding into the gel, and the skirt real dots show);
    - ``texture`` mottles painted dots: the darkness varies by a smooth random field of that
      relative amplitude (sigma), and each dot's darkness by ``level_jitter``.

    Attributes:
        kind: ``"pasted"`` (opaque black stickers / ink, GelSight) or ``"painted"`` (grey,
            partly transparent paint, GelSight Mini: the centre keeps 0.25-0.30 of the gel).
        diameter: dot diameter at 50 % coverage, px.
        darkness: fraction of the gel removed at a dot's centre (1: black).
        edge_px: 10-90 % width of the rim, px (> 0).
        halo: darkening just outside the rim, fraction of the gel (0: none).
        halo_px: decay length of the halo, px (> 0).
        texture: relative sigma of the in-dot mottling (0: uniform dots).
        level_jitter: relative sigma of each dot's darkness (0: all dots alike).

    The defaults are fitted to the two real GelSight Mini frames with markers (FOTS, 320x240):
    their mean radial profile around the dot centres (luma over the gel 10-14 px out) is
    0.27 at the centre, 0.51 at 5-6 px, 0.88 / 0.97 / 0.99 at 6-7 / 7-8 / 8-9 px; this style
    painted on flat gel matches it to 0.010 RMS, the in-dot mottling (0.03 of the gel, sigma)
    and the dot-to-dot spread of the centre level (0.095).
    """

    kind: MarkerKind = "painted"
    diameter: float = 11.5
    darkness: float = 0.73
    edge_px: float = 1.5
    halo: float = 0.05
    halo_px: float = 1.5
    texture: float = 0.05
    level_jitter: float = 0.12

    def __post_init__(self) -> None:
        if self.kind not in ("pasted", "painted"):
            raise ValueError(f"kind: expected 'pasted' or 'painted'; got {self.kind!r}")
        for name, lo, hi in (("diameter", 1e-3, np.inf), ("darkness", 0.0, 1.0),
                             ("edge_px", 1e-3, np.inf), ("halo", 0.0, 0.5),
                             ("halo_px", 1e-3, np.inf), ("texture", 0.0, 1.0),
                             ("level_jitter", 0.0, 0.5)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating, np.integer)) and lo <= v <= hi):
                raise ValueError(f"{name}: must be a number in [{lo}, {hi}]; got {v!r}")


def sample_style(rng: np.random.Generator | int | None = None, *,
                 kind: MarkerKind | None = None, diameter: float = 11.0) -> MarkerStyle:
    """A random realistic :class:`MarkerStyle`.

    Painted dots keep 0.25-0.30 of the gel at the centre (GelSight Mini), pasted ones 0-5 %
    (GelSight); rims 1.2-3 px wide (10-90 %; real Mini dots: 1.5 px plus their halo), halo
    0-6 % of the gel decaying over 1-2 px, mottling 2-8 % and dot-to-dot darkness spread
    3-15 % on painted dots (pasted: 0-3 %). ``diameter`` (px) is jittered by +-10 %.

    Args:
        rng: generator or seed.
        kind: force ``"pasted"`` or ``"painted"`` (default: either, equally likely).
        diameter: nominal dot diameter, px.
    """
    g = _rng(rng)
    drawn: MarkerKind = "pasted" if g.random() < 0.5 else "painted"
    k = drawn if kind is None else kind
    if k not in ("pasted", "painted"):
        raise ValueError(f"kind: expected 'pasted' or 'painted'; got {k!r}")
    painted = k == "painted"
    return MarkerStyle(
        kind=k,
        diameter=float(diameter * g.uniform(0.9, 1.1)),
        darkness=float(g.uniform(0.70, 0.75) if painted else g.uniform(0.95, 1.0)),
        edge_px=float(g.uniform(1.2, 3.0)),
        halo=float(g.uniform(0.0, 0.06)),
        halo_px=float(g.uniform(1.0, 2.0)),
        texture=float(g.uniform(0.02, 0.08)) if painted else 0.0,
        level_jitter=float(g.uniform(0.03, 0.15) if painted else g.uniform(0.0, 0.03)),
    )


def marker_transmittance(
    height: int,
    width: int,
    centres: NDArray,
    style: MarkerStyle,
    *,
    diameters: NDArray | None = None,
    rng: np.random.Generator | int | None = None,
) -> NDArray[np.float32]:
    """Transmittance of the markers of ``style`` at ``centres`` (``N x 2`` ``(x, y)`` px),
    ``H x W`` float32: 1 off the markers. Overlapping dots: the darkest wins. Dots may leave
    the frame (border-cut markers are painted as far as they are visible).

    Args:
        diameters: ``N`` per-dot diameters, px (default ``style.diameter``).
        rng: randomness of the texture and per-dot darkness (unused when both are 0).
    """
    pts = np.asarray(centres, np.float64).reshape(-1, 2)
    n = pts.shape[0]
    diam = np.broadcast_to(
        np.asarray(style.diameter if diameters is None else diameters, np.float64), (n,))
    g = _rng(rng)
    level = np.clip(style.darkness * (1.0 + style.level_jitter * g.standard_normal(n)), 0, 1)
    mottle = None
    if style.texture > 0:
        import cv2

        field = cv2.GaussianBlur(g.standard_normal((height, width)).astype(np.float32), (0, 0),
                                 1.0)
        # Unit variance after smoothing (a sigma-1 Gaussian keeps 1 / (2 sqrt(pi)) of it).
        field *= np.float32(np.sqrt(4 * np.pi))
        mottle = np.float32(style.texture) * field
    s = style.edge_px / _ERF_10_90
    # Reach where the core's erf tail and the halo fall below 1e-4 of the gel.
    tail = 4.0 * s + (style.halo_px * np.log(max(style.halo, 1e-12) / 1e-4)
                      if style.halo > 1e-4 else 0.0)
    trans = np.ones((height, width), np.float32)
    for (cx, cy), d, k in zip(pts, diam, level, strict=True):
        r = d / 2
        reach = r + tail + 1.0
        x0, x1 = max(int(np.floor(cx - reach)), 0), min(int(np.ceil(cx + reach)), width - 1)
        y0, y1 = max(int(np.floor(cy - reach)), 0), min(int(np.ceil(cy + reach)), height - 1)
        if x0 > x1 or y0 > y1:
            continue
        yy, xx = np.mgrid[y0 : y1 + 1, x0 : x1 + 1]
        dist = np.hypot(xx - cx, yy - cy) - r
        core = 0.5 * _erfc(dist / (np.sqrt(2.0) * s))
        dark = k * core
        if mottle is not None:
            dark = dark * (1.0 + mottle[y0 : y1 + 1, x0 : x1 + 1])
        if style.halo > 0:
            dark = dark + style.halo * np.exp(-np.maximum(dist, 0.0) / style.halo_px) * (1 - core)
        patch = trans[y0 : y1 + 1, x0 : x1 + 1]
        np.minimum(patch, np.clip(1.0 - dark, 0.0, 1.0).astype(np.float32), out=patch)
    return trans


def paint_markers(
    clean: NDArray[np.uint8],
    centres: NDArray,
    style: MarkerStyle | None = None,
    *,
    displacement: NDArray | None = None,
    diameters: NDArray | None = None,
    rng: np.random.Generator | int | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Paints markers on a clean (markerless) frame, real or simulated.

    Args:
        clean: ``H x W x 3`` uint8 BGR markerless frame (grey ``H x W`` accepted).
        centres: ``N x 2`` rest centres ``(x, y)``, px.
        style: marker look (default :class:`MarkerStyle`: GelSight Mini painted dots).
        displacement: ``N x 2`` marker displacement ``(dx, dy)`` px added to ``centres``.
        diameters: ``N`` per-dot diameters, px (default ``style.diameter``).
        rng: randomness of the mottling and per-dot darkness.

    Returns:
        ``(img, footprint)``: the frame with markers (uint8, rounded; add camera effects with
        :mod:`tacswitch.sim.capture`) and the true footprint, ``H x W`` bool, True where painting
        changed the frame by more than :data:`FOOTPRINT_LEVEL` grey levels in any channel. The
        clean frame is the markerless target; it is not modified.
    """
    if not isinstance(clean, np.ndarray):
        raise TypeError(f"clean: expected a numpy array, got {type(clean).__name__}")
    if clean.dtype != np.uint8:
        raise TypeError(f"clean: expected dtype uint8, got {clean.dtype}")
    if clean.ndim not in (2, 3) or (clean.ndim == 3 and clean.shape[2] != 3):
        raise ValueError(f"clean: expected an H x W x 3 BGR (or H x W grey) image; "
                         f"got shape {clean.shape}")
    pts = np.asarray(centres, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or not np.isfinite(pts).all():
        raise ValueError(f"centres: expected finite N x 2 (x, y); got shape {pts.shape}")
    if displacement is not None:
        disp = np.asarray(displacement, np.float64)
        if disp.shape != pts.shape or not np.isfinite(disp).all():
            raise ValueError(f"displacement: expected finite {pts.shape} like centres; "
                             f"got shape {disp.shape}")
        pts = pts + disp
    if diameters is not None:
        dd = np.asarray(diameters, np.float64)
        if dd.shape not in ((), (pts.shape[0],)) or not (np.isfinite(dd) & (dd > 0)).all():
            raise ValueError(f"diameters: expected {pts.shape[0]} positive numbers; "
                             f"got shape {dd.shape}")
    st = MarkerStyle() if style is None else style
    if not isinstance(st, MarkerStyle):
        raise TypeError(f"style: expected a MarkerStyle, got {type(st).__name__}")
    h, w = clean.shape[:2]
    trans = marker_transmittance(h, w, pts, st, diameters=diameters, rng=rng)
    base = clean.astype(np.float32)
    t = trans if clean.ndim == 2 else trans[:, :, None]
    painted = base * t
    change = base - painted
    footprint = (change if clean.ndim == 2 else change.max(axis=2)) > FOOTPRINT_LEVEL
    img = np.clip(np.rint(painted), 0, 255).astype(np.uint8)
    return img, footprint
