"""TacDiff inference with onnxruntime (numpy only; never imports torch).

:func:`inpaint_tacdiff` fills the masked pixels of a BGR frame with the diffusion model:

1. The holes are filled classically first (the prior, :mod:`~tacswitch.tacdiff.prior`: the
   mean of our TELEA and biharmonic fills, or TELEA for older models; what is diffused is the
   residual over it, see :mod:`~tacswitch.tacdiff.model`). Noise is drawn once for the whole
   frame (seeded), so overlapping patches start from the same noise.
2. Regions: the whole frame (padded by reflection to a multiple of 16) or ``patch x patch``
   tiles from the Rust :func:`tacswitch.tile`; tiles without a pixel to fill are not run (their
   output is the input). ``patch="auto"`` picks whichever runs fewer pixels through the network,
   so sparse masks (few markers, or the contact-only mask of ``method="hybrid"``) cost little.
3. K sampler steps from pure noise (:mod:`~tacswitch.tacdiff.schedule`: DPM-Solver++(2M) or DDIM,
   v-prediction, zero terminal SNR); known pixels are pasted into the network input at every
   step (inside the ONNX graph).
4. Tiles are merged by the Rust :func:`tacswitch.merge_patches` (feathered); only masked pixels
   of the output differ from the input.
"""

from __future__ import annotations

import itertools
import json
import os
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_image_u8
from tacswitch._ort import cached, open_session
from tacswitch.tacdiff.prior import check_prior, combine, fills, has_spread, to_net
from tacswitch.tacdiff.schedule import Sampler, Solver, alpha_sigma, timesteps, v_to_x0_eps

#: File name of the shipped default model under ``tacswitch/models``.
DEFAULT_MODEL = "tacdiff_unet.onnx"
#: Default sampler steps (the speed/accuracy table in BENCHMARKS.md says why).
DEFAULT_STEPS = 1
#: Default tile side and overlap, px, when tiling (multiples of the model's size multiple).
DEFAULT_PATCH, DEFAULT_OVERLAP = 128, 32
#: Most regions sent to onnxruntime in one call (bounds memory on huge frames).
MAX_BATCH = 16

PatchArg = int | Literal["auto"] | None


def default_model_path() -> Path:
    """Path of the shipped default model."""
    return Path(__file__).resolve().parent.parent / "models" / DEFAULT_MODEL


def default_weights_path() -> Path:
    """Path of the shipped model's torch weights (float16 safetensors; the starting point of
    ``tacswitch finetune``)."""
    return default_model_path().with_suffix(".safetensors")


