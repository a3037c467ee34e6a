"""Hybrid marker removal: the diffusion model only where the scene needs it, TELEA elsewhere.

TELEA is near-exact on the smooth, uncontacted gel and weakest on contact texture and edges,
which is where TacDiff earns its cost. :func:`model_mask` picks the holes that lie in or near the
contact (whole holes, never part of one); :func:`inpaint_hybrid` fills every hole with TELEA,
then re-fills those holes with TacDiff on the TELEA frame (so the network never sees a leftover
marker outside its mask), tiling so that only tiles holding such holes run the network.

Finding the contact (on marker-free frames, holes filled by TELEA):

- with ``ref`` (a no-contact frame of the same sensor, markers allowed): where the local means
  (box of :data:`BOX` px) of frame and reference differ by more than ``threshold`` grey levels in
  any channel, after removing the global per-channel offset (exposure drift between frames);
- without: where the local contrast (mean absolute difference from a box mean of about an eighth
  of the frame, averaged over :data:`TEXTURE_BOX` px) exceeds ``threshold`` times the frame's
  median contrast and an absolute floor. An unloaded gel is smooth at that scale: its contrast
  is camera noise (about 2-3 grey levels); contact shading and texture raise it several-fold.

The region is grown by ``margin`` px before selecting holes. Thresholds are in grey levels or
ratios of the frame's own statistics, not tuned to one sensor: the same defaults work on the
simulated GelSight, GelSight Mini and DIGIT frames (``benches``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_count, as_image_u8
from tacswitch.inpaint import DEFAULT_RADIUS, _as_mask, inpaint_telea
from tacswitch.markers import dilate_mask
from tacswitch.tacdiff.data import removal_markers
from tacswitch.tacdiff.infer import DEFAULT_STEPS, SEPARATION, check_orientations, inpaint_tacdiff

#: Box side (px) of the local means compared against the reference.
BOX = 7
#: Contact threshold against a reference, grey levels (outside the contact the box-mean difference
#: stays near 2 levels: camera noise and TELEA residuals; inside it is typically 8-25).
REF_THRESHOLD = 6.0
#: Without a reference: contact where the local contrast exceeds this multiple of the frame's
#: median contrast, and at least :data:`TEXTURE_FLOOR` grey levels.
TEXTURE_RATIO, TEXTURE_FLOOR = 1.8, 4.5
#: Box side (px) over which the local contrast is averaged.
TEXTURE_BOX = 9


@dataclass(frozen=True)
class HybridInfo:
    """What the hybrid run spent: pixels and tiles through the network vs the whole job."""

    mask_pixels: int
    model_pixels: int
    holes_fraction: float  # share of the mask's pixels filled by the network

    @property
    def saved(self) -> float:
        """Share of the mask's pixels that the network did not have to fill (0..1)."""
        return 1.0 - self.holes_fraction


