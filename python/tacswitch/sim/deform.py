"""Gel deformation under an indenter: Taxim-style pyramid Gaussian smoothing.

Conventions: heights are in **mm toward the camera**, measured from the undeformed gel surface
(0 = rest, positive = pushed in by the object). An object's surface ``z_obj`` is positive where it
penetrates the rest surface. Arrays are ``H x W`` float32 on the sensor's pixel grid.
"""

from __future__ import annotations

from typing import cast

import numpy as np
from numpy.typing import NDArray

#: Smoothing pyramid, coarse to fine, in mm on the gel. Taxim's GelSight values (fractions of the
#: 640-px frame width times 0.0295 mm/px), kept physical so every resolution deforms alike.
PYRAMID_SIGMA_MM: tuple[float, ...] = (0.8996, 0.4572, 0.2360, 0.1032, 0.0590, 0.0324)
#: Final smoothing of the gel surface, mm.
FINAL_SIGMA_MM = 0.0590
#: Fraction of the press depth below which the gel is *not* pinned to the object while
#: smoothing (Taxim's ``contact_scale``): the rim of a contact is free to round off.
CONTACT_SCALE = 0.4
#: Penetration above which a pixel counts as in contact (contact-mask label), mm.
CONTACT_TOL_MM = 0.01


def gaussian_blur(img: NDArray[np.float32], sigma_px: float) -> NDArray[np.float32]:
    """Gaussian blur with reflected borders (``cv2.GaussianBlur``, ``BORDER_REFLECT_101``)."""
    import cv2

    if sigma_px < 0.3:
        return img
    k = int(2 * np.ceil(3 * sigma_px) + 1)
    # The blur keeps the input's float32 dtype.
    return cast("NDArray[np.float32]",
                cv2.GaussianBlur(img, (k, k), sigma_px, borderType=cv2.BORDER_REFLECT_101))


def deform_gel(
    z_obj: NDArray, mm_per_px: float, *, contact_scale: float = CONTACT_SCALE
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """Surface of the gel pressed by an object, and the contact mask.

    The gel takes the object's shape where it is pressed deepest (``z_obj > contact_scale *
    depth``) and relaxes smoothly elsewhere: the union of object and rest surface is blurred
    level by level of :data:`PYRAMID_SIGMA_MM` with the deep contact re-pinned after each level,
    then blurred once more (Taxim's approximation of the elastomer's bending).

    Args:
        z_obj: object surface, mm toward the camera (``-inf`` where there is no object).
        mm_per_px: pixel size on the gel, mm.
        contact_scale: see :data:`CONTACT_SCALE`.

    Returns:
        ``(gel, contact)``: gel surface in mm (``H x W`` float32, >= 0) and the contact mask
        (``H x W`` bool: the object penetrates the rest surface by more than
        :data:`CONTACT_TOL_MM`).
    """
    z = np.asarray(z_obj, np.float32)
    joined = np.maximum(z, 0.0).astype(np.float32)
    depth = float(joined.max())
    contact = z > CONTACT_TOL_MM
    if depth <= 0:
        return np.zeros_like(joined), contact
    pinned = z > contact_scale * depth
    gel = joined
    for s in PYRAMID_SIGMA_MM:
        gel = gaussian_blur(gel, s / mm_per_px)
        gel[pinned] = joined[pinned]
    gel = gaussian_blur(gel, FINAL_SIGMA_MM / mm_per_px)
    return np.maximum(gel, 0.0), contact
