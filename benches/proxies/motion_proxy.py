"""Real-texture proxy for marker motion: real markerless frames warped by known smooth fields.

No public data pair markerless frames with the motion of markers, so this module makes the truth:
a real markerless press (taxim's GelSight 640 x 480 and GelSight Mini presses, the latter
area-downsampled to 320 x 240 as the Mini's driver crops/resizes) is warped by a known lateral
displacement field of the gel, so everything the real frame shows — the imprint's shading, the
coating's fixed-pattern grain, dust — moves with the field, as it would on the sensor.

Conventions (px, ``(x, y)``, pixel centres at integers): a field ``u`` is defined at REST
positions ``X`` (the undeformed gel, the reference frame's pixels): the gel point at ``X`` moves to
``X + u(X)``. The warped frame is ``img(X + u(X)) = src(X)``, rendered by backward mapping
(``cv2.remap``): for each pixel ``y`` of the warped frame the rest point ``X`` solving
``X + u(X) = y`` is found by the fixed-point iteration ``X <- y - u(X)`` (a contraction: every
field here has a displacement gradient of norm < 0.85). The true motion of a marker at rest
centre ``c`` from the reference to ``img`` is then exactly ``u(c)``.

Fields, centred on the real contact (``touch_center``, radius ``a`` = ``touch_radius``), ``d = X -
centre``, ``r = |d|``, amplitude ``A`` (the largest displacement, px):

- ``press``: radial outward, ``A d / r0 exp((1 - r²/r0²) / 2)`` (peak ``A`` at ``r = r0``,
  ``r0 = max(1.3 a, 2 A)``);
- ``shear``: Cerruti-like tangential field, uniform inside the contact and decaying as ``rs / r``
  outside (``A s(r) [e + k ((e.d^) d^ - e / 2) r² / (r² + rs²)]``, ``s = (1 + (r/rs)^4)^(-1/4)``,
  ``rs = max(1.2 a, 1.5 A)``, ``e`` a unit direction, ``k`` in [0, 0.4]: the along-load component
  decays more slowly than the transverse one, as in Cerruti's solution);
- ``twist``: rotation about the contact fading as a Gaussian, ``theta perp(d) exp(-r²/(2 rt²))``
  (peak ``A`` at ``r = rt``, ``rt = max(1.3 a, 3 A)``);
- ``mix``: the sum of the three with random shares of ``A`` (rescaled if its gradient is too
  steep).

Amplitudes are drawn up to one GelSight Mini marker pitch (1.68 mm: 28.5 px at 320 x 240, 57 px at
640 x 480). Capture: the warped frame gets an exposure / white-balance drift and the capture's
compression (``tacswitch.sim.capture``: MJPEG or H.264; the reference frame gets its own
compression but no drift). The real frames already hold their own blur and sensor noise.

Settings (every sample of :func:`make_proxy` carries the references of all three):

- ``"no_contact"``: ``ref`` = the sensor's real no-contact frame ``f0`` (a separate capture: the
  same fixed-pattern grain, independent noise), ``img`` = the warped press. The truth is the
  warp alone: it leaves out the press's own (unknown, small) lateral motion.
- ``"press"``: ``ref`` = the unwarped press frame, ``img`` = its warp: the cleanest test of
  following real texture, optimistic because the two share the capture's noise pattern.
- ``"single"``: ``img`` only (the paper's setting).

A second proxy, :func:`make_contact_proxy`, keeps the real imprint instead and takes the motion of
that contact from the simulator's elastic model (real frames, MODELLED field; see its section).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

__all__ = ["CONTACT_KINDS", "FIELD_KINDS", "REAL_BALL_RADIUS_MM", "SENSORS", "SETTINGS",
           "ContactSample", "Field",
           "ProxySample", "backward_map", "contact_fields", "dense_backward_map",
           "load_real_presses", "make_contact_proxy", "make_proxy", "marker_grid", "random_field",
           "warp", "warp_dense"]

FIELD_KINDS = ("press", "shear", "twist", "mix")
SETTINGS = ("no_contact", "press", "single")
#: taxim sensor -> (working width, height, marker rows, cols, pitch px at that size).
SENSORS: dict[str, tuple[int, int, int, int, float]] = {
    "gelsight": (640, 480, 6, 8, 80.0),
    "gelsight_mini": (320, 240, 9, 11, 28.5),
}
#: Largest amplitude, mm: one GelSight Mini marker pitch (28.5 px x 0.059 mm/px).
MAX_AMPLITUDE_MM = 1.68
#: mm per px at the working size of each sensor.
MM_PER_PX = {"gelsight": 0.0295, "gelsight_mini": 0.059}
#: Largest displacement-gradient norm allowed (the backward map's contraction factor).
MAX_GRADIENT = 0.85


@dataclass
class Field:
    """A smooth lateral displacement field of the gel, defined at rest positions (see module doc).

    Attributes:
        kind: ``"press"``, ``"shear"``, ``"twist"`` or ``"mix"``.
        centre: contact centre ``(x, y)`` px.
        parts: the components, ``(kind, params)`` with params in px / radians.
    """

    kind: str
    centre: tuple[float, float]
    parts: list[tuple[str, dict[str, float]]] = field(default_factory=list)

    def __call__(self, x: NDArray[Any], y: NDArray[Any]) -> tuple[NDArray[np.float64],
                                                                  NDArray[np.float64]]:
        """Displacement ``(ux, uy)`` px at rest positions ``(x, y)`` (arrays of one shape)."""
        dx = np.asarray(x, np.float64) - self.centre[0]
        dy = np.asarray(y, np.float64) - self.centre[1]
        r2 = dx * dx + dy * dy
        ux = np.zeros_like(dx)
        uy = np.zeros_like(dy)
        for kind, p in self.parts:
            if kind == "press":
                g = p["amp"] / p["r0"] * np.exp(0.5 * (1.0 - r2 / p["r0"] ** 2))
                ux += g * dx
                uy += g * dy
            elif kind == "shear":
                rs2 = p["rs"] ** 2
                s = p["amp"] * (1.0 + (r2 / rs2) ** 2) ** -0.25
                r = np.sqrt(r2)
                nx = np.divide(dx, r, out=np.zeros_like(dx), where=r > 0)
                ny = np.divide(dy, r, out=np.zeros_like(dy), where=r > 0)
                ex, ey = p["ex"], p["ey"]
                w = p["k"] * r2 / (r2 + rs2)
                along = ex * nx + ey * ny
                ux += s * (ex + w * (along * nx - 0.5 * ex))
                uy += s * (ey + w * (along * ny - 0.5 * ey))
            elif kind == "twist":
                g = p["theta"] * np.exp(-0.5 * r2 / p["rt"] ** 2)
                ux += -g * dy
                uy += g * dx
            else:  # pragma: no cover - parts are built by random_field only
                raise ValueError(f"kind: unknown field part {kind!r}")
        return ux, uy

    def at(self, pts: NDArray[Any]) -> NDArray[np.float32]:
        """Displacement ``N x 2`` float32 at ``N x 2`` rest points."""
        pts = np.asarray(pts, np.float64).reshape(-1, 2)
        ux, uy = self(pts[:, 0], pts[:, 1])
        return np.stack([ux, uy], 1).astype(np.float32)

    def max_gradient(self, height: int, width: int, step: int = 4) -> float:
        """Largest spectral norm of the displacement gradient on a grid of the frame (numeric)."""
        ys, xs = np.mgrid[0:height:step, 0:width:step].astype(np.float64)
        h = 0.5
        ux1, uy1 = self(xs + h, ys)
        ux0, uy0 = self(xs - h, ys)
        vx1, vy1 = self(xs, ys + h)
        vx0, vy0 = self(xs, ys - h)
        jac = np.stack([np.stack([ux1 - ux0, vx1 - vx0], -1),
                        np.stack([uy1 - uy0, vy1 - vy0], -1)], -2) / (2 * h)
        return float(np.linalg.norm(jac, ord=2, axis=(-2, -1)).max())


def _part(kind: str, amp: float, a: float, rng: np.random.Generator) -> tuple[str, dict]:
    if kind == "press":
        return kind, {"amp": amp, "r0": max(1.3 * a, 2.0 * amp)}
    if kind == "shear":
        ang = rng.uniform(0, 2 * np.pi)
        return kind, {"amp": amp, "rs": max(1.2 * a, 1.5 * amp), "ex": float(np.cos(ang)),
                      "ey": float(np.sin(ang)), "k": float(rng.uniform(0.0, 0.4))}
    rt = max(1.3 * a, 3.0 * amp)
    theta = amp * np.exp(0.5) / rt * (1 if rng.random() < 0.5 else -1)
    return kind, {"theta": float(theta), "rt": rt}


def random_field(kind: str, centre: tuple[float, float], radius: float, max_amp: float,
                 rng: np.random.Generator, *, shape: tuple[int, int] | None = None) -> Field:
    """A random field of ``kind`` about ``centre`` (contact radius ``radius`` px), amplitude up to
    ``max_amp`` px (drawn uniformly from 5 % to 100 % of it). With ``shape = (H, W)`` the field is
    scaled down, if needed, until its gradient norm is below :data:`MAX_GRADIENT` there."""
    if kind not in FIELD_KINDS:
        raise ValueError(f"kind: unknown {kind!r}; choose from {list(FIELD_KINDS)}")
    amp = float(rng.uniform(0.05, 1.0) * max_amp)
    if kind == "mix":
        share = rng.dirichlet([1.0, 1.0, 1.0])
        parts = [_part(k, float(s * amp), radius, rng)
                 for k, s in zip(("press", "shear", "twist"), share, strict=True)]
    else:
        parts = [_part(kind, amp, radius, rng)]
    fld = Field(kind, (float(centre[0]), float(centre[1])), parts)
    if shape is not None:
        g = fld.max_gradient(*shape)
        if g > MAX_GRADIENT:
            f = MAX_GRADIENT / g
            for _, p in fld.parts:
                for key in ("amp", "theta"):
                    if key in p:
                        p[key] *= f
    return fld


def _solve_rest(fld: Field, xs: NDArray[np.float64], ys: NDArray[np.float64],
                px: NDArray[np.float64], py: NDArray[np.float64], max_iterations: int,
                tol: float) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Fixed-point iteration ``X <- y - u(X)`` from the guess ``(px, py)``; returns the rest
    points and the largest residual ``|X + u(X) - y|`` (max over x and y components)."""
    res = np.inf
    for _ in range(max_iterations):
        ux, uy = fld(px, py)
        # Residual of the current estimate, before stepping to the next one.
        res = float(max(np.abs(px + ux - xs).max(), np.abs(py + uy - ys).max()))
        if res < tol:
            break
        px, py = xs - ux, ys - uy
    return px, py, res


