"""Gel-attached texture: the coating's fixed-pattern grain, carried by the gel's lateral motion.

A real markerless frame is not smooth where the gel is untouched: the coating has a fixed-pattern
grain, weak but present in every frame, and it moves with the gel surface (it is painted on it).
This module renders that grain with the contrast and radial power spectrum measured on real
presses, and warps any gel-attached layer (grain, dust, fibres) by the same lateral displacement
field that moves the markers.

Measurement (:func:`measure_grain`, on taxim's real GelSight and GelSight Mini presses at
640 x 480, 0.0295 mm/px, regions > 2.5 contact radii from the press): the grey image is high-passed
(minus its Gaussian blur, sigma 3 px); two frames of the same gel share the fixed pattern and not
the temporal noise, so the covariance of their high-pass images is the fixed pattern's variance and
their cross power spectrum its spectrum. Measured (``python -m tacswitch.sim.grain``):

=============  ==================  ================  ====================
sensor         correlation         fixed pattern     temporal noise
=============  ==================  ================  ====================
GelSight       0.19 (0.11-0.26)    0.27 grey levels  0.56 grey levels
GelSight Mini  0.41                0.36 grey levels  0.42 grey levels
=============  ==================  ================  ====================

Conventions: layers are ``H x W`` float32; a displacement field is ``H x W x 2`` (dx, dy) px in
*rest* coordinates (the motion of the gel point at rest at pixel ``(x, y)``), as the markers'.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

#: Scale of the real measurements, mm per px (taxim's 640 x 480 frames of both sensors).
MEASURE_MM_PER_PX = 0.0295
#: Sigma of the high-pass used to measure grain, px at :data:`MEASURE_MM_PER_PX`.
HIGHPASS_SIGMA = 3.0
#: Patch size of the cross power spectrum, px.
PATCH = 64
#: Radial bins of the spectrum: ``RADIAL_BINS`` equal bins over [0, 0.5] cycles/px.
RADIAL_BINS = 10
#: Measured cross power spectra of the high-passed grey image (per bin, arbitrary common unit;
#: only the shape is used): taxim GelSight and GelSight Mini presses, 640 x 480.
REAL_RADIAL_PSD: dict[str, tuple[float, ...]] = {
    "gelsight": (1.0090, 1.3240, 0.6416, 0.1709, 0.0472, 0.0186, 0.0070, 0.0051, 0.0037, 0.0032),
    "gelsight_mini": (0.5948, 1.6393, 1.2341, 0.4188, 0.1100, 0.0343, 0.0158, 0.0070, 0.0027,
                      0.0014),
}
#: Fixed-pattern standard deviation of the high-passed grey image, grey levels (measured
#: 0.27 and 0.36); scenes draw from this range.
GRAIN_STD_RANGE = (0.22, 0.42)


def _hp_gain(f: NDArray[Any], sigma: float = HIGHPASS_SIGMA) -> NDArray[np.float64]:
    """Amplitude response of ``x - GaussianBlur(x, sigma)`` at frequency ``f`` cycles/px."""
    return 1.0 - np.exp(-2.0 * (np.pi * sigma * f) ** 2)


def grain_spectrum(profile: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(f, amplitude)``: bin centres (cycles/px at :data:`MEASURE_MM_PER_PX`) and the grain's
    amplitude spectrum before the high-pass, from a measured profile.

    The high-pass hides the lowest bins (gain < 0.3): there the amplitude is held at that of the
    first bin it does not hide, rather than amplified by dividing by a tiny gain.
    """
    if profile not in REAL_RADIAL_PSD:
        raise ValueError(f"profile: unknown {profile!r}; choose from {sorted(REAL_RADIAL_PSD)}")
    psd = np.asarray(REAL_RADIAL_PSD[profile], np.float64)
    f = ((np.arange(RADIAL_BINS) + 0.5) * (0.5 / RADIAL_BINS)).astype(np.float64)
    g = _hp_gain(f)
    amp = np.sqrt(psd) / np.maximum(g, 1e-6)
    ok = g >= 0.3
    first = int(np.argmax(ok))
    amp[:first] = amp[first]
    return f, amp


