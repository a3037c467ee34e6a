"""Optical rendering of a deformed gel: real Taxim colour tables, or Phong shading.

A GelSight camera sees the gel lit by coloured LEDs from the sides; a surface tilt changes the
colour. Both renderers return the colour *change* from the flat gel, ``H x W x 3`` float32 BGR in
grey levels, which is added to a no-contact background (so an untouched gel renders exactly as
its background).

Taxim calibration (Si & Yuan, "Taxim", RA-L 2022; tables from the MIT-licensed PyPI package
``taxim==1.4.1``, derived by :mod:`tacswitch.sim.calib.make_calib`): for every bin of slope
magnitude ``atan|grad z|`` (0..pi/2) and direction ``atan2(dz/dy, dz/dx)`` (-pi..pi) a quadratic
in the pixel position gives the colour. Fitted on real GelSight presses, it reproduces their
colours; shadows are not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

_CALIB_DIR = Path(__file__).parent / "calib"
#: Calibrations shipped with the package.
CALIBRATIONS = ("gelsight", "gelsight_mini")


@dataclass(frozen=True)
class Calibration:
    """A Taxim optical calibration.

    Attributes:
        name: sensor name.
        poly: ``3 x M x D x 6`` float32 (BGR; magnitude bins; direction bins; coefficients of
            ``[u^2, v^2, u v, u, v, 1]`` with ``u = x / W``, ``v = y / H``), grey levels.
        background: real no-contact frame, uint8 BGR.
        pixmm: mm per pixel of the 640x480 calibration frame.
    """

    name: str
    poly: NDArray[np.float32]
    background: NDArray[np.uint8]
    pixmm: float


@lru_cache(maxsize=4)
def load_calibration(name: str) -> Calibration:
    """Loads a shipped calibration (``"gelsight"`` or ``"gelsight_mini"``); no download."""
    if name not in CALIBRATIONS:
        raise ValueError(f"calib: unknown {name!r}; choose from {list(CALIBRATIONS)}")
    with np.load(_CALIB_DIR / f"{name}.npz") as d:
        return Calibration(name, d["poly"].astype(np.float32), d["background"].copy(),
                           float(d["pixmm"]))


def slopes(z_mm: NDArray, mm_per_px: float) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Surface slopes ``(dz/dx, dz/dy)`` (dimensionless) by central differences."""
    # numpy's stub types the gradient of an array of unknown ndim as a 1-D array; a 2-D input
    # gives one array per axis.
    gy, gx = cast("tuple[NDArray[np.float32], NDArray[np.float32]]",
                  np.gradient(np.asarray(z_mm, np.float32), mm_per_px))
    return gx.astype(np.float32), gy.astype(np.float32)


def background_image(calib: Calibration, height: int, width: int) -> NDArray[np.float32]:
    """The calibration's real no-contact frame resized to ``height x width``, float32 BGR."""
    import cv2

    bg = calib.background
    if bg.shape[:2] != (height, width):
        bg = cast("NDArray[np.uint8]",  # resizing keeps the uint8 dtype
                  cv2.resize(bg, (width, height), interpolation=cv2.INTER_AREA))
    return bg.astype(np.float32)


def shade_taxim(z_mm: NDArray, mm_per_px: float, calib: Calibration) -> NDArray[np.float32]:
    """Colour change of a gel surface ``z_mm`` (mm toward the camera) under Taxim's tables.

    The frame is mapped onto the calibration frame (same field of view at any resolution), so
    the position-dependent part of the tables follows the LEDs. Flat pixels change by 0.
    """
    z = np.asarray(z_mm, np.float32)
    h, w = z.shape
    gx, gy = slopes(z, mm_per_px)
    tan = np.hypot(gx, gy)
    out = np.zeros((h, w, 3), np.float32)
    ys, xs = np.nonzero(tan > 1e-5)
    if ys.size == 0:
        return out
    m_bins, d_bins = calib.poly.shape[1:3]
    mag = np.arctan(tan[ys, xs])
    ang = np.arctan2(gy[ys, xs], gx[ys, xs])
    im = np.minimum((mag / (0.5 * np.pi / (m_bins - 1))).astype(np.intp), m_bins - 1)
    idr = np.minimum(((ang + np.pi) / (2 * np.pi / (d_bins - 1))).astype(np.intp), d_bins - 1)
    # The flat gel's bin (magnitude 0, direction 0) is subtracted: the background already holds it.
    i0, d0 = 0, int(np.pi / (2 * np.pi / (d_bins - 1)))
    u = (xs / w).astype(np.float32)
    v = (ys / h).astype(np.float32)
    feats = np.stack([u * u, v * v, u * v, u, v, np.ones_like(u)], axis=1)
    for c in range(3):
        coef = calib.poly[c, im, idr] - calib.poly[c, i0, d0]
        out[ys, xs, c] = np.einsum("nk,nk->n", coef, feats)
    return out


#: Phong lights: (azimuth rad in image coordinates, elevation rad, BGR colour gain in grey
#: levels). Blue, green and red LEDs from three sides, as on GelSight-like sensors.
PHONG_LIGHTS: tuple[tuple[float, float, tuple[float, float, float]], ...] = (
    (np.pi / 2, 0.55, (95.0, 10.0, 5.0)),
    (np.pi * 7 / 6, 0.55, (5.0, 90.0, 10.0)),
    (-np.pi / 6, 0.55, (10.0, 5.0, 100.0)),
)


def shade_phong(
    z_mm: NDArray,
    mm_per_px: float,
    *,
    lights: tuple[tuple[float, float, tuple[float, float, float]], ...] = PHONG_LIGHTS,
    specular: float = 12.0,
    shininess: float = 12.0,
) -> NDArray[np.float32]:
    """Colour change of a gel surface under Lambert + Phong shading (the calibration-free path).

    Normals ``n = (-dz/dx, -dz/dy, 1) / norm``; the camera looks along -z. Each light adds
    ``gain * (n . l - n0 . l)`` (diffuse, relative to the flat gel ``n0``) plus a white specular
    lobe, so a flat gel changes by 0.
    """
    gx, gy = slopes(z_mm, mm_per_px)
    norm = np.sqrt(gx * gx + gy * gy + 1.0)
    n = (-gx / norm, -gy / norm, 1.0 / norm)
    out = np.zeros((*gx.shape, 3), np.float32)
    for az, el, gain in lights:
        lx, ly, lz = np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)
        ndotl = n[0] * lx + n[1] * ly + n[2] * lz
        diffuse = np.maximum(ndotl, 0.0) - lz
        # Reflection of the light about n, seen by a camera along +z.
        rz = 2 * ndotl * n[2] - lz
        rz0 = 2 * lz - lz
        spec = specular * (np.maximum(rz, 0.0) ** shininess - max(rz0, 0.0) ** shininess)
        for c in range(3):
            out[:, :, c] += gain[c] * diffuse + spec / len(lights)
    return out