def backward_map(fld: Field, height: int, width: int, max_iterations: int = 400,
                 tol: float = 1e-3) -> tuple[NDArray[np.float32], NDArray[np.float32], float]:
    """``cv2.remap`` maps ``(map_x, map_y)`` of the warped frame: for each of its pixels ``y``,
    the rest point ``X`` with ``X + u(X) = y``; also the largest residual ``|X + u(X) - y|`` px.

    Solved on a 4 px grid first (the fields are smooth), upsampled bicubically, then polished at
    full resolution until the residual is below ``tol`` px."""
    import cv2

    step = 4
    cy, cx = np.mgrid[0:height + step:step, 0:width + step:step].astype(np.float64)
    qx, qy, _ = _solve_rest(fld, cx, cy, cx.copy(), cy.copy(), max_iterations, tol / 10)
    # Upsample the (smooth) displacement X - y of the coarse grid (node k at pixel k * step).
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    mx = (xs / step).astype(np.float32)
    my = (ys / step).astype(np.float32)
    gx = cv2.remap((qx - cx).astype(np.float32), mx, my, cv2.INTER_CUBIC,
                   borderMode=cv2.BORDER_REPLICATE)
    gy = cv2.remap((qy - cy).astype(np.float32), mx, my, cv2.INTER_CUBIC,
                   borderMode=cv2.BORDER_REPLICATE)
    px, py, res = _solve_rest(fld, xs, ys, xs + gx, ys + gy, max_iterations, tol)
    return px.astype(np.float32), py.astype(np.float32), res


