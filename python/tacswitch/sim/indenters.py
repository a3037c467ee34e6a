"""Indenters and textured objects as analytic surfaces, with class labels.

An object is described in its own frame (mm, origin at its centre, rotated by ``angle``) by a
*profile* ``h(X, Y) >= 0``: how far its surface lies behind its lowest point (``inf`` where there
is no object). Pressed ``depth`` mm into the gel, its surface is ``z_obj = depth - h`` (mm toward
the camera, see :mod:`tacswitch.sim.deform`). Profiles are analytic in ``(X, Y)``, so an object
can be moved by any sub-pixel amount (slip) without resampling artefacts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Rigid indenters (geometry classes).
SHAPES = ("sphere", "cylinder", "edge", "box", "hex", "star", "knurl")
#: Fabrics and other textures pressed by a soft pad (texture classes).
TEXTURES = ("plain_weave", "twill", "knit", "corduroy", "mesh", "felt", "leather")
#: Every class label; ``"none"`` is a no-contact frame.
CLASSES: tuple[str, ...] = ("none", *SHAPES, *TEXTURES)


@dataclass
class ObjectSpec:
    """One object: class label and the parameters that fix its shape (mm, radians).

    ``params`` is JSON-serialisable and goes into the dataset manifest.
    """

    label: str
    params: dict[str, Any] = field(default_factory=dict)

    def profile(self, X: NDArray, Y: NDArray) -> NDArray[np.float32]:
        """``h(X, Y)`` in mm (object frame, mm), ``inf`` off the object."""
        return _PROFILES[self.label](X, Y, self.params).astype(np.float32)

    def surface(self, height: int, width: int, mm_per_px: float, centre: tuple[float, float],
                angle: float, depth: float) -> NDArray[np.float32]:
        """``z_obj`` on the pixel grid: the object centred at ``centre`` ``(x, y)`` px, rotated
        by ``angle`` rad, pressed ``depth`` mm; ``-inf`` off the object."""
        if self.label == "none":
            return np.full((height, width), -np.inf, np.float32)
        y, x = np.mgrid[0:height, 0:width].astype(np.float32)
        dx, dy = (x - centre[0]) * mm_per_px, (y - centre[1]) * mm_per_px
        c, s = np.cos(angle), np.sin(angle)
        X, Y = c * dx + s * dy, -s * dx + c * dy
        return (depth - self.profile(X, Y)).astype(np.float32)


def random_object(label: str, rng: np.random.Generator) -> ObjectSpec:
    """Draws the shape parameters of an object of class ``label``."""
    u = rng.uniform
    if label not in CLASSES:
        raise ValueError(f"label: unknown {label!r}; choose from {list(CLASSES)}")
    p: dict[str, Any]
    if label == "none":
        p = {}
    elif label == "sphere":
        p = {"radius": u(2.0, 6.0)}
    elif label == "cylinder":
        p = {"radius": u(1.5, 4.0), "length": u(6.0, 20.0)}
    elif label == "edge":
        p = {"round": u(0.3, 1.2)}
    elif label == "box":
        p = {"half_x": u(1.5, 4.0), "half_y": u(1.5, 4.0), "round": u(0.2, 0.5)}
    elif label in ("hex", "star"):
        p = {"radius": u(1.5, 3.5), "round": u(0.15, 0.4), "depth_inner": u(0.4, 0.8)}
    elif label == "knurl":
        p = {"radius": u(3.0, 8.0), "pitch": u(0.6, 1.4), "groove": u(0.08, 0.2),
             "diamond": bool(rng.random() < 0.5)}
    else:  # textures: a soft pad covered with the texture
        p = {"pad_radius": u(12.0, 30.0), "pitch": u(0.45, 1.4), "amp": u(0.06, 0.18)}
        if label in ("felt", "leather"):
            k = 48
            scale = 2 * np.pi / p["pitch"]
            ang = rng.uniform(0, 2 * np.pi, k)
            mag = scale * rng.uniform(0.5, 1.5, k)
            p["waves"] = np.stack([mag * np.cos(ang), mag * np.sin(ang),
                                   rng.uniform(0, 2 * np.pi, k)], axis=1).round(5).tolist()
    return ObjectSpec(label, p)


def _rounded(dist_out: NDArray, r: float) -> NDArray:
    """Profile just outside a flat face: a rounded rim of radius ``r`` (mm), then a wall."""
    h = r - np.sqrt(np.maximum(r * r - dist_out**2, 0.0))
    return np.where(dist_out < r, h, np.inf)


def _sphere(X: NDArray, Y: NDArray, p: dict) -> NDArray:
    R = p["radius"]
    r2 = X * X + Y * Y
    return np.where(r2 < R * R, R - np.sqrt(np.maximum(R * R - r2, 0.0)), np.inf)


def _cylinder(X: NDArray, Y: NDArray, p: dict) -> NDArray:
    R = p["radius"]
    h = np.where(np.abs(Y) < R, R - np.sqrt(np.maximum(R * R - Y * Y, 0.0)), np.inf)
    return np.where(np.abs(X) < p["length"] / 2, h, np.inf)


def _edge(X: NDArray, Y: NDArray, p: dict) -> NDArray:
    # A rounded 90-degree edge: a cylinder of radius `round`, then 45-degree faces.
    r = p["round"]
    ay = np.abs(Y)
    lim = r / np.sqrt(2)
    circ = r - np.sqrt(np.maximum(r * r - ay * ay, 0.0))
    face = (r - r / np.sqrt(2)) + (ay - lim)
    return np.where(ay < lim, circ, face)


def _box(X: NDArray, Y: NDArray, p: dict) -> NDArray:
    out = np.hypot(np.maximum(np.abs(X) - p["half_x"], 0), np.maximum(np.abs(Y) - p["half_y"], 0))
    return _rounded(out, p["round"])


def _polygon_radius(theta: NDArray, label: str, R: float) -> NDArray:
    if label == "hex":
        sector = np.mod(theta, np.pi / 3) - np.pi / 6
        return R * np.cos(np.pi / 6) / np.cos(sector)
    # Six-pointed (Torx-like) star: radius alternates between R and 0.6 R.
    tri = np.abs(np.mod(theta, np.pi / 3) / (np.pi / 3) * 2 - 1)
    return R * (0.6 + 0.4 * (1 - tri))


def _bit(X: NDArray, Y: NDArray, p: dict, label: str) -> NDArray:
    rho = np.hypot(X, Y)
    rad = _polygon_radius(np.arctan2(Y, X), label, p["radius"])
    face = np.zeros_like(rho)
    # A driver bit's face is hollow in the middle (the socket of a screw head is not); a shallow
    # central recess makes the imprint a ring, as real bits leave.
    face = np.where(rho < 0.35 * p["radius"], p["depth_inner"], face)
    return np.where(rho <= rad, face, _rounded(rho - rad, p["round"]))


def _knurl(X: NDArray, Y: NDArray, p: dict) -> NDArray:
    base = _cylinder(X, Y, {"radius": p["radius"], "length": 1e9})
    k = 2 * np.pi / p["pitch"]
    if p["diamond"]:
        t = np.maximum(np.abs(np.cos(k * (X + Y) / 2)), np.abs(np.cos(k * (X - Y) / 2)))
    else:
        t = np.abs(np.cos(k * Y / 2))
    return base + p["groove"] * (1 - t)


def _texture(X: NDArray, Y: NDArray, p: dict, label: str) -> NDArray:
    R = p["pad_radius"]
    r2 = X * X + Y * Y
    pad = np.where(r2 < R * R, R - np.sqrt(np.maximum(R * R - r2, 0.0)), np.inf)
    u, v = X / p["pitch"], Y / p["pitch"]
    su, sv = np.abs(np.sin(np.pi * u)), np.abs(np.sin(np.pi * v))
    if label == "plain_weave":  # over-under: warp on top on one checker colour, weft on the other
        over = (np.floor(u) + np.floor(v)) % 2 == 0
        t = np.sqrt(np.where(over, su, sv))
    elif label == "twill":  # over two, under two, shifted one per row: diagonal ribs
        over = np.mod(np.floor(u) + np.floor(v), 4) < 2
        t = np.sqrt(np.where(over, su, sv))
    elif label == "knit":  # rows of V-shaped loops
        t = np.abs(np.sin(np.pi * (u + np.abs(np.mod(v, 1.0) - 0.5)))) ** 0.6 * (0.6 + 0.4 * sv)
    elif label == "corduroy":  # parallel rounded wales
        t = np.sqrt(su)
    elif label == "mesh":  # raised thin strands around open cells
        t = np.maximum(np.cos(np.pi * u) ** 8, np.cos(np.pi * v) ** 8)
    else:  # felt (random fibre noise) / leather (ridged grain with creases)
        w = np.asarray(p["waves"])
        n = np.zeros_like(X)
        for kx, ky, ph in w:
            n += np.cos(kx * X + ky * Y + ph)
        n /= np.sqrt(len(w) / 2)
        t = 0.5 + 0.25 * n if label == "felt" else 1 - np.minimum(np.abs(n), 1.0) ** 0.5
        t = np.clip(t, 0, 1)
    return pad + p["amp"] * (1 - t)


_PROFILES: dict = {
    "sphere": _sphere,
    "cylinder": _cylinder,
    "edge": _edge,
    "box": _box,
    "hex": lambda X, Y, p: _bit(X, Y, p, "hex"),
    "star": lambda X, Y, p: _bit(X, Y, p, "star"),
    "knurl": _knurl,
    **{t: (lambda X, Y, p, t=t: _texture(X, Y, p, t)) for t in TEXTURES},
}


def depth_range(label: str) -> tuple[float, float]:
    """Press depths (mm) that give GelSight-like contacts for a class."""
    if label in TEXTURES:
        return 0.3, 0.9
    if label in ("box", "hex", "star"):
        return 0.15, 0.6
    return 0.3, 1.2
