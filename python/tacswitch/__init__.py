"""tacswitch: mode-switchable optical tactile sensing (GelSight, GelSight Mini, DIGIT-style).

One sensor, both modes, in software:

- marker -> markerless: remove painted markers from an image (:func:`remove_markers`,
  :func:`inpaint_telea`), with patch :func:`tile` / :func:`merge_patches` for patch models;
- markerless -> marker: :func:`predict_motion` (a learned regressor run with onnxruntime,
  :class:`MotionModel`) gives the motion each marker would have had, so :class:`SlipDetector`
  and shear code run on a markerless sensor;
- the fast paths around it: :func:`extract_markers`, :func:`match_markers`,
  :class:`MarkerTracker`, :class:`SlipDetector`.

Conventions: images are numpy ``H x W x 3`` uint8 in **BGR** order (OpenCV's), grey ``H x W``
accepted; points are ``N x 2`` float32 ``(x, y)`` in pixels with pixel centres at integer
coordinates; motions are ``N x 2`` ``(dx, dy)`` aligned with the reference points, NaN where a
marker is lost, with a separate boolean ``valid`` array.

``import tacswitch`` is light: it loads the native extension and numpy only. OpenCV, onnxruntime and
torch are imported by the functions that need them.
"""

from __future__ import annotations

from tacswitch._native import __version__
from tacswitch.grasp.detector import GraspSlipDetector, GraspSlipState
from tacswitch.inpaint import inpaint_biharmonic, inpaint_telea, merge_patches, tile
from tacswitch.markers import Markers, dilate_mask, extract_markers
from tacswitch.motion.infer import MotionModel, predict_motion
from tacswitch.motion.sequence import MarkerlessTracker
from tacswitch.removal import remove_markers
from tacswitch.slip import SlipDetector, SlipState
from tacswitch.tracking import MarkerTracker, estimate_pitch, match_markers

__all__ = [
    "GraspSlipDetector",
    "GraspSlipState",
    "MarkerTracker",
    "MarkerlessTracker",
    "Markers",
    "MotionModel",
    "SlipDetector",
    "SlipState",
    "__version__",
    "dilate_mask",
    "estimate_pitch",
    "extract_markers",
    "inpaint_biharmonic",
    "inpaint_telea",
    "match_markers",
    "merge_patches",
    "predict_motion",
    "remove_markers",
    "tile",
]