def warp(src: NDArray[np.uint8], fld: Field) -> NDArray[np.uint8]:
    """``src`` with its content moved by ``fld`` (bicubic backward map, reflected borders)."""
    import cv2

    h, w = src.shape[:2]
    mx, my, res = backward_map(fld, h, w)
    if res > 1e-2:
        raise ValueError(f"fld: the backward map did not converge (residual {res:.3g} px); the "
                         "field is too steep")
    out = cv2.remap(src, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    return np.asarray(out, np.uint8)


def marker_grid(sensor: str) -> tuple[NDArray[np.float32], float]:
    """The sensor's regular marker grid ``N x 2`` (x, y) px at its working size, and its pitch."""
    w, h, rows, cols, pitch = SENSORS[sensor]
    xs = (w - 1) / 2 + (np.arange(cols) - (cols - 1) / 2) * pitch
    ys = (h - 1) / 2 + (np.arange(rows) - (rows - 1) / 2) * pitch
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], 1).astype(np.float32), pitch


@dataclass
class RealPresses:
    """taxim's real presses of one sensor at the working size (uint8 BGR)."""

    sensor: str
    f0: NDArray[np.uint8]
    imgs: NDArray[np.uint8]
    centres: NDArray[np.float64]
    radii: NDArray[np.float64]

    def subset(self, keep: slice | NDArray[np.intp]) -> RealPresses:
        """The presses selected by ``keep`` (a slice or indices), same no-contact frame."""
        return RealPresses(self.sensor, self.f0, self.imgs[keep], self.centres[keep],
                           self.radii[keep])


