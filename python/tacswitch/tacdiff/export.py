"""ONNX export of the TacDiff denoiser (torch; export time only).

One self-contained float32 graph with dynamic batch, height and width (multiples of 16)::

    cond   float32 B x 3 x H x W   condition image, BGR in [-1, 1] (holes may hold anything)
    mask   float32 B x 1 x H x W   1 = pixel to fill
    x_t    float32 B x 3 x H x W   current sample of the scaled residual over TELEA (only its
                                   masked pixels are read)
    noise  float32 B x 3 x H x W   the run's initial noise, shown in the condition's holes
    prior  float32 B x 3 x H x W   the frame with its holes filled by TELEA, in [-1, 1]
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

OPSET = 17
INPUTS = ("cond", "mask", "x_t", "noise", "prior", "sigma")


class _Graph(nn.Module):
    def __init__(self, net: DenoiserUNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, cond: torch.Tensor, mask: torch.Tensor, x_t: torch.Tensor,
                noise: torch.Tensor, prior: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
        return self.net(network_input(cond, mask, x_t, noise, prior), sigma)


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
    args = (torch.zeros(b, 3, h, w), torch.ones(b, 1, h, w), torch.zeros(b, 3, h, w),
            torch.zeros(b, 3, h, w), torch.zeros(b, 3, h, w), torch.full((b,), 0.5))
    axes: dict[str, dict[int, str]] = {
        name: {0: "batch", 2: "height", 3: "width"} for name in (*INPUTS[:5], "v")}
    axes["sigma"] = {0: "batch"}
    target = Path(path)
    tmp = target.with_suffix(".tmp.onnx")
    with torch.no_grad():
        torch.onnx.export(g, args, str(tmp), input_names=list(INPUTS), output_names=["v"],
                          dynamic_axes=axes, opset_version=OPSET, dynamo=False)
    net.train(was_training)
    meta = {"tacswitch.kind": "tacdiff", "tacswitch.prediction": "v",
            "tacswitch.target": "residual-over-telea",
            "tacswitch.residual_scale": str(RESIDUAL_SCALE),
            "tacswitch.schedule": "cosine-ztsnr", "tacswitch.colour_order": "BGR",
            "tacswitch.multiple": str(MULTIPLE), "tacswitch.unet": json.dumps(net.cfg.to_dict())}
    return write_onnx(tmp, target, meta, metadata)
