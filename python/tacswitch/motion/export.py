"""ONNX export of a :class:`~tacswitch.motion.model.MotionNet` (torch; export time only).

The graph takes the frame as numpy holds it and the marker centres as an input, so one model
serves any grid and any frame size, and returns the motion at those centres::

    image     uint8   1 x H x W x 3   BGR
    centres   float32 N x 2           (x, y) px, pixel centres at integers
    reference uint8   1 x H x W x 3   BGR, markerless no-contact frame (models with use_ref only)
    -> motion float32 N x 2           (dx, dy) px

Normalisation and the bilinear gather are inside the graph. Metadata (``tacswitch.*`` keys) record
the kind (``motion``), the architecture, the design, whether the reference is required, the
working width and the default marker grid.

A :class:`~tacswitch.motion.model.ConsistentMotionNet` exports with one more input::

    has_reference float32 1               1: motion from reference to image; 0: single-frame
                                          motion of image from rest (reference ignored)

and its graph computes ``G(x, (x - r) h) - h G(r, 0)`` (both terms in one batch of two), so
identical frames give exactly zero motion. A
:class:`~tacswitch.motion.model.SingleFrameMotionNet` (design ``single``) exports ``G(x, 0)``
alone, with the inputs ``image`` and ``centres``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from torch import nn

from tacswitch.motion.model import ConsistentMotionNet, MotionNet, SingleFrameMotionNet

OPSET = 17


class _ConsistentGraph(nn.Module):
    def __init__(self, net: ConsistentMotionNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: torch.Tensor, centres: torch.Tensor, reference: torch.Tensor,
                has_reference: torch.Tensor) -> torch.Tensor:
        return self.net(image, centres.unsqueeze(0), reference, has_reference)[0]


class _Graph(nn.Module):
    def __init__(self, net: MotionNet | SingleFrameMotionNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, image: torch.Tensor, centres: torch.Tensor,
                reference: torch.Tensor | None = None) -> torch.Tensor:
        return self.net(image, centres.unsqueeze(0), reference)[0]


def export_onnx(net: MotionNet | ConsistentMotionNet | SingleFrameMotionNet,
                path: str | Path, *,
                metadata: dict[str, Any] | None = None, height: int = 240,
                width: int = 320) -> Path:
    """Writes ``net`` (eval mode) as ONNX to ``path`` (atomically) and returns the path."""
    from tacswitch._io import write_onnx

    was_training = net.training
    consistent = isinstance(net, ConsistentMotionNet)
    # The wrapper must be in eval mode too: the exporter restores the wrapper's mode afterwards,
    # which would otherwise switch the caller's network to training mode (batch-stat BN).
    g: nn.Module = (_ConsistentGraph(net) if consistent else _Graph(net)).eval()  # type: ignore[arg-type]
    img = torch.zeros(1, height, width, 3, dtype=torch.uint8)
    cen = torch.tensor([[width / 2, height / 2], [10.0, 10.0], [width - 5.0, 3.0]])
    args: tuple[torch.Tensor, ...]
    if consistent:
        args = (img, cen, img.clone(), torch.ones(1))
    else:
        args = (img, cen, img.clone()) if net.use_ref else (img, cen)
    names = ["image", "centres", "reference", "has_reference"][: len(args)]
    axes: dict[str, dict[int, str]] = {"image": {1: "height", 2: "width"}, "centres": {0: "n"},
                                       "motion": {0: "n"}}
    if len(args) > 2:
        axes["reference"] = {1: "height", 2: "width"}
    target = Path(path)
    tmp = target.with_suffix(".tmp.onnx")
    with torch.no_grad():
        torch.onnx.export(g, args, str(tmp), input_names=names, output_names=["motion"],
                          dynamic_axes=axes, opset_version=OPSET, dynamo=False)
    net.train(was_training)
    meta = {"tacswitch.kind": "motion", "tacswitch.arch": net.arch,
            "tacswitch.design": "consistent" if consistent else getattr(net, "design", "plain"),
            "tacswitch.use_ref": json.dumps(net.use_ref)}
    return write_onnx(tmp, target, meta, metadata)