def load_real_presses(sensor: str = "gelsight") -> RealPresses:
    """taxim's real markerless presses of ``sensor`` (``"gelsight"`` 640 x 480 or
    ``"gelsight_mini"``, area-downsampled from 640 x 480 to 320 x 240) with contact centres and
    radii in the working size's pixels. Needs the ``taxim`` package (``tacswitch[test]``)."""
    import cv2

    if sensor not in SENSORS:
        raise ValueError(f"sensor: unknown {sensor!r}; choose from {list(SENSORS)}")
    try:
        import taxim
    except ImportError:
        raise ImportError("the real-texture proxy needs taxim's real frames: "
                          "pip install 'tacswitch[test]'") from None
    pack = np.load(Path(taxim.__file__).parent / "calib" / sensor / "dataPack.npz")
    w, h = SENSORS[sensor][:2]
    f0, imgs = pack["f0"], pack["imgs"]
    k = f0.shape[1] / w
    if k != 1:
        def rs(a: NDArray[np.uint8]) -> NDArray[np.uint8]:
            return np.asarray(cv2.resize(a, (w, h), interpolation=cv2.INTER_AREA), np.uint8)
        f0 = rs(f0)
        imgs = np.stack([rs(a) for a in imgs])
    # Pixel centres at integers: x_small = (x + 0.5) / k - 0.5.
    centres = (pack["touch_center"].astype(np.float64) + 0.5) / k - 0.5
    radii = pack["touch_radius"].astype(np.float64) / k
    return RealPresses(sensor, np.ascontiguousarray(f0), np.ascontiguousarray(imgs), centres,
                       radii)


@dataclass
class ProxySample:
    """One proxy sample: ``img`` (warped, captured), the reference of each setting (``refs``:
    ``"no_contact"``, ``"press"``; the single-frame setting has none), ``rest`` marker centres,
    ``motion`` the true motion at them, and what made it."""

    img: NDArray[np.uint8]
    refs: dict[str, NDArray[np.uint8]]
    rest: NDArray[np.float32]
    motion: NDArray[np.float32]
    field: Field
    press: int
    contact: tuple[float, float, float]

    def ref(self, setting: str) -> NDArray[np.uint8] | None:
        """The reference frame of ``setting`` (None for ``"single"``)."""
        if setting not in SETTINGS:
            raise ValueError(f"setting: unknown {setting!r}; choose from {list(SETTINGS)}")
        return self.refs.get(setting)


def _draw_capture(rng: np.random.Generator, drift: bool) -> Any:
    """A random capture of the proxy: exposure / white-balance drift (``drift``; gain
    0.85-1.15 x 0.95-1.05 per channel, offset +-8), read noise 0.5 and MJPEG q75-95 (60 %) or
    H.264 CRF 18-28. The real frames already hold their optics' blur and sensor noise."""
    from tacswitch.sim import capture

    gain = (rng.uniform(0.85, 1.15) * rng.uniform(0.95, 1.05, 3)) if drift else np.ones(3)
    offset = rng.uniform(-8, 8, 3) if drift else np.zeros(3)
    codec: Literal["mjpeg", "h264"] = "mjpeg" if rng.random() < 0.6 else "h264"
    quality = int(rng.integers(75, 96)) if codec == "mjpeg" else int(rng.integers(18, 29))
    return capture.CaptureProfile(read_noise=0.5,
                                  gain=(float(gain[0]), float(gain[1]), float(gain[2])),
                                  offset=(float(offset[0]), float(offset[1]), float(offset[2])),
                                  codec=codec,
                                  quality=quality)


def _capture(img: NDArray[np.uint8], rng: np.random.Generator, drift: bool) -> NDArray[np.uint8]:
    """One frame through its own random capture (:func:`_draw_capture`)."""
    from tacswitch.sim import capture

    return capture.apply(img, _draw_capture(rng, drift), rng)