def _box(a: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    import cv2

    return np.asarray(cv2.blur(a, (k, k), borderType=cv2.BORDER_REFLECT_101), np.float32)


def _dilate8(a: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Dilation by a 3x3 square (8-neighbourhood), separably; outside the image is unset."""
    r = a.copy()
    r[:, 1:] |= a[:, :-1]
    r[:, :-1] |= a[:, 1:]
    out = r.copy()
    out[1:] |= r[:-1]
    out[:-1] |= r[1:]
    return out


def reconstruct(seed: NDArray[np.bool_], mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The 8-connected parts of ``mask`` that ``seed`` touches (morphological reconstruction by
    dilation), so a hole is taken whole or not at all."""
    cur = seed & mask
    for _ in range(mask.size):
        nxt = _dilate8(cur) & mask
        if np.array_equal(nxt, cur):
            break
        cur = nxt
    return cur


def contact_region(img: NDArray[np.uint8], mask: NDArray[np.bool_],
                   ref: NDArray[np.uint8] | None = None, *, radius: int = DEFAULT_RADIUS,
                   threshold: float | None = None) -> NDArray[np.bool_]:
    """Pixels in contact (``ref`` given) or textured (no ``ref``), see the module docstring.
    ``img`` is the frame with its ``mask`` holes already filled (e.g. by TELEA)."""
    f = img.astype(np.float32)
    if ref is not None:
        # The reference's markers as remove_markers masks them (adaptive growth), so their
        # rings do not read as contact.
        ref_mask = removal_markers(ref).mask
        ref_clean = inpaint_telea(ref, ref_mask, radius).astype(np.float32)
        diff = _box(f, BOX) - _box(ref_clean, BOX)
        diff -= np.median(diff.reshape(-1, 3), axis=0)
        level = REF_THRESHOLD if threshold is None else threshold
        # Filled holes of either frame differ by TELEA's residual, not by contact: judge the
        # gel around them (the margin then reaches into the holes).
        return (np.abs(diff).max(axis=2) > level) & ~dilate_mask(mask | ref_mask, BOX // 2)
    k = max(15, min(f.shape[:2]) // 8) | 1
    contrast = _box(np.abs(f - _box(f, k)).max(axis=2), TEXTURE_BOX)
    ratio = TEXTURE_RATIO if threshold is None else threshold
    level = max(TEXTURE_FLOOR, ratio * float(np.median(contrast)))
    return np.asarray(contrast > level)


def model_mask(img: NDArray[np.uint8], mask: NDArray[np.bool_],
               ref: NDArray[np.uint8] | None = None, *, filled: NDArray[np.uint8] | None = None,
               margin: int = 6, radius: int = DEFAULT_RADIUS, threshold: float | None = None
               ) -> NDArray[np.bool_]:
    """The holes of ``mask`` (whole 8-connected parts) lying within ``margin`` px of the contact
    region; ``filled`` is ``img`` with the holes filled (computed by TELEA if None)."""
    base = inpaint_telea(img, mask, radius) if filled is None else filled
    region = contact_region(base, mask, ref, radius=radius, threshold=threshold)
    grown = dilate_mask(region, margin) if margin > 0 else region
    return reconstruct(grown & mask, mask)


def inpaint_hybrid(img: Any, mask: Any, ref: Any = None, *, steps: int | None = None,
                   radius: float = DEFAULT_RADIUS, margin: int = 6, threshold: float | None = None,
                   seed: int | None = 0, separation: int = SEPARATION,
                   model: str | os.PathLike[str] | None = None, orientations: int | None = None,
                   device: str = "auto") -> tuple[NDArray[np.uint8], HybridInfo]:
    """TELEA everywhere, TacDiff on the holes in or near the contact.

    Args:
        img: ``H x W x 3`` uint8 BGR frame.
        mask: ``H x W`` bool/uint8 holes (markers dilated once).
        ref: optional no-contact frame of the same sensor (``H x W x 3`` uint8 BGR, with or
            without markers): the contact is found against it; without it, from local texture.
        steps: TacDiff sampler steps (default :data:`~tacswitch.tacdiff.infer.DEFAULT_STEPS`).
        radius: TELEA radius, px (default: ``remove_markers``' default).
        margin: px the contact region is grown by before picking holes.
        threshold: contact threshold (grey levels with ``ref``; texture ratio without).
        seed: noise seed of the diffusion sampler.
        separation: px; the network fills its holes within this distance of one another in
            separate passes (:func:`~tacswitch.tacdiff.infer.inpaint_tacdiff`; 0: one pass).
        model: TacDiff ONNX path (default: the shipped model).
        orientations: orientations the network's frame is averaged over (1, 2, 4 or 8; None:
            4, or 1 for a narrow model such as the fast one), see
            :func:`~tacswitch.tacdiff.infer.inpaint_tacdiff`.
        device: where the network runs: ``"auto"`` (default: a CUDA GPU when onnxruntime
            offers one, else the CPU), ``"cpu"`` or ``"cuda"`` (:func:`tacswitch._ort.providers`).

    Returns:
        ``(image, info)``: the markerless frame (unmasked pixels bit-identical to ``img``) and a
        :class:`HybridInfo` with the share of hole pixels the network filled.
    """
    # Checked here too: the network (which checks them) may not run when no hole is near contact.
    as_count(separation, "separation", 0, None)
    check_orientations(orientations)
    from tacswitch._ort import providers

    providers(device)
    arr = as_image_u8(img, "img")
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"img: expected a BGR H x W x 3 uint8 image; got shape {arr.shape}")
    m = _as_mask(mask, arr.shape).astype(bool)
    ref_arr = None
    if ref is not None:
        ref_arr = as_image_u8(ref, "ref")
        if ref_arr.shape != arr.shape:
            raise ValueError(f"ref: shape {ref_arr.shape} does not match img {arr.shape}")
    filled = inpaint_telea(arr, m, radius)
    net = model_mask(arr, m, ref_arr, filled=filled, margin=margin, radius=int(radius),
                     threshold=threshold)
    k = DEFAULT_STEPS if steps is None else steps
    out = (inpaint_tacdiff(filled, net, k, seed=seed, separation=separation, model=model,
                           orientations=orientations, device=device) if net.any() else filled)
    total = int(m.sum())
    used = int(net.sum())
    return out, HybridInfo(total, used, used / total if total else 0.0)
