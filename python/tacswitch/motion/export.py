"""ONNX export of a :class:`~tacswitch.motion.model.MotionNet` (torch; export time only).

The graph takes the frame as numpy holds it and the marker centres as an input, so one model
serves any grid and any frame size, and returns the motion at those centres::

    image     uint8   1 x H x W x 3   BGR
    centres   float32 N x 2           (x, y) px, pixel centres at integers
    reference uint8   1 x H x W x 3   BGR, markerless no-contact frame (models with use_ref only)
    -> motion float32 N x 2           (dx, dy) px

Normalisation and the bilinear gather are inside the graph. Metadata (``tacswitch.*`` keys) record
the architecture, whether the reference is used, the working width and the default marker grid.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from torch import nn

from tacswitch.motion.model import MotionNet

OPSET = 17


class _Graph(nn.Module):
    def __init__(self, net: MotionNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: torch.Tensor, centres: torch.Tensor,
                reference: torch.Tensor | None = None) -> torch.Tensor:
        return self.net(image, centres.unsqueeze(0), reference)[0]


def export_onnx(net: MotionNet, path: str | Path, *, metadata: dict[str, Any] | None = None,
                height: int = 240, width: int = 320) -> Path:
    """Writes ``net`` (eval mode) as ONNX to ``path`` (atomically) and returns the path."""
    from tacswitch._io import write_onnx

    was_training = net.training
    # The wrapper must be in eval mode too: the exporter restores the wrapper's mode afterwards,
    # which would otherwise switch the caller's network to training mode (batch-stat BN).
    g = _Graph(net).eval()
    img = torch.zeros(1, height, width, 3, dtype=torch.uint8)
    cen = torch.tensor([[width / 2, height / 2], [10.0, 10.0], [width - 5.0, 3.0]])
    args: tuple[torch.Tensor, ...] = (img, cen, img.clone()) if net.use_ref else (img, cen)
    names = ["image", "centres", "reference"][: len(args)]
    axes: dict[str, dict[int, str]] = {"image": {1: "height", 2: "width"}, "centres": {0: "n"},
                                       "motion": {0: "n"}}
    if net.use_ref:
        axes["reference"] = {1: "height", 2: "width"}
    target = Path(path)
    tmp = target.with_suffix(".tmp.onnx")
    with torch.no_grad():
        torch.onnx.export(g, args, str(tmp), input_names=names, output_names=["motion"],
                          dynamic_axes=axes, opset_version=OPSET, dynamo=False)
    net.train(was_training)
    meta = {"tacswitch.arch": net.arch, "tacswitch.use_ref": json.dumps(net.use_ref)}
    return write_onnx(tmp, target, meta, metadata)
