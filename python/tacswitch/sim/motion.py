"""Marker displacement fields of simple contacts (pixels, ``(dx, dy)`` per marker).

Smooth approximations of the elastic response of a gel pad: inside the contact the surface follows
the indenter, outside the motion decays with distance. The finite-thickness elastic kernels of the
full simulator replace these; their shapes and magnitudes are what tracking and slip need.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from tacswitch.sim.presets import SensorPreset


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


# --- Elastic fields of a pressed, sheared and twisted contact -----------------------------------
#
# The fields below are computed on a coarse grid (``step`` px per cell): gel motion is smooth on
# the scale of a marker, and the FFT convolutions stay cheap at any resolution.


def _cerruti_fft(gh: int, gw: int, step_mm: float, thickness_mm: float, nu: float
                 ) -> tuple[NDArray, NDArray, NDArray, tuple[int, int]]:
    """FFTs of the surface Cerruti kernels of a half-space, cut off at the gel thickness.

    A tangential point force ``Q`` on an elastic half-space moves the surface by (Johnson,
    *Contact Mechanics*, eq. 3.86b, up to the factor ``1 / (2 pi G)``)
    ``u = Q [(1 - nu) / rho + nu x x^T / rho^3]``. A gel layer bonded to rigid glass cannot move
    far from the load: the factor ``exp(-rho / thickness)`` is the finite-thickness cutoff.
    """
    ph, pw = 2 * gh, 2 * gw
    ky = np.fft.fftfreq(ph, 1.0 / ph)[:, None] * step_mm
    kx = np.fft.fftfreq(pw, 1.0 / pw)[None, :] * step_mm
    # The centre cell carries the integral of 1/rho over its own area (regularised singularity).
    rho = np.sqrt(kx * kx + ky * ky + (0.5 * step_mm) ** 2)
    cut = np.exp(-rho / thickness_mm) / rho
    kxx = ((1 - nu) + nu * kx * kx / rho**2) * cut
    kxy = (nu * kx * ky / rho**2) * cut
    kyy = ((1 - nu) + nu * ky * ky / rho**2) * cut
    return np.fft.rfft2(kxx), np.fft.rfft2(kxy), np.fft.rfft2(kyy), (ph, pw)


def elastic_displacement(traction: NDArray, step_mm: float, thickness_mm: float,
                         nu: float = 0.45) -> NDArray[np.float64]:
    """Surface displacement (arbitrary units) of a tangential traction field ``gh x gw x 2``."""
    gh, gw = traction.shape[:2]
    kxx, kxy, kyy, (ph, pw) = _cerruti_fft(gh, gw, step_mm, thickness_mm, nu)
    fx = np.fft.rfft2(traction[..., 0], (ph, pw))
    fy = np.fft.rfft2(traction[..., 1], (ph, pw))
    ux = np.fft.irfft2(kxx * fx + kxy * fy, (ph, pw))[:gh, :gw]
    uy = np.fft.irfft2(kxy * fx + kyy * fy, (ph, pw))[:gh, :gw]
    return np.stack([ux, uy], axis=-1)


def stick_cap(pressure: NDArray, load_ratio: float) -> float:
    """Traction cap ``tau`` (pressure units, friction coefficient 1) for a ratio ``Q / (mu P)``.

    Cattaneo-Mindlin partial slip generalised to any pressure field: where ``mu p`` is below the
    cap the contact slips and carries its friction limit; where it is above, the contact sticks
    and carries the cap. ``sum(min(p, tau)) = load_ratio * sum(p)``; as the ratio approaches 1 the
    stuck zone (``p > tau``) shrinks from the edge of the contact to nothing.
    """
    p = np.sort(pressure[pressure > 0].ravel())
    if p.size == 0 or load_ratio <= 0:
        return float(p[-1]) if p.size else 0.0
    if load_ratio >= 1:
        return 0.0
    # sum(min(p, tau)) over sorted p: cumulative sum below tau plus tau times the count above.
    target = load_ratio * p.sum()
    csum = np.concatenate([[0.0], np.cumsum(p)])
    n = p.size
    lo, hi = 0.0, float(p[-1])
    for _ in range(40):
        tau = 0.5 * (lo + hi)
        k = int(np.searchsorted(p, tau))
        if csum[k] + tau * (n - k) < target:
            lo = tau
        else:
            hi = tau
    return 0.5 * (lo + hi)


def thickness_blur(a: NDArray, sigma_cells: float) -> NDArray[np.float32]:
    """``a`` (a coarse ``gh x gw`` map) blurred by a Gaussian of one gel thickness,
    ``sigma_cells`` grid cells (at least 0.5), edges reflected: the smoothing of the press
    dilation law (the gel flows outward along ``-grad`` of it), shared with the markerless
    mechanics rule."""
    import cv2

    s = max(float(sigma_cells), 0.5)
    k = int(2 * np.ceil(3 * s) + 1)
    return np.asarray(cv2.GaussianBlur(np.asarray(a, np.float32), (k, k), s,
                                       borderType=cv2.BORDER_REFLECT_101), np.float32)


def contact_displacement(
    pressure: NDArray,
    step_px: float,
    mm_per_px: float,
    thickness_mm: float,
    *,
    centre: tuple[float, float],
    shear_px: tuple[float, float] = (0.0, 0.0),
    load_ratio: float = 0.5,
    twist_rad: float = 0.0,
    dilation: float = 0.0,
    gel: NDArray | None = None,
    decay_mm: float | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """Gel surface displacement of one contact on a coarse grid, pixels ``(dx, dy)`` per cell.

    Args:
        pressure: ``gh x gw`` contact pressure (any unit; 0 off the contact) on the coarse grid.
        step_px: grid cell size, px; cell ``(i, j)`` is centred on pixel ``(j, i) * step_px``.
        mm_per_px, thickness_mm: sensor scale and gel thickness (cutoff of the kernels).
        centre: contact centre ``(x, y)`` px (the axis of the twist).
        shear_px: displacement of the stuck zone (the object's tangential motion), px.
        load_ratio: ``Q / (mu P)`` in [0, 1]: partial slip (see :func:`stick_cap`).
        twist_rad: rotation of the stuck zone about ``centre``, rad.
        dilation: normal-press dilation gain: the surface flows outward by
            ``dilation * thickness * -grad(blurred indentation)`` (incompressible layer squeezed
            out from under the indenter); needs ``gel`` (coarse indentation, mm).
        gel: ``gh x gw`` gel indentation, mm.
        decay_mm: width (Gaussian sigma, mm) of that smoothing, i.e. how far the press's outward
            flow reaches; None: ``thickness_mm``. The presets' measured values:
            :attr:`tacswitch.sim.presets.SensorPreset.press_decay_mm`.

    Returns:
        ``(field, stick)``: ``gh x gw x 2`` float32 displacement (px) and the stuck-zone mask.
    """
    gh, gw = pressure.shape
    step_mm = step_px * mm_per_px
    out = np.zeros((gh, gw, 2), np.float64)
    tau = stick_cap(pressure, load_ratio)
    q = np.minimum(pressure, tau)
    stick = pressure > tau
    contact = pressure > 0
    zone = stick if stick.any() else contact
    if np.hypot(*shear_px) > 0 and contact.any():
        e = np.asarray(shear_px, np.float64) / np.hypot(*shear_px)
        u = elastic_displacement(q[..., None] * e, step_mm, thickness_mm)
        # Scale so the stuck zone moves with the object: its mean motion is the commanded shear.
        along = (u[zone] @ e).mean()
        if along > 0:
            out += u * (np.hypot(*shear_px) / along)
    if twist_rad != 0 and contact.any():
        gy, gx = np.mgrid[0:gh, 0:gw] * step_px
        rel = np.stack([gx - centre[0], gy - centre[1]], axis=-1)
        rigid = np.stack([-rel[..., 1], rel[..., 0]], axis=-1) * twist_rad
        u = elastic_displacement(np.where(contact, q, 0.0)[..., None] * rigid, step_mm,
                                 thickness_mm)
        den = (u[zone] * u[zone]).sum()
        if den > 0:
            out += u * ((u[zone] * rigid[zone]).sum() / den)
    if dilation != 0 and gel is not None:
        smooth = thickness_blur(gel, (thickness_mm if decay_mm is None else decay_mm) / step_mm)
        dy, dx = np.gradient(smooth, step_mm)
        out -= dilation * thickness_mm / mm_per_px * np.stack([dx, dy], axis=-1)
    return out.astype(np.float32), stick


def sample_field(field: NDArray, step_px: float, pts: NDArray
                 ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Bilinear samples of a coarse field at points ``(x, y)`` px, and its Jacobian there.

    Returns ``(values N x 2, jacobian N x 2 x 2)`` where ``jacobian[n] = d(value) / d(x, y)``.
    """
    gh, gw = field.shape[:2]
    p = np.asarray(pts, np.float64) / step_px
    x = np.clip(p[:, 0], 0, gw - 1.000001)
    y = np.clip(p[:, 1], 0, gh - 1.000001)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    f00, f01 = field[y0, x0], field[y0, x0 + 1]
    f10, f11 = field[y0 + 1, x0], field[y0 + 1, x0 + 1]
    val = (f00 * (1 - fx) + f01 * fx) * (1 - fy) + (f10 * (1 - fx) + f11 * fx) * fy
    ddx = ((f01 - f00) * (1 - fy) + (f11 - f10) * fy) / step_px
    ddy = ((f10 - f00) * (1 - fx) + (f11 - f01) * fx) / step_px
    jac = np.stack([ddx, ddy], axis=-1)  # jac[n, i, j] = d value_i / d coord_j
    return val.astype(np.float32), jac.astype(np.float32)


def pressed_ball(height: int, width: int, mm_per_px: float, centre: tuple[float, float],
                 radius_px: float, ball_radius_mm: float
                 ) -> tuple[NDArray[np.float32], NDArray[np.bool_], float]:
    """A ball of radius ``ball_radius_mm`` pressed into a flat gel (``height x width`` px of
    ``mm_per_px``) at ``centre`` ``(x, y)`` px until its contact radius is ``radius_px``: the gel
    surface (mm, :func:`tacswitch.sim.deform.deform_gel`), the contact mask and the depth
    ``R - sqrt(R^2 - a^2)`` (mm). ``ValueError`` naming ``ball_radius_mm`` unless it exceeds
    the contact radius."""
    from tacswitch.sim.deform import deform_gel
    from tacswitch.sim.indenters import ObjectSpec

    a_mm = radius_px * mm_per_px
    if not (np.isfinite(ball_radius_mm) and ball_radius_mm > a_mm):
        raise ValueError(f"ball_radius_mm: must be finite and exceed the contact radius "
                         f"{a_mm:.3g} mm; got {ball_radius_mm!r}")
    depth = ball_radius_mm - float(np.sqrt(ball_radius_mm ** 2 - a_mm ** 2))
    z = ObjectSpec("sphere", {"radius": ball_radius_mm}).surface(height, width, mm_per_px,
                                                                 centre, 0.0, depth)
    gel, contact = deform_gel(z, mm_per_px)
    return gel, contact, depth


def ball_press(preset: SensorPreset, centre: tuple[float, float], radius_px: float,
               ball_radius_mm: float, dilation: float, decay_mm: float | None = None
               ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], int]:
    """The press field of a ball of radius ``ball_radius_mm`` pressed into ``preset``'s gel at
    ``centre`` ``(x, y)`` px until its contact radius is ``radius_px`` (:func:`pressed_ball`),
    with the press law's ``dilation`` gain and reach ``decay_mm`` (None: the preset's measured
    ``press_decay_mm``).

    Returns ``(field, pressure, gel, step)``: the coarse ``gh x gw x 2`` outward field (px; cell
    ``(i, j)`` centred on pixel ``((j + 0.5) step - 0.5, (i + 0.5) step - 0.5)``), the coarse
    contact pressure and indentation (mm) it came from (for shear / twist fields of the same
    contact), and the grid step ``step`` px."""
    import cv2

    p = preset
    h, w = p.height, p.width
    gel, contact, _ = pressed_ball(h, w, p.mm_per_px, centre, radius_px, ball_radius_mm)
    st = max(2, round(w / 80))
    gh, gw = -(-h // st), -(-w // st)
    pen = np.where(contact, np.maximum(gel, 0), 0).astype(np.float32)
    pres = np.asarray(cv2.resize(pen, (gw, gh), interpolation=cv2.INTER_AREA), np.float32)
    gel_c = np.asarray(cv2.resize(gel, (gw, gh), interpolation=cv2.INTER_AREA), np.float32)
    decay = p.press_decay_mm if decay_mm is None else decay_mm
    fld, _ = contact_displacement(pres, st, p.mm_per_px, p.gel_thickness_mm, centre=centre,
                                  dilation=dilation, gel=gel_c, decay_mm=decay)
    return fld, pres, gel_c, st