def grain_texture(height: int, width: int, mm_per_px: float, rng: np.random.Generator, *,
                  std_grey: float, mean_grey: float = 130.0,
                  profile: str = "gelsight") -> NDArray[np.float32]:
    """A relative reflectance grain ``g`` (the image is multiplied by ``1 + g``), ``H x W``.

    Drawn as filtered white noise at the measurement scale (0.0295 mm/px) over the frame's
    physical size, with the measured radial spectrum of ``profile``, scaled so that on a gel of
    brightness ``mean_grey`` its high-passed grey image has ``std_grey`` grey levels there, then
    area-resampled to ``height x width`` (the grain is physical: cycles per mm).
    """
    import cv2

    if height < 1 or width < 1:
        raise ValueError(f"height, width: must be >= 1; got {height} x {width}")
    if mm_per_px <= 0:
        raise ValueError(f"mm_per_px: must be > 0; got {mm_per_px}")
    k = mm_per_px / MEASURE_MM_PER_PX
    hh, ww = max(8, round(height * k)), max(8, round(width * k))
    fb, amp = grain_spectrum(profile)
    fy = np.fft.fftfreq(hh)[:, None]
    fx = np.fft.rfftfreq(ww)[None, :]
    fr = np.hypot(fx, fy)
    a = np.interp(fr, fb, amp, left=amp[0], right=amp[-1])
    spec = np.fft.rfft2(rng.standard_normal((hh, ww))) * a
    g = np.fft.irfft2(spec, (hh, ww)).astype(np.float32)
    hp = g - cv2.GaussianBlur(g, (0, 0), HIGHPASS_SIGMA)
    g *= np.float32(std_grey / mean_grey / max(float(hp.std()), 1e-12))
    if (hh, ww) != (height, width):
        interp = cv2.INTER_AREA if k > 1 else cv2.INTER_CUBIC
        g = cast("NDArray[np.float32]", cv2.resize(g, (width, height), interpolation=interp))
    return g


def dense_field(coarse: NDArray, step: float, height: int, width: int) -> NDArray[np.float32]:
    """Bilinear upsampling of a coarse field (cell ``(i, j)`` centred on pixel
    ``((j + 0.5) step - 0.5, (i + 0.5) step - 0.5)``, as in :mod:`tacswitch.sim.scene`) to
    ``H x W x 2`` px."""
    import cv2

    c = np.asarray(coarse, np.float32)
    xs = (np.arange(width, dtype=np.float32) + 0.5) / step - 0.5
    ys = (np.arange(height, dtype=np.float32) + 0.5) / step - 0.5
    mx, my = np.meshgrid(xs, ys)
    return cast("NDArray[np.float32]",
                cv2.remap(c, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))