class TacDiffModel:
    """One loaded denoiser (an onnxruntime session and its metadata).

    Args:
        path: ONNX file written by :func:`tacswitch.tacdiff.export.export_onnx`; default: the
            shipped model.
        threads: intra-op threads (default ``os.cpu_count()``).
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *,
                 threads: int | None = None) -> None:
        self.path = Path(path) if path is not None else default_model_path()
        self.session, meta = open_session(self.path, threads)
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
        inputs = [i.name for i in self.session.get_inputs()]
        if ("spread" in inputs) != has_spread(self.prior):
            raise ValueError(f"model: {str(self.path)!r} has inputs {inputs}, which do not "
                             f"match its prior {self.prior!r}")

    @property
    def channels(self) -> int:
        """Channels of the region stack :func:`_sample` takes: cond 3, mask 1, noise 3, prior 3
        and, for two-fill priors, spread 3."""
        return 13 if has_spread(self.prior) else 10

    def v(self, cond: NDArray[np.float32], mask: NDArray[np.float32], x_t: NDArray[np.float32],
          noise: NDArray[np.float32], prior: NDArray[np.float32], sigma: float,
          spread: NDArray[np.float32] | None = None) -> NDArray[np.float32]:
        """The network's v-prediction for a batch (arrays as in the export's docstring)."""
        if (spread is not None) != has_spread(self.prior):
            raise ValueError(f"spread: this model's prior is {self.prior!r}; pass spread "
                             "exactly for 'telea+biharmonic'")
        outs = []
        for i in range(0, len(cond), MAX_BATCH):
            sl = slice(i, i + MAX_BATCH)
            n = len(cond[sl])
            feed = {"cond": cond[sl], "mask": mask[sl], "x_t": x_t[sl], "noise": noise[sl],
                    "prior": prior[sl], "sigma": np.full(n, sigma, np.float32)}
            if spread is not None:
                feed["spread"] = spread[sl]
            outs.append(self.session.run(None, feed)[0])
        return np.concatenate(outs)


def load_model(path: str | os.PathLike[str] | None = None) -> TacDiffModel:
    """The cached :class:`TacDiffModel` of ``path`` (one session per file and process)."""
    return cached(TacDiffModel, Path(path) if path is not None else default_model_path())


def _regions(stack: NDArray[np.float32], mask: NDArray[np.bool_], multiple: int,
             patch: PatchArg, overlap: int) -> tuple[str, Any]:
    """Chooses whole-frame or tiled processing. Returns ``("whole", padded stack)`` or
    ``("tiles", (patches, origins, run))`` where ``run`` flags tiles holding a pixel to fill."""
    from tacswitch.inpaint import tile

    h, w = mask.shape
    ph, pw = -(-h // multiple) * multiple, -(-w // multiple) * multiple
    whole_cost = ph * pw
    if patch is None or (patch == "auto" and min(h, w) < DEFAULT_PATCH):
        return "whole", _pad(stack, ph, pw)
    side = DEFAULT_PATCH if patch == "auto" else int(patch)
    patches, origins = tile(stack, side, overlap)
    run = np.array([mask[y:y + side, x:x + side].any() for x, y in origins])
    if patch == "auto" and int(run.sum()) * side * side >= whole_cost:
        return "whole", _pad(stack, ph, pw)
    return "tiles", (patches, origins, run)


def _pad(a: NDArray[np.float32], ph: int, pw: int) -> NDArray[np.float32]:
    h, w = a.shape[:2]
    if (h, w) == (ph, pw):
        return a
    mode = "reflect" if h > 1 and w > 1 and ph - h < h and pw - w < w else "edge"
    out: NDArray[np.float32] = np.pad(a, ((0, ph - h), (0, pw - w), (0, 0)),
                                      mode=mode)  # type: ignore[call-overload]
    return out


def _sample(model: TacDiffModel, regions: NDArray[np.float32], steps: int, sampler: Sampler
            ) -> NDArray[np.float32]:
    """Runs the sampler on ``B x S x S x C`` regions (cond 3, mask 1, noise 3, prior 3, and
    spread 3 for two-fill priors; channels last) and returns the ``B x S x S x 3`` image
    estimates in [-1, 1]."""
    x = np.ascontiguousarray(regions.transpose(0, 3, 1, 2))
    cond, mask, noise, prior = x[:, :3], x[:, 3:4], x[:, 4:7], x[:, 7:10]
    spread = x[:, 10:13] if x.shape[1] > 10 else None
    scale = model.residual_scale
    # Residual bounds that keep prior + residual inside the image range [-1, 1].
    lo, hi = scale * (-1.0 - prior), scale * (1.0 - prior)
    x_t = noise.copy()
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
    img = np.clip(prior + np.clip(r0, lo, hi) / scale, -1.0, 1.0)
    return np.ascontiguousarray(img.transpose(0, 2, 3, 1))


def inpaint_tacdiff(img: Any, mask: Any, steps: int = DEFAULT_STEPS, *,
                    sampler: Sampler = "dpmpp2m", seed: int | None = 0,
                    patch: PatchArg = "auto", overlap: int = DEFAULT_OVERLAP,
                    model: str | os.PathLike[str] | None = None) -> NDArray[np.uint8]:
    """Fills the masked pixels of a BGR frame with the TacDiff diffusion model.

    Args:
        img: ``H x W x 3`` uint8 **BGR** (the model was trained on BGR).
        mask: ``H x W`` bool/uint8, True = fill (markers, dilated once as the paper does).
        steps: sampler steps K, 1..1000 (1: one network call, the fastest; more: sharper
            texture, slower; see BENCHMARKS.md).
        sampler: ``"dpmpp2m"`` (DPM-Solver++(2M)) or ``"ddim"``.
        seed: seed of the initial noise (None: fresh randomness); the default 0 makes the output
            reproducible.
        patch: ``None`` (whole frame at once), a tile side in px (multiple of 16), or ``"auto"``
            (tiles of 128 when they run fewer pixels than the whole frame).
        overlap: tile overlap in px.
        model: ONNX model path (default: the shipped model).

    Returns:
        A new ``H x W x 3`` uint8 image; pixels outside ``mask`` are bit-identical to ``img``.
    """
    from tacswitch._checks import as_count
    from tacswitch.inpaint import _as_mask, merge_patches

    arr = as_image_u8(img, "img")
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"img: expected a BGR H x W x 3 uint8 image (the model was trained on "
                         f"colour frames); got shape {arr.shape}")
    m = _as_mask(mask, arr.shape).astype(bool)
    timesteps(steps)  # validates steps before any work
    if not m.any():
        return arr.copy()
    if m.all():
        raise ValueError("mask: covers the whole image; nothing is known to inpaint from")
    net = load_model(model)
    if patch not in (None, "auto"):
        side = as_count(patch, "patch", net.multiple)
        if side % net.multiple:
            raise ValueError(f"patch: must be a multiple of {net.multiple}; got {side}")
    ov = as_count(overlap, "overlap", 0)
    h, w = m.shape
    rng = np.random.default_rng(seed)
    stack = np.empty((h, w, net.channels), np.float32)
    stack[..., :3] = to_net(arr)
    stack[..., 3] = m
    stack[..., 4:7] = rng.standard_normal((h, w, 3), dtype=np.float32)
    telea, smooth = fills(arr, m, net.prior)
    prior, spread = combine(to_net(telea), None if smooth is None else to_net(smooth))
    stack[..., 7:10] = prior
    if spread is not None:
        stack[..., 10:13] = spread
    kind, data = _regions(stack, m, net.multiple, patch, ov)
    if kind == "whole":
        x0 = _sample(net, data[None], steps, sampler)[0, :h, :w]
    else:
        patches, origins, run = data
        merged = patches[..., :3].copy()
        if run.any():
            merged[run] = _sample(net, patches[run], steps, sampler)
        x0 = merge_patches(np.ascontiguousarray(merged), origins, (h, w, 3), mode="feather")
    out = arr.copy()
    vals = np.rint((x0[m] + 1.0) * np.float32(127.5))
    out[m] = np.clip(vals, 0, 255).astype(np.uint8)
    return out
