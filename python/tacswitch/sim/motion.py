"""Marker displacement fields of simple contacts (pixels, ``(dx, dy)`` per marker).

Smooth approximations of the elastic response of a gel pad: inside the contact the surface follows
the indenter, outside the motion decays with distance. The finite-thickness elastic kernels of the
full simulator replace these; their shapes and magnitudes are what tracking and slip need.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def _decay(r: NDArray, radius: float) -> NDArray:
    """1 inside the contact, then an elastic-like fall-off ~ (radius / r)^2."""
    out = np.ones_like(r)
    outside = r > radius
    out[outside] = (radius / r[outside]) ** 2
    return out


def press_field(
    centres: NDArray, contact: tuple[float, float], radius: float, dilation_px: float
) -> NDArray[np.float32]:
    """Normal press: markers move radially away from the contact centre.

    The outward displacement grows linearly to ``dilation_px`` at the contact edge, then decays.
    """
    c = np.asarray(centres, np.float64)
    rel = c - np.asarray(contact, np.float64)
    r = np.hypot(rel[:, 0], rel[:, 1])
    inside = dilation_px * r / max(radius, 1e-9)
    mag = np.where(r <= radius, inside, dilation_px * _decay(r, radius))
    unit = rel / np.maximum(r, 1e-9)[:, None]
    return (unit * mag[:, None]).astype(np.float32)


def shear_field(
    centres: NDArray, contact: tuple[float, float], radius: float, shift: tuple[float, float]
) -> NDArray[np.float32]:
    """Tangential shear: markers in the contact move by ``shift``; outside, the motion decays."""
    c = np.asarray(centres, np.float64)
    r = np.hypot(*(c - np.asarray(contact, np.float64)).T)
    return (_decay(r, radius)[:, None] * np.asarray(shift, np.float64)[None, :]).astype(np.float32)


def twist_field(
    centres: NDArray, contact: tuple[float, float], radius: float, angle_rad: float
) -> NDArray[np.float32]:
    """Torsion about the contact centre: rigid rotation inside the contact, decaying outside."""
    c = np.asarray(centres, np.float64)
    rel = c - np.asarray(contact, np.float64)
    r = np.hypot(rel[:, 0], rel[:, 1])
    cos, sin = np.cos(angle_rad), np.sin(angle_rad)
    rot = np.stack([cos * rel[:, 0] - sin * rel[:, 1], sin * rel[:, 0] + cos * rel[:, 1]], axis=1)
    return ((rot - rel) * _decay(r, radius)[:, None]).astype(np.float32)
