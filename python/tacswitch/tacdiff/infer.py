"""TacDiff inference with onnxruntime (numpy only; never imports torch).

:func:`inpaint_tacdiff` fills the masked pixels of a BGR frame with the diffusion model:

1. The holes are filled classically first (the prior, :mod:`~tacswitch.tacdiff.prior`: the
   mean of our TELEA and biharmonic fills, or TELEA for older models, TELEA at the radius the
   model records, :func:`prior_radius`; what is diffused is the residual over it, see
   :mod:`~tacswitch.tacdiff.model`). Noise is drawn once for the whole
   frame (seeded), so overlapping patches start from the same noise.
2. Regions: the whole frame (padded by reflection to a multiple of 16), ``patch x patch``
   tiles from the Rust :func:`tacswitch.tile` (tiles without a pixel to fill are not run: their
   output is the input), windows around groups of holes, or one small crop per hole, all crops of
   one size in one network call (:func:`hole_crops`). ``patch="auto"`` picks whichever runs
   fewest pixels through the network, so sparse masks (few markers, or the contact-only mask of
   ``method="hybrid"``) cost little, and on a dense 640 x 480 grid the per-hole crops run about
   a third of the frame's pixels.
3. K sampler steps from pure noise (:mod:`~tacswitch.tacdiff.schedule`: DPM-Solver++(2M) or DDIM,
   v-prediction, zero terminal SNR); known pixels are pasted into the network input at every
   step (inside the ONNX graph).
4. Tiles are merged by the Rust :func:`tacswitch.merge_patches` (feathered); only masked pixels
   of the output differ from the input.
5. Holes within ``separation`` px of one another (:mod:`~tacswitch.tacdiff.passes`) run in
   separate passes, each seeing the other holes as gel holding the prior; a usual marker grid is
   one pass. On the real FOTS GelSight Mini frames' dense held-out check (twice the markers, 4
   passes) this cut the default model's held-out MAE from 2.27 to 1.91 (TELEA 1.97); on the
   sparse one (a quarter of the held-out holes at a time) it costs 1.88 -> 1.92 (TELEA 1.89).
6. The default model runs the frame in :data:`DEFAULT_ORIENTATIONS` orientations (as it is,
   mirrored left-right, upside down, and both) and averages the image estimates before they are
   rounded: the network was trained with flips and turns, and its errors in different
   orientations are partly independent. On the real-frame proxy this lowers the masked MAE by
   about 2.6 % on GelSight and 1.2 % on the GelSight Mini, and a little on the real FOTS
   frames, at about 3x the time (BENCHMARKS.md, "TacDiff: averaging orientations"). A narrow
   model (the fast one) runs one orientation by default: speed is what it is for.
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_count, as_image_u8, check_model_arg
from tacswitch._ort import cached, open_session
from tacswitch._ort import providers as _ort_providers
from tacswitch.inpaint import _as_mask, merge_patches, tile
from tacswitch.tacdiff.passes import hole_passes, pass_masks
from tacswitch.tacdiff.prior import (
    PRIOR_RADIUS,
    check_prior,
    from_net,
    has_spread,
    input_channels,
    prior_on_mask,
)
from tacswitch.tacdiff.schedule import Sampler, Solver, alpha_sigma, timesteps, v_to_x0_eps

#: File name of the shipped default model under ``tacswitch/models``.
DEFAULT_MODEL = "tacdiff_unet.onnx"
#: Shipped models by name (``model="fast"``): the default, and a narrower one for speed.
SHIPPED = {"default": DEFAULT_MODEL, "fast": "tacdiff_unet_fast.onnx"}
#: Default sampler steps (docs/notes/2026-11-marker-removal.md, "TacDiff 0.5: trained for the
#: one-step sampler" and "TacDiff speed per setting", say why).
DEFAULT_STEPS = 1
#: Default tile side and overlap, px, when tiling (multiples of the model's size multiple).
DEFAULT_PATCH, DEFAULT_OVERLAP = 128, 32
#: Most regions sent to onnxruntime in one call (bounds memory on huge frames).
MAX_BATCH = 16
#: Most pixels of one batch of same-size regions sent in one call (bounds the activations'
#: memory: 227 crops of 48 x 48 through the default model peak at 262 MB of process memory,
#: against 169 MB after a whole 640 x 480 frame).
MAX_BATCH_PX = 1 << 19
#: Context (px) kept around each hole in ``patch="holes"`` windows.
DEFAULT_CONTEXT = 16
#: Least context (px) kept around each hole in ``patch="crops"`` crops (the network was trained
#: on 96 px crops). On the real-frame proxy (taxim's 640 x 480 GelSight presses with painted
#: markers, 3 presses x 7 capture cases, adaptive masks) 48 x 48 crops with this context change
#: the masked MAE of whole-frame runs by +0.9 % (fast model) and +1.0 % (default), on 4 held-out
#: simulated GelSight frames by +1.0 % / -1.2 %, at 36 % of the pixels
#: (docs/notes/2026-11-marker-removal.md, "TacDiff speed per setting"). 16 px (64 x 64 crops) is
#: within 0.5 % but barely cheaper than the whole frame.
CROP_CONTEXT = 8
#: Default hole separation (px) of :func:`inpaint_tacdiff`: holes within this Chebyshev distance
#: of one another are filled in separate passes (:mod:`~tacswitch.tacdiff.passes`). The network
#: never saw holes that close: on its GelSight Mini training masks (``data.render_pair``, 320 x
#: 240, the masks ``remove_markers`` builds) 0.8 % of the holes have a neighbour within 4 px,
#: 3 % within 6 and 23 % within 8; GelSight's (640 x 480) none within 24. At 4, the real FOTS
#: GelSight Mini frames (holes 5-9 px apart) and every proxy and simulated frame are one pass,
#: while the FOTS held-out checks, whose held-out holes lie 3-4 px from the real markers, are
#: split: there 8 gave the same held-out MAE but ran the real frames alone in 3 passes and moved
#: their ghost from -0.07 to -0.18 grey levels
#: (docs/notes/2026-11-marker-removal.md, "TacDiff: crowded holes in separate passes").
SEPARATION = 4

#: Orientation counts :func:`inpaint_tacdiff` accepts: 1 (as is), 2 (+ mirrored left-right),
#: 4 (+ upside down, + both: the 180-degree turn) and 8 (+ the four transposed ones).
ORIENTATIONS = (1, 2, 4, 8)
#: Orientations averaged by default with the default model (or any model wider than
#: :data:`NARROW_BASE`). Eight were no better than four on the real-frame proxy (GelSight 1.361
#: vs 1.362; BENCHMARKS.md, "TacDiff: averaging orientations") at twice the time.
DEFAULT_ORIENTATIONS = 4
#: U-Net base width at or below which a model runs one orientation by default: the shipped fast
#: model's (16; the default model's is 24), kept by a fine-tune of it.
NARROW_BASE = 16
#: The eight orientations in the order they are added: ``(flip rows, flip columns, transpose)``.
_DIHEDRAL = ((False, False, False), (False, True, False), (True, False, False),
             (True, True, False), (False, False, True), (False, True, True),
             (True, False, True), (True, True, True))

PatchArg = int | Literal["auto", "holes", "crops"] | None
Orientation = tuple[bool, bool, bool]


def default_model_path() -> Path:
    """Path of the shipped default model."""
    return Path(__file__).resolve().parent.parent / "models" / DEFAULT_MODEL


def model_path(model: str | os.PathLike[str] | None) -> Path:
    """The ONNX file of ``model``: None or ``"default"`` (the shipped default), ``"fast"`` (the
    shipped narrow model, about 1.4x as fast per network pass and run in one orientation by
    default: ~4.6x as fast as the default setting), or a path."""
    if model is None:
        return default_model_path()
    if isinstance(model, str) and model in SHIPPED:
        return default_model_path().with_name(SHIPPED[model])
    return Path(model)


def default_weights_path() -> Path:
    """Path of the shipped model's torch weights (float16 safetensors; the starting point of
    ``tacswitch finetune``)."""
    return default_model_path().with_suffix(".safetensors")


class TacDiffModel:
    """One loaded denoiser (an onnxruntime session and its metadata).

    Args:
        path: ONNX file written by :func:`tacswitch.tacdiff.export.export_onnx`, or a shipped
            model by name (``"default"``, ``"fast"``); default: the shipped default model.
        threads: intra-op threads (default ``os.cpu_count()``).
        device: ``"auto"`` (default: a CUDA GPU when onnxruntime offers one, else the CPU),
            ``"cpu"`` or ``"cuda"`` (``ValueError`` naming ``device`` when onnxruntime has no
            CUDA here); see :func:`tacswitch._ort.providers`.
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *,
                 threads: int | None = None, device: str = "auto") -> None:
        self.path = model_path(path)
        self.session, meta = open_session(self.path, threads, kind="tacdiff", device=device)
        self.device = device
        if meta.get("tacswitch.kind") != "tacdiff":
            raise ValueError(f"model: {str(self.path)!r} is not a TacDiff model")
        if meta.get("tacswitch.colour_order", "BGR") != "BGR":
            raise ValueError(f"model: {str(self.path)!r} expects "
                             f"{meta['tacswitch.colour_order']} input; tacswitch feeds BGR")
        self.metadata = meta
        self.multiple = int(meta.get("tacswitch.multiple", "16"))
        self.unet = json.loads(meta.get("tacswitch.unet", "{}"))
        self.residual_scale = float(meta.get("tacswitch.residual_scale", "1"))
        # Models exported before the prior was recorded diffuse the residual over TELEA.
        self.prior = check_prior(meta.get("tacswitch.prior", "telea"))
        self.prior_radius = prior_radius(meta, self.path)
        inputs = [i.name for i in self.session.get_inputs()]
        if ("spread" in inputs) != has_spread(self.prior):
            raise ValueError(f"model: {str(self.path)!r} has inputs {inputs}, which do not "
                             f"match its prior {self.prior!r}")

    @property
    def channels(self) -> int:
        """Channels of the region stack :func:`_sample` takes: cond 3, mask 1, noise 3, prior 3
        and, for two-fill priors, spread 3."""
        return input_channels(self.prior)

    def v(self, cond: NDArray[np.float32], mask: NDArray[np.float32], x_t: NDArray[np.float32],
          noise: NDArray[np.float32], prior: NDArray[np.float32], sigma: float,
          spread: NDArray[np.float32] | None = None) -> NDArray[np.float32]:
        """The network's v-prediction for a batch (arrays as in the export's docstring), in
        calls of at most :data:`MAX_BATCH` regions or :data:`MAX_BATCH_PX` pixels."""
        if (spread is not None) != has_spread(self.prior):
            raise ValueError(f"spread: this model's prior is {self.prior!r}; pass spread "
                             "exactly for 'telea+biharmonic'")
        per = max(MAX_BATCH, MAX_BATCH_PX // max(1, cond.shape[2] * cond.shape[3]))
        outs = []
        for i in range(0, len(cond), per):
            sl = slice(i, i + per)
            n = len(cond[sl])
            feed = {"cond": cond[sl], "mask": mask[sl], "x_t": x_t[sl], "noise": noise[sl],
                    "prior": prior[sl], "sigma": np.full(n, sigma, np.float32)}
            if spread is not None:
                feed["spread"] = spread[sl]
            outs.append(self.session.run(None, feed)[0])
        return np.concatenate(outs)


def prior_radius(meta: dict[str, str], path: Path) -> float:
    """The TELEA radius (px) of a model's prior at inference: its ``tacswitch.prior_radius``
    metadata (:func:`tacswitch.tacdiff.metadata.set_metadata` records one on an existing
    model; :func:`tacswitch.tacdiff.export.export_onnx` records the radius the model was
    trained with), or :data:`~tacswitch.tacdiff.prior.PRIOR_RADIUS` (3, the training radius of
    every model before 0.4) when absent (MODEL_CARD_tacdiff.md, ``benches/bench_prior_radius.py``
    for what the radius changes)."""
    raw = meta.get("tacswitch.prior_radius")
    if raw is None:
        return float(PRIOR_RADIUS)
    try:
        r = float(raw)
    except ValueError:
        r = float("nan")
    if not (0.0 < r <= 64.0):
        raise ValueError(f"model: {str(path)!r} records tacswitch.prior_radius={raw!r}; "
                         "expected a radius in px in (0, 64]")
    return r


def load_model(path: str | os.PathLike[str] | None = None,
               device: str = "auto") -> TacDiffModel:
    """The cached :class:`TacDiffModel` of ``path`` on ``device`` (one session per file,
    device and process)."""
    return cached(TacDiffModel, model_path(path), device)


#: Fixed cost of one network call (window or tile) in pixel-equivalents for ``patch="auto"``:
#: gathering, padding and pasting a window plus the session's per-call overhead. Measured on a
#: 640 x 480 GelSight frame with 47 adaptive-mask markers (fast model, 2 cores): 47 hole windows
#: covering 93 % of the frame took 230 ms against 160 ms for the whole frame, about 1.7 ms
#: (~3 300 px of network time) per call.
CALL_COST_PX = 4096
#: Cost of one crop of ``patch="crops"`` beyond its pixels, in pixel-equivalents: crops of one
#: size share a network call, so a crop costs its gathering and pasting and the network's lower
#: throughput on small images (48 x 48 crops: ~1.3x the time per pixel of a whole frame).
CROP_COST_PX = 1024


def _ceil(n: int, multiple: int) -> int:
    return -(-n // multiple) * multiple


def _choose(mask: NDArray[np.bool_], multiple: int, patch: PatchArg, overlap: int,
            context: int | None) -> tuple[str, Any]:
    """What goes through the network: ``("whole", None)``, ``("holes", (windows, owner))``
    (:func:`hole_windows`), ``("crops", (crops, labels))`` (:func:`hole_crops`) or
    ``("tiles", (origins, run))`` (tiles of the Rust :func:`tacswitch.tile`, ``run`` flagging
    those holding a pixel to fill). ``"auto"`` takes the cheapest: pixels through the network
    plus :data:`CALL_COST_PX` per network call (:data:`CROP_COST_PX` per crop for the batched
    crops); ties go to the whole frame (one call), then the crops, then the windows.
    ``context`` None is each mode's default (:data:`DEFAULT_CONTEXT`, :data:`CROP_CONTEXT`)."""
    h, w = mask.shape
    ph, pw = _ceil(h, multiple), _ceil(w, multiple)
    options: dict[str, tuple[int, Any]] = {}
    if patch in (None, "auto"):
        options["whole"] = (ph * pw + CALL_COST_PX, None)
    if patch in ("crops", "auto"):
        crops, labels = hole_crops(mask, multiple, CROP_CONTEXT if context is None else context)
        sizes = [(y1 - y0) * (x1 - x0) for y0, x0, y1, x1 in crops]
        options["crops"] = (sum(sizes) + CROP_COST_PX * len(crops)
                            + CALL_COST_PX * len(set(sizes)), (crops, labels))
    if patch in ("holes", "auto"):
        windows, owner = hole_windows(mask, multiple,
                                      DEFAULT_CONTEXT if context is None else context)
        options["holes"] = (sum((y1 - y0) * (x1 - x0) for y0, x0, y1, x1 in windows)
                            + CALL_COST_PX * len(windows), (windows, owner))
    if isinstance(patch, int) or (patch == "auto" and min(h, w) >= DEFAULT_PATCH):
        side = DEFAULT_PATCH if patch == "auto" else int(patch)  # type: ignore[arg-type]
        # Tiling the one-channel mask gives the layout at a fraction of the frame's cost.
        flags, origins = tile(mask.view(np.uint8)[:, :, None], side, overlap)
        run = flags.reshape(len(flags), -1).any(axis=1)
        options["tiles"] = (int(run.sum()) * (side * side + CALL_COST_PX), (origins, run, side))
    order = ("whole", "crops", "holes", "tiles")
    kind = min(options, key=lambda k: (options[k][0], order.index(k)))
    return kind, options[kind][1]


def hole_windows(mask: NDArray[np.bool_], multiple: int, context: int
                 ) -> tuple[list[tuple[int, int, int, int]], NDArray[np.int32]]:
    """Windows around the holes for ``patch="holes"``: only these pixels go through the network.

    The frame is cut into ``multiple x multiple`` cells; the cells holding a pixel to fill are
    grouped into 8-connected components (about one per marker), and each component's bounding
    box, grown by ``context`` px (whole cells) and clipped to the frame, is one window. Every
    window is thus a multiple of the network's size step and holds at least ``context`` px of
    gel around its holes (neighbouring holes inside it are seen as holes, as in a whole-frame
    run). Windows may overlap; each fills only its own component's cells.

    Returns:
        ``(windows, owner)``: windows ``(y0, x0, y1, x1)`` in px of the frame padded to a
        multiple of ``multiple``, and the ``ceil(H / m) x ceil(W / m)`` map giving, for each cell
        holding a pixel to fill, the index of the window that fills it (-1 elsewhere).
    """
    import cv2

    h, w = mask.shape
    ch, cw = -(-h // multiple), -(-w // multiple)
    cells = np.zeros((ch * multiple, cw * multiple), bool)
    cells[:h, :w] = mask
    occupied: NDArray[np.uint8] = np.ascontiguousarray(
        cells.reshape(ch, multiple, cw, multiple).any(axis=(1, 3)), np.uint8)
    k = -(-context // multiple)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(occupied, connectivity=8,
                                                           ltype=cv2.CV_32S)
    owner = (labels - 1).astype(np.int32)
    windows = [(max(0, int(y) - k) * multiple, max(0, int(x) - k) * multiple,
                min(ch, int(y + bh) + k) * multiple, min(cw, int(x + bw) + k) * multiple)
               for x, y, bw, bh in stats[1:n, :4]]
    return windows, owner


def hole_crops(mask: NDArray[np.bool_], multiple: int, context: int
               ) -> tuple[list[tuple[int, int, int, int]], NDArray[np.int32]]:
    """One crop per hole for ``patch="crops"``: only these pixels go through the network.

    Each hole (8-connected component of ``mask``) gets the smallest crop whose sides are
    multiples of ``multiple`` and hold its bounding box grown by ``context`` px on every side,
    centred on the hole and shifted inside the padded frame (a crop never exceeds it). Unlike
    :func:`hole_windows` the crops are not aligned to a grid, so a round marker of 30 px at
    ``context=8`` gets a 48 x 48 crop, and crops of one size run as one batch. Neighbouring
    holes inside a crop are seen as holes; each crop fills only its own hole.

    Returns:
        ``(crops, labels)``: crops ``(y0, x0, y1, x1)`` in px of the frame padded to a multiple
        of ``multiple``, and the padded ``H' x W'`` map of hole labels (crop ``i`` fills the
        pixels labelled ``i + 1``; 0 = no hole).
    """
    import cv2

    h, w = mask.shape
    ph, pw = _ceil(h, multiple), _ceil(w, multiple)
    labels = np.zeros((ph, pw), np.int32)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(np.ascontiguousarray(mask, np.uint8),
                                                        connectivity=8, ltype=cv2.CV_32S)
    labels[:h, :w] = lab
    crops = []
    for x, y, bw, bh in stats[1:n, :4].tolist():
        sh, sw = min(ph, _ceil(bh + 2 * context, multiple)), min(pw, _ceil(bw + 2 * context,
                                                                          multiple))
        y0 = min(max(0, y + (bh - sh) // 2), ph - sh)
        x0 = min(max(0, x + (bw - sw) // 2), pw - sw)
        crops.append((y0, x0, y0 + sh, x0 + sw))
    return crops, labels


Box = tuple[int, int, int, int]


def _sample_boxes(model: TacDiffModel, planes: NDArray[np.float32], boxes: list[Box],
                  owned: Callable[[int, Box], NDArray[np.bool_]], steps: int,
                  sampler: Sampler) -> NDArray[np.float32]:
    """Samples every box ``(y0, x0, y1, x1)`` of the padded ``C x H x W`` planes (one batch per
    box size) and returns the ``3 x H x W`` image estimate: box ``i``'s output on the pixels
    ``owned(i, box)`` marks (a ``y1 - y0 x x1 - x0`` bool array), the prior elsewhere."""
    out = planes[7:10].copy()
    by_shape: dict[tuple[int, int], list[int]] = {}
    for i, (y0, x0, y1, x1) in enumerate(boxes):
        by_shape.setdefault((y1 - y0, x1 - x0), []).append(i)
    for idx in by_shape.values():
        batch = np.stack([planes[:, boxes[i][0]:boxes[i][2], boxes[i][1]:boxes[i][3]]
                          for i in idx])
        res = _sample(model, batch, steps, sampler)
        for i, r in zip(idx, res, strict=True):
            y0, x0, y1, x1 = boxes[i]
            own = owned(i, boxes[i])
            out[:, y0:y1, x0:x1][:, own] = r[:, own]
    return out


def _crop_owner(labels: NDArray[np.int32]) -> Callable[[int, Box], NDArray[np.bool_]]:
    """Crop ``i`` fills its own hole (label ``i + 1`` of :func:`hole_crops`)."""
    def owned(i: int, box: Box) -> NDArray[np.bool_]:
        y0, x0, y1, x1 = box
        return labels[y0:y1, x0:x1] == i + 1
    return owned


def _window_owner(owner: NDArray[np.int32], m: int) -> Callable[[int, Box], NDArray[np.bool_]]:
    """Window ``i`` fills the ``m`` px cells it owns (:func:`hole_windows`)."""
    def owned(i: int, box: Box) -> NDArray[np.bool_]:
        y0, x0, y1, x1 = box
        own = owner[y0 // m:y1 // m, x0 // m:x1 // m] == i
        return np.repeat(np.repeat(own, m, axis=0), m, axis=1)
    return owned


def _sample(model: TacDiffModel, x: NDArray[np.float32], steps: int, sampler: Sampler
            ) -> NDArray[np.float32]:
    """Runs the sampler on ``B x C x H x W`` regions (cond 3, mask 1, noise 3, prior 3, and
    spread 3 for two-fill priors) and returns the ``B x 3 x H x W`` image estimates in
    [-1, 1]."""
    cond, mask, noise, prior = x[:, :3], x[:, 3:4], x[:, 4:7], x[:, 7:10]
    spread = x[:, 10:13] if x.shape[1] > 10 else None
    scale = model.residual_scale
    # Residual bounds that keep prior + residual inside the image range [-1, 1].
    lo, hi = scale * (-1.0 - prior), scale * (1.0 - prior)
    x_t = np.ascontiguousarray(noise)
    solver = Solver(sampler)
    ts = timesteps(steps)
    r0 = x_t
    for t, t_next in itertools.pairwise(ts):
        sigma = float(alpha_sigma(t)[1])
        v = model.v(cond, mask, x_t, noise, prior, sigma, spread)
        r0, eps = v_to_x0_eps(x_t, v, float(t))
        # Clipping the estimate to the image range keeps a poor early estimate from blowing up
        # the multistep extrapolation (saturated and black frames).
        np.clip(r0, lo, hi, out=r0)
        x_t = solver.step(x_t, r0, eps, float(t), float(t_next))
    out: NDArray[np.float32] = np.clip(prior + np.clip(r0, lo, hi) / scale, -1.0, 1.0)
    return out


def _planes(arr: NDArray[np.uint8], m: NDArray[np.bool_], model: TacDiffModel,
            rng: np.random.Generator) -> NDArray[np.float32]:
    """The network's inputs for the whole frame, channel-first (``C x H' x W'``, the frame
    reflect-padded to a multiple of the model's size step): condition, mask, the run's noise
    (drawn once per frame, on the pixels to fill only; the network never reads it elsewhere),
    the classical prior and, for two-fill priors, the spread."""
    noise = rng.standard_normal((3, int(np.count_nonzero(m))), dtype=np.float32)
    return _pad(_frame_planes(arr, m, model, noise), model.multiple)


def _frame_planes(arr: NDArray[np.uint8], m: NDArray[np.bool_], model: TacDiffModel,
                  noise: NDArray[np.float32]) -> NDArray[np.float32]:
    """The planes of :func:`_planes` before padding (``C x H x W``); ``noise`` is ``3 x N``, in
    the row-major order of ``m``'s pixels."""
    h, w = m.shape
    planes = np.zeros((model.channels, h, w), np.float32)
    # to_net written straight into the planes (same float32 operations, no temporaries).
    np.divide(arr.transpose(2, 0, 1), np.float32(127.5), out=planes[0:3], dtype=np.float32)
    np.subtract(planes[0:3], np.float32(1.0), out=planes[0:3])
    # Masked pixels by flat index (row-major, as img[m]): several times faster than boolean
    # indexing of the channel planes.
    idx = np.flatnonzero(m)
    flat = planes.reshape(len(planes), h * w)
    flat[3, idx] = 1.0
    flat[4:7, idx] = noise
    # The prior is the frame off the mask and the spread 0 there (prior_on_mask), so only the
    # masked pixels are converted and combined (identical to prior_planes, a third of the work).
    flat[7:10] = flat[0:3]
    prior, spread = prior_on_mask(arr, m, model.prior, idx, model.prior_radius)
    flat[7:10, idx] = prior.T
    if spread is not None:
        flat[10:13, idx] = spread.T
    return planes


def _pad(planes: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    """``C x H x W`` planes reflect-padded (bottom, right) to a multiple of ``k``."""
    _, h, w = planes.shape
    ph, pw = -(-h // k) * k, -(-w // k) * k
    if (ph, pw) == (h, w):
        return planes
    mode = "reflect" if h > 1 and w > 1 and ph - h < h and pw - w < w else "edge"
    padded: NDArray[np.float32] = np.pad(planes, ((0, 0), (0, ph - h), (0, pw - w)),
                                         mode=mode)  # type: ignore[call-overload]
    return padded


def _pass_planes(planes: NDArray[np.float32], m: NDArray[np.bool_], sub: NDArray[np.bool_]
                 ) -> NDArray[np.float32]:
    """The unpadded planes of one pass: the holes of ``m`` outside the pass ``sub`` become known
    gel holding the prior (condition = prior, mask 0, noise 0, spread 0, as on any known
    pixel); the pass's holes keep the prior, spread and noise of the whole mask."""
    out = planes.copy()
    h, w = m.shape
    idx = np.flatnonzero(m & ~sub)
    flat = out.reshape(len(out), h * w)
    flat[0:3, idx] = flat[7:10, idx]
    flat[3:7, idx] = 0.0
    if len(out) > 10:
        flat[10:13, idx] = 0.0
    return out


def _network(planes: NDArray[np.float32], m: NDArray[np.bool_], net: TacDiffModel, steps: int,
             sampler: Sampler, patch: PatchArg, ov: int, ctx: int | None
             ) -> NDArray[np.float32]:
    """The ``3 x H' x W'`` image estimate of one network pass over the padded ``planes``
    filling ``m`` (regions chosen by :func:`_choose`; the prior where nothing ran)."""
    h, w = m.shape
    kind, data = _choose(m, net.multiple, patch, ov, ctx)
    if kind == "whole":
        return _sample(net, planes[None], steps, sampler)[0]
    if kind == "holes":
        windows, owner = data
        return _sample_boxes(net, planes, windows, _window_owner(owner, net.multiple),
                             steps, sampler)
    if kind == "crops":
        crops, labels = data
        return _sample_boxes(net, planes, crops, _crop_owner(labels), steps, sampler)
    origins, run, side = data
    hwc = np.ascontiguousarray(planes[:, :h, :w].transpose(1, 2, 0))
    patches, _ = tile(hwc, side, ov)
    merged = np.ascontiguousarray(patches[..., :3])
    if run.any():
        res = _sample(net, np.ascontiguousarray(patches[run].transpose(0, 3, 1, 2)), steps,
                      sampler)
        merged[run] = res.transpose(0, 2, 3, 1)
    x0: NDArray[np.float32] = merge_patches(merged, origins, (h, w, 3),
                                            mode="feather").transpose(2, 0, 1)
    return x0


def check_orientations(orientations: Any) -> int | None:
    """``orientations`` as an int of :data:`ORIENTATIONS`, or None; ``ValueError`` naming the
    argument otherwise (bools, floats and strings included)."""
    if orientations is None:
        return None
    if (isinstance(orientations, (bool, np.bool_))
            or not isinstance(orientations, (int, np.integer)) or orientations not in ORIENTATIONS):
        raise ValueError(f"orientations: must be one of {ORIENTATIONS} (or None: "
                         f"{DEFAULT_ORIENTATIONS}, 1 for a narrow model such as the fast one); "
                         f"got {orientations!r}")
    return int(orientations)


def default_orientations(net: TacDiffModel) -> int:
    """Orientations averaged when none are asked for: 1 for a narrow model (U-Net base width
    at most :data:`NARROW_BASE`, the shipped fast model's, or a fine-tune of it: speed is what
    it is for), else :data:`DEFAULT_ORIENTATIONS`."""
    base = net.unet.get("base")
    return 1 if isinstance(base, int) and base <= NARROW_BASE else DEFAULT_ORIENTATIONS


def _orientation_list(n: int | None, net: TacDiffModel) -> list[Orientation]:
    """The first ``n`` orientations (a checked count), or :func:`default_orientations` of
    ``net`` for None."""
    return list(_DIHEDRAL[:n if n is not None else default_orientations(net)])


def orientations_for(orientations: Any, model: str | os.PathLike[str] | None
                     ) -> list[Orientation]:
    """The orientations :func:`inpaint_tacdiff` averages for ``model``: ``orientations`` (one
    of :data:`ORIENTATIONS`), or for None :func:`default_orientations` of that model.
    ``TypeError`` / ``ValueError`` naming the argument otherwise."""
    check_model_arg(model)
    return _orientation_list(check_orientations(orientations), load_model(model))


def _orient(a: NDArray[Any], o: Orientation) -> NDArray[Any]:
    """``a`` (``... x H x W``) flipped and transposed as ``o`` says (a contiguous copy)."""
    rows, cols, trans = o
    out = a[..., ::-1, :] if rows else a
    out = out[..., ::-1] if cols else out
    return np.ascontiguousarray(np.swapaxes(out, -1, -2) if trans else out)


def _unorient(a: NDArray[Any], o: Orientation) -> NDArray[Any]:
    """The inverse of :func:`_orient`."""
    rows, cols, trans = o
    out = np.swapaxes(a, -1, -2) if trans else a
    out = out[..., ::-1] if cols else out
    return out[..., ::-1, :] if rows else out


def _network_oriented(planes: NDArray[np.float32], m: NDArray[np.bool_], net: TacDiffModel,
                      steps: int, sampler: Sampler, patch: PatchArg, ov: int, ctx: int | None,
                      orients: list[Orientation]) -> NDArray[np.float32]:
    """The mean over ``orients`` of :func:`_network`'s ``3 x H x W`` image estimate for the
    unpadded ``planes`` filling ``m``, each orientation padded and run on its own."""
    # Summed from zero and divided by the count: one orientation comes back bit for bit.
    acc = np.zeros((3, *m.shape), np.float32)
    for o in orients:
        om = _orient(m, o)
        x0 = _network(_pad(_orient(planes, o), net.multiple), om, net, steps, sampler, patch, ov,
                      ctx)
        acc += _unorient(x0[:, :om.shape[0], :om.shape[1]], o)
    acc /= np.float32(len(orients))
    return acc


def _paste(out: NDArray[np.uint8], x0: NDArray[np.float32], m: NDArray[np.bool_]) -> None:
    """Writes the estimate ``x0`` (``3 x H' x W'``, [-1, 1]) into ``out`` on the pixels of
    ``m``, as uint8."""
    h, w = m.shape
    idx = np.flatnonzero(m)
    out.reshape(h * w, 3)[idx] = from_net(np.ascontiguousarray(x0[:, :h, :w]).reshape(3, h * w)
                                          [:, idx].T)


def inpaint_tacdiff(img: Any, mask: Any, steps: int = DEFAULT_STEPS, *,
                    sampler: Sampler = "dpmpp2m", seed: int | None = 0,
                    patch: PatchArg = "auto", overlap: int = DEFAULT_OVERLAP,
                    context: int | None = None, separation: int = SEPARATION,
                    model: str | os.PathLike[str] | None = None,
                    orientations: int | None = None,
                    device: str = "auto") -> NDArray[np.uint8]:
    """Fills the masked pixels of a BGR frame with the TacDiff diffusion model.

    Args:
        img: ``H x W x 3`` uint8 **BGR** (the model was trained on BGR).
        mask: ``H x W`` bool/uint8, True = fill (markers, dilated once as the paper does).
        steps: sampler steps K, 1..1000 (1: one network call, the fastest; more: sharper
            texture, slower; see docs/notes/2026-11-marker-removal.md,
            "TacDiff speed per setting").
        sampler: ``"dpmpp2m"`` (DPM-Solver++(2M)) or ``"ddim"``.
        seed: seed of the initial noise (None: fresh randomness); the default 0 makes the output
            reproducible.
        patch: ``None`` (whole frame at once), a tile side in px (multiple of 16),
            ``"holes"`` (only windows around groups of holes, each with ``context`` px of gel
            around them, in 16 px cells: :func:`hole_windows`), ``"crops"`` (one crop per hole
            with at least ``context`` px of gel around it, batched: :func:`hole_crops`), or
            ``"auto"`` (whichever of the whole frame, tiles of 128, the crops and the windows
            costs least, see :func:`_choose`).
        overlap: tile overlap in px.
        context: px of known gel kept around the holes in ``"holes"`` windows and
            ``"crops"`` crops (None: :data:`DEFAULT_CONTEXT` = 16 for windows,
            :data:`CROP_CONTEXT` = 8 for crops).
        separation: px (>= 0). Holes (8-connected parts of ``mask``) within this distance of
            one another (Chebyshev, between their nearest pixels) are filled in separate passes
            (:func:`tacswitch.tacdiff.passes.hole_passes`): each pass runs the network on its
            own holes while the other holes show the classical prior as known gel, so no hole
            sees a hole of its own pass that close (crowded holes, e.g. a mask holding twice the
            markers, are outside what the network was trained on and bias its fill). Prior and
            noise are those of the whole mask, so a pass changes only what a hole's neighbours
            look like. Default :data:`SEPARATION` (4 px, closer than the training masks' holes
            came). A marker grid without holes that close is one pass, output identical to
            ``separation=0``, for a check of about 2 ms at 640 x 480; 0 always runs one pass.
        model: ONNX model path, or a shipped model by name: ``"default"`` (the default) or
            ``"fast"`` (narrower, one orientation by default: ~4.6x as fast as the default
            setting at 640 x 480, less accurate).
        orientations: how many orientations of the frame the network runs in, their image
            estimates averaged before rounding: 1, 2 (+ mirrored left-right), 4 (+ upside down,
            + both) or 8 (+ the transposed four); the time grows in proportion. None (default):
            :data:`DEFAULT_ORIENTATIONS` (4), or 1 for a narrow model such as the shipped fast
            one (:func:`default_orientations`). Each pixel keeps its noise draw in every
            orientation.
        device: ``"auto"`` (default: a CUDA GPU when onnxruntime offers one, else the CPU),
            ``"cpu"`` or ``"cuda"`` (``ValueError`` naming ``device`` when onnxruntime has no
            CUDA here); see :func:`tacswitch._ort.providers`.

    Returns:
        A new ``H x W x 3`` uint8 image; pixels outside ``mask`` are bit-identical to ``img``.
    """
    arr = as_image_u8(img, "img")
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"img: expected a BGR H x W x 3 uint8 image (the model was trained on "
                         f"colour frames); got shape {arr.shape}")
    m = _as_mask(mask, arr.shape).astype(bool)
    timesteps(steps)  # validates steps before any work
    sep = as_count(separation, "separation", 0, None)
    n_orient = check_orientations(orientations)
    check_model_arg(model)
    _ort_providers(device)  # a bad device fails even when there is nothing to fill
    if not m.any():
        return arr.copy()
    if m.all():
        raise ValueError("mask: covers the whole image; nothing is known to inpaint from")
    net = load_model(model, device)
    orients = _orientation_list(n_orient, net)
    if patch not in (None, "auto", "holes", "crops"):
        side = as_count(patch, "patch", net.multiple)
        if side % net.multiple:
            raise ValueError(f"patch: must be a multiple of {net.multiple}; got {side}")
    ov = as_count(overlap, "overlap", 0)
    ctx = None if context is None else as_count(context, "context", 0)
    # Noise drawn once for every pixel to fill (as a one-pass run draws it), and the prior of
    # the whole mask: a pixel gets both whatever its pass.
    noise = np.random.default_rng(seed).standard_normal((3, int(np.count_nonzero(m))),
                                                        dtype=np.float32)
    planes = _frame_planes(arr, m, net, noise)
    labels, pass_of = hole_passes(m, sep)
    out = arr.copy()
    if pass_of.max(initial=0) <= 0:
        _paste(out, _network_oriented(planes, m, net, steps, sampler, patch, ov, ctx, orients),
               m)
        return out
    for sub in pass_masks(labels, pass_of):
        x0 = _network_oriented(_pass_planes(planes, m, sub), sub, net, steps, sampler, patch, ov,
                               ctx, orients)
        _paste(out, x0, sub)
    return out
