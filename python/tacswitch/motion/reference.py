"""What kind of reference a markerless pair has: does ``ref`` lack the contact ``img`` shows?

Optical flow from a reference follows what moves between the two frames. With a reference of the
same contact (the grasp start, an earlier frame) the imprint is in both frames and moves with the
gel, and flow is the best method measured (real texture warped by known fields: 2.7 px against
10.2 px for zero motion at 640 x 480, cosine 0.97). Against the no-contact frame the imprint
*appears*: its shading is not motion, and DIS turns it into 4-20 px of false motion within about
two contact radii on taxim's real presses (where the gel moves 1-3 px); the contact-mechanics
rule, which reads the imprint's shape instead, is then far better (real frames with the
calibrated press field: 1.64 px against flow's 4.45 and zero's 2.74). ``predict_motion``'s
``method="auto"`` therefore asks this module which case a pair is.

The cue: where the two frames differ (relative change of the blurred grey level above
:data:`CHANGE`, after matching the median gain), a new contact has its shading gradients in
``img`` only — the reference shows flat gel there — while a reference of the same contact (at
another depth or load, or sheared) has them too. :func:`contact_energy_ratio` is the gradient
energy of ``ref`` over that of ``img`` inside the changed region; a ratio under
:data:`NEW_CONTACT_RATIO` means a new contact.

Measured (``benches/studies/bench_motion_reference.py``; docs/notes/2026-11-markerless-motion.md,
"Markerless motion: which reference"): taxim's real no-contact frame against its 48 GelSight
presses 0.17-0.53, against
the 24 GelSight Mini presses 0.01-0.03; the same presses warped by known fields and captured
(MJPEG / H.264, exposure drift), against the no-contact frame 0.14-0.68 / 0.01-0.45 and against
the unwarped press (the same contact) 0.59-1.22 / 0.58-1.19; simulated held-out pairs:
no-contact 0.02-1.0 (the shallowest presses overlap, where both methods give little motion),
the same contact at another depth and load 0.68-2.2. The threshold sits in the gap of the real
frames (:data:`NEW_CONTACT_RATIO`); no accuracy figure was used to choose it. Cost: 0.5 ms at
320 x 240, 1.2 ms at 640 x 480 (the frames are area-downsampled to :data:`WORK_WIDTH` first).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["CHANGE", "CONTACT_REACH", "MIN_NEAR_MARKERS", "NEW_CONTACT_RATIO", "WORK_WIDTH",
           "contact_changed", "contact_energy_ratio", "is_new_contact", "is_unchanged",
           "near_contact"]

#: Width (px) the frames are area-downsampled to before the test (a coarse, cheap statistic).
WORK_WIDTH = 160
#: Relative grey-level change (after gain matching) that marks the changed region.
CHANGE = 0.04
#: Smallest changed region, a fraction of the frame's pixels: below it nothing new is there.
MIN_CHANGED_FRAC = 0.002
#: :func:`contact_energy_ratio` below this: ``ref`` lacks ``img``'s contact.
NEW_CONTACT_RATIO = 0.6
#: :func:`near_contact`: how far from the changed region a marker still counts, a fraction of
#: the frame width (16 px at 320 wide, about half a GelSight Mini pitch; a coarse grid's cell
#: can hold a small contact farther than that from every marker, hence
#: :data:`MIN_NEAR_MARKERS`). Chosen among 0.05-0.25 on development grasps (real-texture
#: videos of ``benches/studies/bench_slip_real_texture.py`` at seed 1, presses 2, 8, 14, ... of
#: taxim's recordings, H.264 CRF 23 / 28 and MJPEG; simulated grasps of seed 200): the fewest false
#: alarms on H.264, every slip still found by the displacement rule.
CONTACT_REACH = 0.05
#: :func:`near_contact` keeps at least this many markers, the nearest to the contact (the
#: rigid-fit slip criterion needs 3).
MIN_NEAR_MARKERS = 3


def _grey_small(img: NDArray[np.uint8], k: int) -> NDArray[np.float32]:
    import cv2

    g: Any = img
    if g.ndim == 3:
        g = cv2.cvtColor(g, cv2.COLOR_BGRA2GRAY if g.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if k > 1:
        h, w = g.shape
        g = cv2.resize(g, (max(1, w // k), max(1, h // k)), interpolation=cv2.INTER_AREA)
    return np.asarray(g, np.float32)


def _gradient_energy(b: NDArray[np.float32], region: NDArray[np.float32]) -> float:
    """Sum of the squared Sobel gradient of ``b`` over ``region`` (a 0 / 1 float mask)."""
    import cv2

    gx = cv2.Sobel(b, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(b, cv2.CV_32F, 0, 1, ksize=3)
    return float(np.vdot(gx * gx + gy * gy, region))


def _blurred(img: NDArray[np.uint8], k: int) -> NDArray[np.float32]:
    """``img`` grey, area-downsampled by ``k`` and blurred for the comparison."""
    import cv2

    g = _grey_small(img, k)
    s = max(1.0, g.shape[1] / 80.0)
    return np.asarray(cv2.GaussianBlur(g, (0, 0), s, borderType=cv2.BORDER_REFLECT), np.float32)


def _compare(bi: NDArray[np.float32], br: NDArray[np.float32]
             ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """``bi`` gain-matched to ``br`` (a new array) and the region where they differ (0 / 1
    float mask)."""
    # Median gain (on every 4th pixel each way: the blurred frames are smooth at that scale): a
    # contact changes a small part of the frame, a drift all of it.
    gain = float(np.median(bi[::4, ::4])) / max(float(np.median(br[::4, ::4])), 1.0)
    bi = bi * np.float32(1.0 / max(gain, 1e-3))
    region = (np.abs(bi - br) > np.float32(CHANGE) * np.maximum(br, 4.0)).astype(np.float32)
    return bi, region


def _changed(img: NDArray[np.uint8], ref: NDArray[np.uint8]
             ) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32], int]:
    """``(img, ref)`` grey, area-downsampled by ``k`` to about :data:`WORK_WIDTH`, blurred and
    gain-matched, the region where they differ (0 / 1 float mask at that size), and ``k``."""
    k = max(1, round(img.shape[1] / WORK_WIDTH))
    br = _blurred(ref, k)
    bi, region = _compare(_blurred(img, k), br)
    return bi, br, region, k


def _too_small(region: NDArray[np.float32]) -> bool:
    """Whether a changed region (0 / 1 float mask) is too small to hold a contact."""
    return float(region.sum()) < max(4.0, MIN_CHANGED_FRAC * region.size)


def _energy_ratio(bi: NDArray[np.float32], br: NDArray[np.float32],
                  region: NDArray[np.float32]) -> float:
    """:func:`contact_energy_ratio` of the compared frames."""
    if _too_small(region):
        return 1.0
    e_img = _gradient_energy(bi, region)
    if e_img <= 0:
        return 1.0
    return _gradient_energy(br, region) / e_img


def near_contact(img: Any, no_contact: Any, centres: Any, reach: float = CONTACT_REACH, *,
                 fallback: bool = True) -> NDArray[np.bool_] | None:
    """Which markers lie near the contact ``img`` shows: those within ``reach`` x the frame
    width of where ``img`` differs from the no-contact frame (the region
    :func:`contact_energy_ratio` uses), and at least the :data:`MIN_NEAR_MARKERS` nearest to it
    (a small contact in a coarse grid's cell, or off the grid, still has markers to judge). The
    gel moves most there (on the real FOTS GelSight Mini shear frame: 10-12 px on the contact,
    2-3 px at the border), so the largest motion, which the slip rule judges, is there.

    Args:
        img: ``H x W x 3`` (or ``H x W``) uint8 frame with the contact.
        no_contact: uint8 frame of the same sensor without contact, the same shape.
        centres: ``N x 2`` marker rest centres ``(x, y)`` px.
        reach: fraction of the frame width, >= 0.
        fallback: when nothing changed (no contact to place): every marker (True) or None.

    Returns:
        ``N`` bools, or None (``fallback=False`` and nothing changed).
    """
    import cv2

    from tacswitch._checks import as_image, as_number, as_points

    a = as_image(img, "img", any_channels=True)
    b = as_image(no_contact, "no_contact", any_channels=True)
    if a.shape != b.shape:
        raise ValueError(f"no_contact: shape {b.shape} does not match img {a.shape}")
    pts = as_points(centres, "centres")
    reach = as_number(reach, "reach", 0.0)
    n = len(pts)
    _, _, region, k = _changed(a, b)
    if _too_small(region):
        return np.ones(n, bool) if fallback else None
    if n == 0:
        return np.zeros(0, bool)
    # Distance (px at the small size) from every pixel to the changed region.
    dist = cv2.distanceTransform((region == 0).astype(np.uint8), cv2.DIST_L2, 5)
    idx = ((pts.astype(np.float64) + 0.5) / k - 0.5).round().astype(np.int64)
    h, w = dist.shape
    d = dist[np.clip(idx[:, 1], 0, h - 1), np.clip(idx[:, 0], 0, w - 1)]
    near = d <= reach * w
    if near.sum() < min(MIN_NEAR_MARKERS, n):
        near[np.argsort(d, kind="stable")[:MIN_NEAR_MARKERS]] = True
    return np.asarray(near, bool)


def contact_energy_ratio(img: NDArray[np.uint8], ref: NDArray[np.uint8]) -> float:
    """Shading-gradient energy of ``ref`` over that of ``img`` where the two frames differ
    (uint8 frames of one shape, BGR, BGRA or grey); 1.0 when nothing changed (identical
    frames, a pure brightness change). Small: ``ref`` shows flat gel where ``img`` has a
    contact (see the module doc)."""
    from tacswitch._checks import as_image_u8

    img = as_image_u8(img, "img")
    ref = as_image_u8(ref, "ref")
    if ref.shape != img.shape:
        raise ValueError(f"ref: shape {ref.shape} does not match img {img.shape}")
    bi, br, region, _ = _changed(img, ref)
    return _energy_ratio(bi, br, region)


def is_new_contact(img: NDArray[np.uint8], ref: NDArray[np.uint8]) -> bool:
    """True when ``img`` shows a contact that ``ref`` lacks (``ref`` is a no-contact frame for
    it): :func:`contact_energy_ratio` below :data:`NEW_CONTACT_RATIO`."""
    return contact_energy_ratio(img, ref) < NEW_CONTACT_RATIO


def is_unchanged(img: NDArray[np.uint8], ref: NDArray[np.uint8]) -> bool:
    """True when nothing in ``img`` differs from ``ref`` (validated uint8 frames of one shape):
    the region whose blurred grey level changed by more than :data:`CHANGE` (after matching the
    median gain) is under :data:`MIN_CHANGED_FRAC` of the frame. Stricter than ``not
    is_new_contact``: a contact that grew or receded, or any imprint, counts as a change."""
    _, _, region, _ = _changed(img, ref)
    return _too_small(region)


def contact_changed(img: NDArray[np.uint8], ref: NDArray[np.uint8]) -> bool:
    """True when either frame shows a contact the other lacks: ``is_new_contact(img, ref) or
    is_new_contact(ref, img)`` (validated uint8 frames of one shape), reading each frame once."""
    k = max(1, round(img.shape[1] / WORK_WIDTH))
    bi, br = _blurred(img, k), _blurred(ref, k)
    for a, b in ((bi, br), (br, bi)):
        a_matched, region = _compare(a, b)
        if _energy_ratio(a_matched, b, region) < NEW_CONTACT_RATIO:
            return True
    return False