def _capture_stream(frames: list[NDArray[np.uint8]], rng: np.random.Generator
                    ) -> list[NDArray[np.uint8]]:
    """Captures ``frames`` as one recording would: the last one gets the exposure /
    white-balance drift, then all go through one codec at one quality (H.264: one stream,
    in order, so the later frames are predicted from the earlier ones; MJPEG: each frame)."""
    from dataclasses import replace

    from tacswitch.sim import capture

    prof = _draw_capture(rng, drift=True)
    last = capture.colour_drift(frames[-1].astype(np.float32), prof.gain, prof.offset)
    seq = [*frames[:-1], np.clip(np.rint(last), 0, 255).astype(np.uint8)]
    steady = replace(prof, gain=(1.0, 1.0, 1.0), offset=(0.0, 0.0, 0.0))
    return list(capture.apply_sequence(seq, steady, rng))


def make_proxy(sensor: str = "gelsight", *, kinds: tuple[str, ...] = FIELD_KINDS,
               per_press: int = 1, seed: int = 0, presses: RealPresses | None = None,
               capture: bool = True, stream: bool = False) -> Iterator[ProxySample]:
    """Yields proxy samples: every real press of ``sensor`` x every field kind x ``per_press``
    random fields, each with the references of every setting (see the module doc).
    Deterministic given ``seed``.

    Args:
        capture: apply the exposure drift and compression (False: the exact warp, for tests).
        stream: capture the no-contact frame, the press and its warp as ONE recording (one codec
            and quality; H.264 as one stream in that order), as a sensor's video holds them;
            default False: each captured on its own, codec drawn per frame (the proxy's
            published numbers; separately encoded H.264 frames show false motion to flow).
            Not bit-for-bit reproducible: under pytest the predicted frames of a stream were
            seen to differ by up to 2 grey levels between runs, rarely (cause not found;
            `h264_roundtrip` itself repeated identically in and across processes).
    """
    data = presses if presses is not None else load_real_presses(sensor)
    rest, _ = marker_grid(data.sensor)
    h, w = data.f0.shape[:2]
    max_amp = MAX_AMPLITUDE_MM / MM_PER_PX[data.sensor]
    for i in range(len(data.imgs)):
        for kind in kinds:
            if kind not in FIELD_KINDS:
                raise ValueError(f"kinds: unknown {kind!r}; choose from {list(FIELD_KINDS)}")
            for rep in range(per_press):
                rng = np.random.default_rng([seed, i, FIELD_KINDS.index(kind), rep])
                c = (float(data.centres[i, 0]), float(data.centres[i, 1]))
                fld = random_field(kind, c, float(data.radii[i]), max_amp, rng, shape=(h, w))
                img = warp(data.imgs[i], fld)
                refs = {"no_contact": data.f0, "press": data.imgs[i]}
                if capture and stream:
                    f0, press, img = _capture_stream([data.f0, data.imgs[i], img], rng)
                    refs = {"no_contact": f0, "press": press}
                elif capture:
                    img = _capture(img, rng, drift=True)
                    refs = {k: _capture(v, rng, drift=False) for k, v in refs.items()}
                yield ProxySample(img, refs, rest, fld.at(rest), fld, i,
                                  (c[0], c[1], float(data.radii[i])))


# --- Real frames with the simulator's field of their own contact ------------------------------
#
# The warp proxy above moves real texture by fields unrelated to the imprint in the frame, so
# from one frame most of its motion is unpredictable in principle. The proxy below keeps the
# real imprint and asks for the motion that contact would cause: the simulator's elastic model
# (:func:`tacswitch.sim.motion.contact_displacement`) applied to a ball press at the recorded
# contact, optionally sheared / twisted (the frame then warped by that shear's field). Its truth
# is MODELLED (real frames, simulated field): it complements the warp proxy, it does not replace
# real marker measurements.

#: Cases of :func:`make_contact_proxy`: the press alone (frame unchanged) or the press plus a
#: stuck shear and / or twist of the same contact (frame warped by the shear's field).
CONTACT_KINDS = ("press", "shear", "twist", "shear_twist")
#: Radius (mm) of the ball that made taxim's real presses, per sensor, measured from their
#: imprints: the simulator's shading of a ball of each candidate radius pressed to every recorded
#: contact (depth ``R - sqrt(R^2 - a^2)`` from the recorded contact radius ``a``) against the
#: real colour change on rings about the contact (``benches/studies/bench_press_calibration.py``,
#: "Geometry"; docs/notes/2026-11-markerless-motion.md, "Real presses: the gel's outward motion
#: (grain block matching) and the calibrated press law"). GelSight: the smallest radius all its
#: contacts allow (a ~1.86 mm,
#: up to 1.98 mm), 2 mm, fits best (relative profile error 0.39 against 0.47-0.76 for
#: 2.25-6 mm): a 4 mm ball pressed 1.0-1.7 mm deep, not the 0.3-0.5 mm that a radius drawn up to
#: 6 mm gave before. GelSight Mini: 3 mm fits best, weakly (0.38 against 0.42-0.44 at 2.5 / 4
#: mm; its real imprint peaks at the centre, the render at the rim), and its gel barely moves
#: under a press anyway.
REAL_BALL_RADIUS_MM: dict[str, float] = {"gelsight": 2.0, "gelsight_mini": 3.0}


