"""Marker extraction: find the painted dots of a tactile sensor image (Rust core)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch import _native
from tacswitch._checks import as_count, as_image_u8, check_extract_options

Polarity = Literal["dark", "bright"]
#: ``dilate`` value that grows each marker's mask adaptively (see :func:`extract_markers`).
AUTO = "auto"


@dataclass(frozen=True)
class Markers:
    """Markers found in one image.

    Attributes:
        centres: ``N x 2`` float32 sub-pixel centres ``(x, y)`` in pixels, in raster order.
        areas: ``N`` uint32 areas in pixels (pixels above the threshold).
        bboxes: ``N x 4`` int32 boxes ``(x, y, width, height)``, as
            ``cv2.connectedComponentsWithStats`` reports them.
        contrast: ``N`` float32 peak darkness ``1 - darkest / local background`` in ``[0, 1]``.
        mask: ``H x W`` bool, True on marker pixels: every marker found, including markers cut
            by the frame border that ``exclude_border`` leaves out of ``centres``, after the
            requested growth (``dilate``).
        threshold: darkness threshold used, grey levels above the local background.
        background_level: median darkness of the image (grey levels; ~0 means a flat background).
        noise_sigma: robust noise estimate of the darkness image, grey levels.
        block_size: side of the background box filter used, pixels.
        n_components: connected components before the area/shape filters.
        grow_rings: with ``dilate="auto"``, the rings (pixels) added around each masked
            marker, uint16, in raster order of the markers' first pixel (border-cut markers
            included); empty otherwise.
    """

    centres: NDArray[np.float32]
    areas: NDArray[np.uint32]
    bboxes: NDArray[np.int32]
    contrast: NDArray[np.float32]
    mask: NDArray[np.bool_]
    threshold: float
    background_level: float
    noise_sigma: float
    block_size: int
    n_components: int
    grow_rings: NDArray[np.uint16]

    def __len__(self) -> int:
        return int(self.centres.shape[0])


def extract_markers(
    img: NDArray[np.uint8],
    *,
    polarity: Polarity = "dark",
    block_size: int | None = None,
    threshold: float | None = None,
    min_area: int | None = None,
    max_area: int | None = None,
    min_fill: float = 0.35,
    max_aspect: float = 3.0,
    dilate: int | Literal["auto"] = 0,
    exclude_border: bool = True,
) -> Markers:
    """Finds markers in a tactile image.

    A marker is a blob darker (``polarity="dark"``) or brighter (``"bright"``) than the local
    background, estimated by a ``block_size`` box mean with ``cv2.BORDER_REFLECT_101`` borders and
    computed in wide integers (no uint8 wraparound). The threshold is chosen per image (Otsu on the
    darkness histogram, never below 6 noise sigmas or 10 grey levels above the background level),
    so one setting works across sensors and lighting; pass ``threshold`` to fix it. When that noise
    floor decides, the background is computed again without the pixels Otsu puts in the dark class
    and the gel's level and noise are taken from the others, so that large or many markers and an
    object's texture or imprint do not push the threshold above the markers. Components are
    8-connected (same components as ``cv2.connectedComponents(connectivity=8)``), then filtered by
    area, fill ratio and aspect ratio, and must be darker than the ring just around them. Centres
    are darkness-weighted over the blob and a one-pixel margin, so soft edges count.

    Args:
        img: ``H x W x 3`` uint8 **BGR** (or BGRA, or grey ``H x W``). Luma uses BT.601 weights.
        polarity: ``"dark"`` for painted dots (GelSight, Mini, GelSlim), ``"bright"`` for pins.
        block_size: odd box size in pixels for the background; default ``max(15, min(H, W) // 8)``.
        threshold: darkness threshold in grey levels; default chosen from the image.
        min_area: smallest blob in pixels; default ``max(4, 5e-5 * H * W)``, but at most a
            quarter of the typical marker-shaped blob (area-weighted median), so frames of
            several megapixels with small markers still find them.
        max_area: largest blob in pixels; default ``0.02 * H * W``.
        min_fill: smallest ``area / bbox area`` (a disc has 0.785).
        max_aspect: largest bounding-box aspect ratio.
        dilate: growth of ``mask`` beyond the thresholded pixels. An integer: that many
            dilations by a 3x3 cross (the paper dilates once before inpainting; stops early
            once the mask no longer changes, so any size is cheap). ``"auto"``: per marker,
            ring by ring (a ring is one pixel) while the ring's mean luma differs from the
            local background just outside it (a plane through the next two rings) by more
            than a quarter of the local noise sigma, capped at 1.5 marker radii and half the
            gap to the nearest marker: soft paint edges, optical blur and the dark/bright
            rings of H.264/MJPEG compression end up inside, while crisp lossless markers get
            one pixel (``grow_rings`` reports the rings). This is the mask
            :func:`tacswitch.remove_markers` uses by default; it costs about 1-2 ms per 100
            markers (docs/notes/2026-11-marker-removal.md, "Marker masks on real-frame
            proxies (adaptive growth)"), nothing when not requested.
        exclude_border: leave out of ``centres`` the markers whose centre lies outside the
            frame: blobs on the image border with less than 0.3 of the median interior marker
            area visible (or, with fewer than 3 interior markers, cut to less than half their
            extent), and slivers that only pass as the visible part of a marker-sized disc.
            ``mask`` includes them either way (removal must cover them). Set False to report
            them too; the centre of a marker cut by the border is then placed one typical
            marker radius in from its far edge along the cut axis (it may lie outside the
            frame), since the visible part's centroid would lean inward.

    Returns:
        :class:`Markers`. An image without markers (flat, black, white, markerless) gives zero.

    Raises:
        TypeError: ``img`` is not a uint8 numpy array.
        ValueError: bad shape or option; the message names the argument.
    """
    arr = as_image_u8(img)
    # Conversion errors (polarity=None, threshold="abc", min_fill=None, ...) name the option.
    check_extract_options({"polarity": polarity, "block_size": block_size, "threshold": threshold,
                           "min_area": min_area, "max_area": max_area, "min_fill": min_fill,
                           "max_aspect": max_aspect, "exclude_border": exclude_border})

    for value, name, minimum in ((block_size, "block_size", 3), (min_area, "min_area", 0),
                                 (max_area, "max_area", 0)):
        if value is not None:
            as_count(value, name, minimum)
    adaptive = isinstance(dilate, str)
    if adaptive and dilate != AUTO:
        raise ValueError(f"dilate: must be an integer >= 0 or 'auto'; got {dilate!r}")
    # More dilations than H + W change nothing (the mask is full or stopped changing); capping
    # here keeps any Python integer within the native size type.
    steps = 0 if adaptive else min(as_count(dilate, "dilate", 0, None), sum(arr.shape[:2]))
    out = _native.extract_markers(
        arr,
        polarity=polarity,
        block_size=block_size,
        threshold=None if threshold is None else float(threshold),
        min_area=min_area,
        max_area=max_area,
        min_fill=float(min_fill),
        max_aspect=float(max_aspect),
        dilate=steps,
        adaptive=adaptive,
        exclude_border=bool(exclude_border),
    )
    return Markers(**out)


def dilate_mask(mask: NDArray, iterations: int = 1) -> NDArray[np.bool_]:
    """Dilates an ``H x W`` mask by a 3x3 cross ``iterations`` times (Rust core).

    Same result as ``cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)),
    iterations=iterations)`` (the 3x3 ellipse is a cross); pixels outside the image count as
    unset. The paper dilates marker masks once before inpainting. Stops once the mask no longer
    changes (at most ``H + W`` passes), so a huge ``iterations`` returns at once.
    """
    if not isinstance(mask, np.ndarray):
        raise TypeError(f"mask: expected a numpy array, got {type(mask).__name__}")
    if mask.ndim != 2:
        raise ValueError(f"mask: expected an H x W array; got shape {mask.shape}")
    steps = min(as_count(iterations, "iterations", 0, None), sum(mask.shape))
    return _native.dilate_mask(np.ascontiguousarray(mask != 0), steps)
