"""Markerless -> marker: the 2D motion each marker would have had, from a markerless image.

- :mod:`tacswitch.motion.infer`: :func:`predict_motion` with onnxruntime (numpy only, no torch);
- :mod:`tacswitch.motion.data`: synthetic training/evaluation pairs from :mod:`tacswitch.sim`;
- :mod:`tacswitch.motion.model`, :mod:`~tacswitch.motion.train`, :mod:`~tacswitch.motion.export`:
  the networks, training and ONNX export (need torch, ``pip install "tacswitch[train]"``);
- :mod:`tacswitch.motion.sequence`: :class:`MarkerlessTracker`, motion from rest over a video
  that starts at the no-contact frame;
- :mod:`tacswitch.motion.reference`: does a reference lack the frame's contact, which markers
  lie near it;
- :mod:`tacswitch.motion.flow` (dense optical flow from a reference),
  :mod:`~tacswitch.motion.heuristic` (the outward-from-contact rule) and
  :mod:`~tacswitch.motion.mechanics` (an elastic press law on the imprint): the training-free
  methods of :func:`predict_motion`;
- :mod:`tacswitch.motion.evaluate`: the paper's metrics, the baselines and slip on markerless
  streams. The real-texture proxies they are scored on (real frames warped by known fields,
  grasp videos of real texture) are evaluation code of the benches, not of this package:
  ``benches/proxies/``.

Importing this package imports neither torch nor onnxruntime.
"""

from __future__ import annotations

from tacswitch.motion.infer import MotionModel, default_model_path, predict_motion
from tacswitch.motion.sequence import MarkerlessTracker

__all__ = ["MarkerlessTracker", "MotionModel", "default_model_path", "predict_motion"]