@dataclass
class ContactSample:
    """One sample of :func:`make_contact_proxy`: ``img`` (the real press, warped by the
    shear / twist field for those kinds, captured), ``refs`` (``"no_contact"``: the sensor's real
    no-contact frame), ``rest`` marker centres, ``motion`` the modelled motion from rest
    (``N x 2`` px), ``press`` index, ``kind`` and the contact and load parameters."""

    img: NDArray[np.uint8]
    refs: dict[str, NDArray[np.uint8]]
    rest: NDArray[np.float32]
    motion: NDArray[np.float32]
    press: int
    kind: str
    params: dict[str, float]

    def ref(self, setting: str) -> NDArray[np.uint8] | None:
        """The reference frame of ``setting`` (``"no_contact"``; None for ``"single"``)."""
        if setting not in ("no_contact", "single"):
            raise ValueError(f"setting: unknown {setting!r}; choose 'no_contact' or 'single'")
        return self.refs.get(setting)


def _sample_coarse(fld: NDArray[Any], step: int, pts: NDArray[Any]) -> NDArray[np.float32]:
    """The simulator's bilinear read-out of a coarse field at points ``(x, y)`` px (its cell
    ``(i, j)`` is centred on pixel ``((j + 0.5) step - 0.5, (i + 0.5) step - 0.5)``)."""
    from tacswitch.sim.motion import sample_field

    return sample_field(fld, step, np.asarray(pts, np.float64) + (0.5 - 0.5 * step))[0]


def warp_dense(src: NDArray[np.uint8], v: NDArray[np.float32], max_iterations: int = 200,
               tol: float = 1e-3) -> NDArray[np.uint8]:
    """``src`` with its content moved by the dense field ``v`` (``H x W x 2`` px at ``src``'s
    pixels: the point at ``X`` moves to ``X + v(X)``); bicubic backward map, reflected borders.
    ``ValueError`` if the fixed point ``X <- y - v(X)`` does not converge (too steep a field)."""
    import cv2

    if v.shape != (*src.shape[:2], 2):
        raise ValueError(f"v: expected shape {(*src.shape[:2], 2)} to match src; got {v.shape}")
    px, py = dense_backward_map(v, max_iterations, tol)
    return np.asarray(cv2.remap(src, px, py, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT),
                      np.uint8)


