"""ONNX export of the TacDiff denoiser (torch; export time only).

One self-contained float32 graph with dynamic batch, height and width (multiples of 16)::

    cond   float32 B x 3 x H x W   condition image, BGR in [-1, 1] (holes may hold anything)
    mask   float32 B x 1 x H x W   1 = pixel to fill
    x_t    float32 B x 3 x H x W   current sample of the scaled residual over the prior (only
                                   its masked pixels are read)
    noise  float32 B x 3 x H x W   the run's initial noise, shown in the condition's holes
    prior  float32 B x 3 x H x W   the frame with its holes filled classically, in [-1, 1]
                                   (:mod:`~tacswitch.tacdiff.prior`)
    spread float32 B x 3 x H x W   TELEA minus biharmonic fill (``telea+biharmonic`` prior only)
    sigma  float32 B               noise level sigma(t) in [0, 1]
    -> v   float32 B x 3 x H x W   v-prediction of the residual

The Palette input assembly (:func:`~tacswitch.tacdiff.model.network_input`) is inside the graph,
so the numpy sampler never re-implements it. Metadata (``tacswitch.*``) record the architecture,
the colour order, the size multiple and the training run.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from torch import nn

from tacswitch.tacdiff.model import MULTIPLE, RESIDUAL_SCALE, DenoiserUNet, network_input
from tacswitch.tacdiff.prior import PRIOR_RADIUS, check_radius, has_spread

OPSET = 17
#: Image inputs of every model, then ``spread`` for two-fill priors, then ``sigma``.
IMAGE_INPUTS = ("cond", "mask", "x_t", "noise", "prior")


def input_names(prior: str) -> tuple[str, ...]:
    """The graph's input names for a model with ``prior``."""
    return (*IMAGE_INPUTS, *(("spread",) if has_spread(prior) else ()), "sigma")


class _Graph(nn.Module):
    def __init__(self, net: DenoiserUNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, cond: torch.Tensor, mask: torch.Tensor, x_t: torch.Tensor,
                noise: torch.Tensor, prior: torch.Tensor, *rest: torch.Tensor) -> torch.Tensor:
        spread, sigma = (rest[0], rest[1]) if len(rest) == 2 else (None, rest[0])
        return self.net(network_input(cond, mask, x_t, noise, prior, spread), sigma)


def export_onnx(net: DenoiserUNet, path: str | Path, *, metadata: dict[str, Any] | None = None,
                fp16: bool = False) -> Path:
    """Writes ``net`` as ONNX to ``path`` (atomically) and returns the path.

    ``fp16=True`` is refused: the noise embedding evaluates ``sin(1000 sigma)`` and GroupNorm a
    variance, both of which lose their meaning in half precision (the embedding's phase error
    reaches radians), and onnxruntime's CPU provider runs float16 convolutions slower than
    float32 anyway.
    """
    from tacswitch._io import write_onnx

    if fp16:
        raise ValueError("fp16: float16 export is not supported (the noise-level embedding and "
                         "GroupNorm lose precision, and CPU onnxruntime is not faster in "
                         "float16); export float32")
    was_training = net.training
    g = _Graph(net).eval()
    b, h, w = 2, 2 * MULTIPLE, 3 * MULTIPLE
    names = input_names(net.cfg.prior)
    images = [torch.ones(b, 1, h, w) if n == "mask" else torch.zeros(b, 3, h, w)
              for n in names[:-1]]
    args = (*images, torch.full((b,), 0.5))
    axes: dict[str, dict[int, str]] = {
        name: {0: "batch", 2: "height", 3: "width"} for name in (*names[:-1], "v")}
    axes["sigma"] = {0: "batch"}
    target = Path(path)
    tmp = target.with_suffix(".tmp.onnx")
    with torch.no_grad():
        torch.onnx.export(g, args, str(tmp), input_names=list(names), output_names=["v"],
                          dynamic_axes=axes, opset_version=OPSET, dynamo=False)
    net.train(was_training)
    meta = {"tacswitch.kind": "tacdiff", "tacswitch.prediction": "v",
            "tacswitch.target": f"residual-over-{net.cfg.prior}",
            "tacswitch.prior": net.cfg.prior,
            # The TELEA radius the training priors used (infer.prior_radius reads it).
            "tacswitch.prior_radius": f"{check_radius(net.cfg.prior_radius):g}",
            "tacswitch.residual_scale": str(RESIDUAL_SCALE),
            "tacswitch.schedule": "cosine-ztsnr", "tacswitch.colour_order": "BGR",
            "tacswitch.multiple": str(MULTIPLE), "tacswitch.unet": json.dumps(net.cfg.to_dict())}
    return write_onnx(tmp, target, meta, metadata)


def network_from_onnx(path: str | Path) -> DenoiserUNet:
    """The :class:`DenoiserUNet` (eval mode) of an ONNX file written by :func:`export_onnx`,
    its weights read back from the graph, so a model shipped without torch weights (the fast
    one) can be fine-tuned or trained further.

    The exporter keeps every weight under its parameter name (``net.`` + the state-dict key)
    except the GroupNorm scales and shifts, which it folds into anonymous ``Mul``/``Add``
    constants; those are matched to the remaining parameters in graph order, shape by shape.
    """
    import onnx
    from onnx import numpy_helper

    from tacswitch.tacdiff.model import UNetConfig

    model = onnx.load(str(path))
    meta = {p.key: p.value for p in model.metadata_props}
    if meta.get("tacswitch.kind") != "tacdiff" or "tacswitch.unet" not in meta:
        raise ValueError(f"path: {str(path)!r} is not a TacDiff ONNX model")
    cfg = json.loads(meta["tacswitch.unet"])
    # The radius metadata wins over the architecture's record: set_metadata may change it.
    radius = meta.get("tacswitch.prior_radius", cfg.get("prior_radius", PRIOR_RADIUS))
    net = DenoiserUNet(UNetConfig(base=cfg["base"], mults=tuple(cfg["mults"]),
                                  attention=cfg["attention"], emb=cfg["emb"],
                                  prior=cfg["prior"],
                                  prior_radius=check_radius(radius, "path")))
    named, anonymous = {}, []
    for init in model.graph.initializer:
        arr = numpy_helper.to_array(init)
        if init.name.startswith("net."):
            named[init.name[4:]] = arr
        else:
            anonymous.append((int(init.name.rsplit("_", 1)[-1]), arr))
    anonymous.sort(key=lambda kv: kv[0])
    state = net.state_dict()
    rest = iter(a for _, a in anonymous if a.ndim == 3 and a.shape[1:] == (1, 1))
    new = {}
    for key, ref in state.items():
        found = named.get(key)
        if found is None:
            folded = next(rest, None)
            if folded is None:
                raise ValueError(f"path: {str(path)!r} has no weight for {key!r}")
            found = folded.reshape(-1)
        arr = found
        if tuple(arr.shape) != tuple(ref.shape):
            raise ValueError(f"path: {str(path)!r}: weight {key!r} has shape {arr.shape}, "
                             f"expected {tuple(ref.shape)}")
        new[key] = torch.from_numpy(arr.copy())
    net.load_state_dict(new)
    return net.eval()
