"""TacDiff: diffusion inpainting for marker -> markerless (the paper's central model, small).

- :mod:`tacswitch.tacdiff.infer`: :func:`inpaint_tacdiff` with onnxruntime (numpy only);
- :mod:`tacswitch.tacdiff.hybrid`: :func:`inpaint_hybrid`, the network only on markers in or near
  the contact and TELEA elsewhere;
- :mod:`tacswitch.tacdiff.schedule`: the noise schedule and samplers (numpy), separate from the
  network;
- :mod:`tacswitch.tacdiff.data`: training pairs (simulated, or the marker-offset strategy on a
  user's own marker frames) and random crops;
- :mod:`~tacswitch.tacdiff.model`, :mod:`~tacswitch.tacdiff.train`,
  :mod:`~tacswitch.tacdiff.export`: the U-Net, training and ONNX export (need torch,
  ``pip install "tacswitch[train]"``).

Importing this package imports neither torch nor onnxruntime.
"""

from __future__ import annotations

from tacswitch.tacdiff.hybrid import HybridInfo, inpaint_hybrid
from tacswitch.tacdiff.infer import (
    DEFAULT_STEPS,
    TacDiffModel,
    default_model_path,
    inpaint_tacdiff,
)

__all__ = [
    "DEFAULT_STEPS",
    "HybridInfo",
    "TacDiffModel",
    "default_model_path",
    "inpaint_hybrid",
    "inpaint_tacdiff",
]
