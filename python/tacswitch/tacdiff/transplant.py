"""Real marker appearance moved onto real gel: the inputs of ``tacswitch finetune`` (numpy).

A sensor with markers has no ground truth under its markers, so the fine-tune (the paper's
marker-offset strategy) asks the network to fill holes placed *between* the markers, where the
true gel is known. For that to teach anything, the holes must look like real markers do: on real
recordings a marker darkens more than the mask it is found with (soft paint edges, optical blur,
the dark ring compression leaves around a dark dot), and that ring, left outside the mask,
drags every classical fill and the network's prior dark. Holes cut into clean gel have no ring,
so a fine-tune on them learns the wrong lesson (issue 14).

Here each real marker's appearance is measured and moved to the shifted position:

1. ``footprint``: the removal mask grown by ``ring`` px, i.e. every pixel the marker may darken;
   ``fill``: the frame with the footprints filled by our TELEA (the pseudo-markerless frame).
2. ``ratio = frame / fill`` per pixel and channel over the footprint (1 elsewhere): the marker's
   darkening relative to the gel under it, ring and codec artefacts included. A ratio (not a
   difference) because paint and shadow scale the light the gel sends back.
3. Each whole marker's ratio is shifted by ``(dx, dy)`` and multiplied onto the frame; markers
   whose shifted footprint leaves the frame, whose original is cut by the frame border, or whose
   moved mask lands mostly on original footprints are dropped. The loss covers the moved mask's
   pixels off every original footprint: real gel whose true value is the frame itself; TELEA's
   pseudo-fill (and the darkened rings of the originals) never are a target.

Offsets that are multiples of 8 px keep each moved marker on the same phase of the 8 x 8 JPEG
and H.264 transform blocks as the original, so its codec ringing stays plausible. The gel
*around* a moved marker was still compressed without it; ``tacswitch finetune`` therefore
re-compresses the result like the source (:mod:`~tacswitch.tacdiff.recompress`).
Images are ``H x W x 3`` uint8 BGR; offsets ``(dx, dy)``
in px, positive right and down.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.inpaint import inpaint_telea
from tacswitch.markers import dilate_mask

#: Px the removal mask is grown by to hold a marker's whole darkening (soft edge, codec ring).
DEFAULT_RING = 3
#: Codec block side (px) offsets are rounded to by :func:`default_offset`.
BLOCK = 8
#: A pseudo-markerless fill: ``(frame, holes) -> frame`` with the holes filled (uint8 BGR).
PseudoFill = Callable[[NDArray[np.uint8], NDArray[np.bool_]], NDArray[np.uint8]]


@dataclass(frozen=True)
class Appearance:
    """The markers of one frame, as :func:`measure_appearance` returns them.

    Attributes:
        ratio: ``H x W x 3`` float32, frame / pseudo-markerless fill on the footprints, 1
            elsewhere.
        footprint: ``H x W`` bool, the removal mask grown by the ring.
        labels: ``H x W`` int32, one label per 8-connected footprint (0: gel).
        fill: ``H x W x 3`` uint8 BGR, the frame with its footprints filled by TELEA.
    """

    ratio: NDArray[np.float32]
    footprint: NDArray[np.bool_]
    labels: NDArray[np.int32]
    fill: NDArray[np.uint8]


def shift(a: NDArray[Any], offset: tuple[int, int], fill: Any = 0) -> NDArray[Any]:
    """``a`` (``H x W [x C]``) moved by ``(dx, dy)`` px; vacated pixels get ``fill``, pixels
    moved out of the frame are dropped."""
    dx, dy = int(offset[0]), int(offset[1])
    h, w = a.shape[:2]
    out = np.full_like(a, fill)
    if abs(dx) >= w or abs(dy) >= h:
        return out
    ys, yd = (slice(0, h - dy), slice(dy, h)) if dy >= 0 else (slice(-dy, h), slice(0, h + dy))
    xs, xd = (slice(0, w - dx), slice(dx, w)) if dx >= 0 else (slice(-dx, w), slice(0, w + dx))
    out[yd, xd] = a[ys, xs]
    return out


def default_offset(pitch: float, block: int = BLOCK) -> tuple[int, int]:
    """``(d, d)``: half the marker ``pitch`` (px) rounded to a multiple of ``block`` (at least
    one block), so moved markers land between the originals on the same codec-block phase."""
    if not np.isfinite(pitch) or pitch <= 0:
        raise ValueError(f"pitch: expected a positive number of px; got {pitch}")
    d = max(block, round(pitch / 2 / block) * block)
    return d, d


def measure_appearance(frame: NDArray[np.uint8], mask: NDArray[np.bool_], *,
                       ring: int = DEFAULT_RING, radius: int = 3,
                       pseudo_fill: PseudoFill | None = None) -> Appearance:
    """Each marker's darkening relative to the gel under it (see the module docstring).

    Args:
        frame: ``H x W x 3`` uint8 BGR frame with markers.
        mask: ``H x W`` bool removal mask of its markers (what inference would fill).
        ring: px the mask is grown by (the footprint whose darkening is measured).
        radius: TELEA radius of the pseudo-markerless fill.
        pseudo_fill: another pseudo-markerless fill instead of TELEA (e.g. the model being
            fine-tuned: a fill closer to the gel makes the context around the moved markers,
            and their measured darkening, closer to a real frame's).
    """
    import cv2

    if ring < 0:
        raise ValueError(f"ring: must be >= 0 px; got {ring}")
    footprint = dilate_mask(mask, ring) if ring else mask.astype(bool)
    fill = (inpaint_telea(frame, footprint, radius) if pseudo_fill is None
            else np.asarray(pseudo_fill(frame, footprint), np.uint8))
    ratio = np.ones(frame.shape, np.float32)
    f = frame[footprint].astype(np.float32)
    # The +0.5 keeps black gel (a 0 fill) from dividing by zero; it is far below the noise.
    ratio[footprint] = (f + 0.5) / (fill[footprint].astype(np.float32) + 0.5)
    _, labels = cv2.connectedComponents(footprint.view(np.uint8), connectivity=8)
    return Appearance(ratio, footprint, labels.astype(np.int32), fill)


def movable(app: Appearance, mask: NDArray[np.bool_], offset: tuple[int, int], *,
            min_real: float = 0.5) -> NDArray[np.bool_]:
    """Per footprint label (index 0 unused), whether the marker can be moved by ``offset``: its
    original is not cut by the frame border, its moved footprint stays inside the frame, and
    at least ``min_real`` of its moved mask lands off every original footprint (on gel whose
    true value is known; the rest is left out of the loss)."""
    lab = app.labels
    n = int(lab.max()) + 1
    ok = np.ones(n, bool)
    edge = np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]])
    ok[np.unique(edge)] = False
    before = np.bincount(lab.ravel(), minlength=n)
    after = np.bincount(shift(lab, offset, 0).ravel(), minlength=n)
    ok &= after == before  # no pixel shifted out of the frame
    mask_lab = np.where(mask, lab, 0)
    moved = shift(mask_lab, offset, 0)
    total = np.bincount(mask_lab.ravel(), minlength=n)
    real = np.bincount(moved[~app.footprint].ravel(), minlength=n)
    ok &= real >= min_real * np.maximum(total, 1)
    ok[0] = False
    return ok


def transplant(frame: NDArray[np.uint8], mask: NDArray[np.bool_], offset: tuple[int, int], *,
               ring: int = DEFAULT_RING, radius: int = 3, pseudo_fill: PseudoFill | None = None,
               appearance: Appearance | None = None
               ) -> tuple[NDArray[np.uint8], NDArray[np.bool_], NDArray[np.bool_], int]:
    """The frame's real markers moved by ``offset`` onto real gel.

    ``appearance``: the frame's :func:`measure_appearance` (with ``mask``), when several
    offsets of one frame are made (the pseudo-markerless fill is its costly part); ``ring``,
    ``radius`` and ``pseudo_fill`` are then not used.

    Returns:
        ``(cond, moved_mask, loss_mask, n)``: the pseudo-markerless frame (original footprints
        filled by TELEA) carrying the moved markers' appearance, the removal mask of the moved
        markers, its pixels on real gel (off every original footprint; the loss goes there
        only), and how many markers were moved.
    """
    app = appearance if appearance is not None else measure_appearance(
        frame, mask, ring=ring, radius=radius, pseudo_fill=pseudo_fill)
    if app.ratio.shape != frame.shape:
        raise ValueError(f"appearance: measured on a {app.ratio.shape} frame, not this "
                         f"{frame.shape} one")
    ok = movable(app, mask, offset)
    keep = ok[shift(app.labels, offset, 0)]
    ratio = np.where(keep[:, :, None], shift(app.ratio, offset, 1.0), np.float32(1.0))
    # Where a moved ring overlaps an original footprint it darkens TELEA's fill there: the
    # input still looks like a marker's surroundings, and those pixels carry no loss.
    cond = np.clip(np.rint(app.fill.astype(np.float32) * ratio), 0, 255).astype(np.uint8)
    moved_mask = shift(mask.astype(bool), offset, False) & keep
    return cond, moved_mask, moved_mask & ~app.footprint, int(ok.sum())