def warp_layer(layer: NDArray, field: NDArray | None, *, border: float = 0.0
               ) -> NDArray[np.float32]:
    """A gel-attached layer after the gel moved by ``field`` (rest coordinates, px).

    The point at rest at ``X`` appears at ``X + u(X)``; the value at image pixel ``x`` is the
    layer at ``X = x - u(X)``, solved by two fixed-point steps (exact to second order in the
    field's gradient). Bicubic sampling: a bilinear one would blur the grain by an amount that
    depends on the sub-pixel shift, a cue real frames do not have. ``field=None``: unchanged.
    """
    import cv2

    lay = np.asarray(layer, np.float32)
    if field is None:
        return lay
    u = np.asarray(field, np.float32)
    h, w = lay.shape[:2]
    if u.shape != (h, w, 2):
        raise ValueError(f"field: expected shape {(h, w, 2)}; got {u.shape}")
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    px, py = gx - u[..., 0], gy - u[..., 1]
    for _ in range(2):
        back = cv2.remap(u, px, py, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        px, py = gx - back[..., 0], gy - back[..., 1]
    return cast("NDArray[np.float32]",
                cv2.remap(lay, px, py, cv2.INTER_CUBIC, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=border))


@dataclass(frozen=True)
class GrainStats:
    """Fixed-pattern statistics of a set of frames of one gel (see :func:`measure_grain`).

    Attributes:
        corr: mean correlation between the high-passed grey images of two frames.
        fixed_std: fixed-pattern standard deviation, grey levels (sqrt of the covariance).
        temporal_std: the rest of the high-passed variance, grey levels.
        radial_psd: cross power spectrum of the high-passed grey images, per radial bin
            (:data:`RADIAL_BINS` bins over [0, 0.5] cycles/px), mean over patch pairs.
        n_pairs: frame pairs used.
    """

    corr: float
    fixed_std: float
    temporal_std: float
    radial_psd: tuple[float, ...]
    n_pairs: int


def measure_grain(frames: NDArray, usable: NDArray | None = None, *, max_lag: int = 5
                  ) -> GrainStats:
    """Fixed-pattern grain of ``frames`` (``N x H x W x 3`` uint8/float BGR of one gel).

    Args:
        frames: at least two frames of the same gel.
        usable: ``N x H x W`` bool, True where a frame is untouched (default: everywhere);
            a 6 % border is always left out (vignetting, frame edges).
        max_lag: each frame is paired with the next ``max_lag`` frames.
    """
    import cv2

    f = np.asarray(frames, np.float32)
    if f.ndim != 4 or f.shape[-1] != 3 or f.shape[0] < 2:
        raise ValueError(f"frames: expected N x H x W x 3 with N >= 2; got {f.shape}")
    n, h, w = f.shape[:3]
    use = np.ones((n, h, w), bool) if usable is None else np.asarray(usable, bool)
    if use.shape != (n, h, w):
        raise ValueError(f"usable: expected shape {(n, h, w)}; got {use.shape}")
    b = int(0.06 * w)
    inner = np.zeros((h, w), bool)
    inner[b:h - b, b:w - b] = True
    hp = np.stack([g - cv2.GaussianBlur(g, (0, 0), HIGHPASS_SIGMA) for g in f.mean(-1)])
    cors, covs, vars_ = [], [], []
    spec = np.zeros((PATCH, PATCH))
    n_patch = 0
    tiles = [(y, x) for y in range(b, h - b - PATCH + 1, PATCH)
             for x in range(b, w - b - PATCH + 1, PATCH)]
    for i in range(n):
        for j in range(i + 1, min(n, i + 1 + max_lag)):
            m = use[i] & use[j] & inner
            if m.sum() < 100:
                continue
            a, c = hp[i][m], hp[j][m]
            cors.append(float(np.corrcoef(a, c)[0, 1]))
            covs.append(float(np.mean(a * c)))
            vars_.append(0.5 * float(a.var() + c.var()))
            for y, x in tiles:
                if m[y:y + PATCH, x:x + PATCH].all():
                    fa = np.fft.fft2(hp[i][y:y + PATCH, x:x + PATCH])
                    fc = np.fft.fft2(hp[j][y:y + PATCH, x:x + PATCH])
                    spec += (fa * np.conj(fc)).real
                    n_patch += 1
    if not cors:
        raise ValueError("usable: no frame pair shares 100 usable pixels")
    fq = np.fft.fftfreq(PATCH)
    fr = np.hypot(fq[:, None], fq[None, :])
    edges = np.linspace(0, 0.5, RADIAL_BINS + 1)
    spec /= max(n_patch, 1) * PATCH * PATCH
    radial = tuple(float(spec[(fr >= edges[k]) & (fr < edges[k + 1])].mean())
                   for k in range(RADIAL_BINS))
    fixed = max(float(np.mean(covs)), 0.0)
    return GrainStats(float(np.mean(cors)), float(np.sqrt(fixed)),
                      float(np.sqrt(max(float(np.mean(vars_)) - fixed, 0.0))), radial, len(cors))


def taxim_presses(sensor: str) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """taxim's real presses of ``sensor`` (``"gelsight"`` / ``"gelsight_mini"``) and their
    untouched regions (> 2.5 contact radii + 20 px from the press); needs the ``taxim`` package
    (its data files only)."""
    from pathlib import Path

    import taxim

    d = np.load(Path(taxim.__file__).parent / "calib" / sensor / "dataPack.npz")
    imgs = d["imgs"]
    h, w = imgs.shape[1:3]
    yy, xx = np.mgrid[0:h, 0:w]
    use = np.stack([(xx - cx) ** 2 + (yy - cy) ** 2 > (2.5 * r + 20) ** 2
                    for (cx, cy), r in zip(d["touch_center"], d["touch_radius"], strict=True)])
    return imgs, use


def main(argv: Any = None) -> None:
    """Prints the grain statistics of taxim's real presses (the constants above)."""
    for sensor in REAL_RADIAL_PSD:
        imgs, use = taxim_presses(sensor)
        s = measure_grain(imgs, use)
        print(f"{sensor}: corr {s.corr:.3f}, fixed {s.fixed_std:.3f}, temporal "
              f"{s.temporal_std:.3f} grey levels, pairs {s.n_pairs}")
        print("  radial cross-PSD:", " ".join(f"{v:.4f}" for v in s.radial_psd))


if __name__ == "__main__":
    main()