def dense_backward_map(v: NDArray[np.float32], max_iterations: int = 200, tol: float = 1e-3
                       ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """The ``cv2.remap`` maps ``(map_x, map_y)`` (``H x W`` float32) that move content by the
    dense field ``v`` (as :func:`warp_dense`): the rest point ``X`` with ``X + v(X) = x`` for
    every pixel ``x``, by fixed-point iteration. ``ValueError`` if it does not converge."""
    import cv2

    if v.ndim != 3 or v.shape[2] != 2:
        raise ValueError(f"v: expected an H x W x 2 field; got shape {v.shape}")
    h, w = v.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    vx = np.ascontiguousarray(v[..., 0], np.float32)
    vy = np.ascontiguousarray(v[..., 1], np.float32)
    px, py = xs.copy(), ys.copy()
    res = np.inf
    for _ in range(max_iterations):
        ux = cv2.remap(vx, px, py, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        uy = cv2.remap(vy, px, py, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        res = float(max(np.abs(px + ux - xs).max(), np.abs(py + uy - ys).max()))
        if res < tol:
            break
        px, py = xs - ux, ys - uy
    if res > 1e-2:
        raise ValueError(f"v: the backward map did not converge (residual {res:.3g} px)")
    return px, py


def contact_fields(sensor: str, centre: tuple[float, float], radius_px: float, kind: str,
                   rng: np.random.Generator, *, dilation: float | None = None,
                   decay_mm: float | None = None, ball_radius_mm: float | None = None
                   ) -> tuple[NDArray[np.float32], NDArray[np.float32], int, dict[str, float]]:
    """The simulator's coarse fields of a ball press at ``centre`` whose contact radius is
    ``radius_px`` (px at the sensor's working size): the press's own outward field and the
    shear / twist field of ``kind`` (zero for ``"press"``), the grid step, and the draws.

    Draws, as the simulator's scenes do (:class:`tacswitch.sim.scene.Scene`,
    :func:`tacswitch.sim.scene.render_sample`): ball radius ``R`` ~ U(max(2, 1.2 a), 6) mm (the
    simulator's spheres; the depth then follows from the recorded contact radius ``a``:
    ``R - sqrt(R^2 - a^2)``), dilation gain uniform in the preset's ``press_dilation`` range
    with its ``press_decay_mm`` reach (measured on real presses, :mod:`tacswitch.sim.presets`),
    stuck shear ``pitch * U(0, 0.9)^1.5`` in a random direction, load ratio U(0, 0.95), twist
    U(-0.08, 0.08) rad. ``dilation`` / ``decay_mm`` override the press law's gain (the draw is
    still made, so the other draws do not change) and reach (calibration); ``ball_radius_mm``
    the ball's radius (mm, greater than the contact radius; the draw is still made), e.g.
    :data:`REAL_BALL_RADIUS_MM` for taxim's real presses, whose ball is known.
    """
    from tacswitch.sim.motion import ball_press, contact_displacement
    from tacswitch.sim.presets import get_preset

    if kind not in CONTACT_KINDS:
        raise ValueError(f"kind: unknown {kind!r}; choose from {list(CONTACT_KINDS)}")
    p = get_preset(sensor)
    a_mm = radius_px * p.mm_per_px
    big_r = float(rng.uniform(max(2.0, 1.2 * a_mm), 6.0))
    if ball_radius_mm is not None:
        big_r = float(ball_radius_mm)  # ball_press checks it against the contact radius
    drawn = float(rng.uniform(*p.press_dilation))
    dilation = drawn if dilation is None else float(dilation)
    press, pres, _, st = ball_press(p, centre, radius_px, big_r, dilation, decay_mm)
    depth = big_r - float(np.sqrt(big_r ** 2 - a_mm ** 2))
    params = {"ball_radius_mm": big_r, "depth_mm": depth, "dilation": dilation}
    shear = (0.0, 0.0)
    twist = 0.0
    load = float(rng.uniform(0.0, 0.95))
    if kind in ("shear", "shear_twist"):
        mag = p.pitch * float(rng.uniform(0.0, 0.9)) ** 1.5
        ang = float(rng.uniform(0, 2 * np.pi))
        shear = (mag * float(np.cos(ang)), mag * float(np.sin(ang)))
    if kind in ("twist", "shear_twist"):
        twist = float(rng.uniform(-0.08, 0.08))
    if kind == "press":
        other = np.zeros_like(press)
    else:
        other, _ = contact_displacement(pres, st, p.mm_per_px, p.gel_thickness_mm,
                                        centre=centre, shear_px=shear, load_ratio=load,
                                        twist_rad=twist)
        params |= {"shear_x": shear[0], "shear_y": shear[1], "load_ratio": load,
                   "twist_rad": twist}
    return press, other, st, params


def _stuck_load(data: RealPresses, i: int, kind: str, rng: np.random.Generator,
                rest: NDArray[np.float32]
                ) -> tuple[NDArray[np.float32], NDArray[np.float32] | None,
                           NDArray[np.float32], dict[str, float]]:
    """Press ``i``'s modelled fields for ``kind``: ``(u_p at rest, dense stuck field v or None
    for a press, v's motion at the pressed markers v(X + u_p), params)``; ``v`` is scaled down
    where its gradient would make the backward warp no contraction."""
    from tacswitch.sim.grain import dense_field

    if kind not in CONTACT_KINDS:
        raise ValueError(f"kinds: unknown {kind!r}; choose from {list(CONTACT_KINDS)}")
    h, w = data.f0.shape[:2]
    c = (float(data.centres[i, 0]), float(data.centres[i, 1]))
    press, other, st, params = contact_fields(
        data.sensor, c, float(data.radii[i]), kind, rng,
        ball_radius_mm=REAL_BALL_RADIUS_MM[data.sensor])
    up = _sample_coarse(press, st, rest)
    if kind == "press":
        return up, None, np.zeros_like(up), params
    v = dense_field(other, st, h, w)
    gy = np.gradient(v, axis=0)
    gx = np.gradient(v, axis=1)
    jac = np.stack([gx, gy], -1)  # jac[..., i, j] = d v_i / d x_j
    g = float(np.linalg.norm(jac, ord=2, axis=(-2, -1)).max())
    if g > MAX_GRADIENT:  # keep the backward map a contraction
        other = other * np.float32(MAX_GRADIENT / g)
        v = v * np.float32(MAX_GRADIENT / g)
        params["scaled"] = MAX_GRADIENT / g
    return up, v, _sample_coarse(other, st, rest + up), params


def make_contact_proxy(sensor: str = "gelsight", *, kinds: tuple[str, ...] = CONTACT_KINDS,
                       seed: int = 0, presses: RealPresses | None = None,
                       capture: bool = True) -> Iterator[ContactSample]:
    """Yields a sample per real press of ``sensor`` and case of ``kinds`` (module section doc):
    the truth at the sensor's marker grid is the simulator's press field ``u_p`` of taxim's ball
    (:data:`REAL_BALL_RADIUS_MM`) pressed to the recorded ``touch_center`` / ``touch_radius``
    (the press law calibrated on the same presses) plus, for shear / twist cases, that
    contact's shear field ``v`` read at the pressed positions: ``u_p(X) + v(X + u_p(X))``; the
    real press frame is then warped by ``v`` (its imprint and grain move with the stuck zone).
    The real press's own lateral motion is unknown: the modelled ``u_p`` stands for it.
    Deterministic given ``seed``; ``capture`` as in :func:`make_proxy`."""
    data = presses if presses is not None else load_real_presses(sensor)
    rest, _ = marker_grid(data.sensor)
    for i in range(len(data.imgs)):
        for kind in kinds:
            rng = np.random.default_rng([seed, i, CONTACT_KINDS.index(kind)
                                         if kind in CONTACT_KINDS else 0, 17])
            up, v, vs, params = _stuck_load(data, i, kind, rng, rest)
            img = data.imgs[i]
            motion = up + vs
            if v is not None:
                img = warp_dense(img, v)
            refs = {"no_contact": data.f0}
            if capture:
                img = _capture(img, rng, drift=True)
                refs = {"no_contact": _capture(data.f0, rng, drift=False)}
            yield ContactSample(img, refs, rest, motion.astype(np.float32), i, kind, params)


#: Press depths (fractions of the recorded press) and shear fractions of :func:`make_ramp_proxy`.
RAMP_PRESS = (1 / 3, 2 / 3, 1.0)
RAMP_SHEAR = (0.25, 0.5, 0.75, 1.0)


@dataclass
class RampSequence:
    """One recording of :func:`make_ramp_proxy`: ``frames`` after the no-contact frame
    ``no_contact``, ``truths`` (motion from rest per frame, ``N x 2`` px) at ``rest``, and
    ``pressed`` (index of the frame with the full press, before the shear)."""

    frames: list[NDArray[np.uint8]]
    no_contact: NDArray[np.uint8]
    rest: NDArray[np.float32]
    truths: list[NDArray[np.float32]]
    pressed: int
    press: int
    kind: str


def make_ramp_proxy(sensor: str = "gelsight", *, kinds: tuple[str, ...] = ("shear", "twist",
                                                                           "shear_twist"),
                    seed: int = 0, presses: RealPresses | None = None) -> Iterator[RampSequence]:
    """Yields a press-then-shear recording per real press of ``sensor`` and case of ``kinds``:
    the no-contact frame; the press built up over :data:`RAMP_PRESS` (the real press's colour
    change scaled, truth ``s u_p``: a stand-in for a deepening contact); then the full press
    warped by growing fractions :data:`RAMP_SHEAR` of its stuck field (truth
    ``u_p + r v(X + u_p)``, as :func:`make_contact_proxy`). All frames go through one capture,
    as one recording (:func:`_capture_stream`). Real texture and imprint, modelled motion; the
    motion after the full press is the warp alone, known exactly."""
    data = presses if presses is not None else load_real_presses(sensor)
    rest, _ = marker_grid(data.sensor)
    f0 = data.f0.astype(np.float32)
    for i in range(len(data.imgs)):
        for kind in kinds:
            rng = np.random.default_rng([seed, i, CONTACT_KINDS.index(kind)
                                         if kind in CONTACT_KINDS else 0, 17])
            up, v, vs, _ = _stuck_load(data, i, kind, rng, rest)
            pi = data.imgs[i].astype(np.float32)
            frames = [np.clip(np.rint(f0 + s * (pi - f0)), 0, 255).astype(np.uint8)
                      for s in RAMP_PRESS]
            truths = [(s * up).astype(np.float32) for s in RAMP_PRESS]
            for r in RAMP_SHEAR:
                frames.append(data.imgs[i] if v is None
                              else warp_dense(data.imgs[i], (r * v).astype(np.float32)))
                truths.append((up + r * vs).astype(np.float32))
            cap = _capture_stream([data.f0, *frames], rng)
            yield RampSequence(cap[1:], cap[0], rest, truths, len(RAMP_PRESS) - 1, i, kind)
