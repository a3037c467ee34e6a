"""Causal features of a tracked marker field over time, for the learned slip detector.

One feature vector per frame, computed from that frame and the ones before it only (the detector
decides online). Every length is divided by the marker pitch, so a 640x480 GelSight and a 320x240
GelSight Mini give the same numbers for the same gel motion, and every feature is invariant to
rotating or mirroring the image (a sensor mounted the other way round reads the same).

Per frame (the motion ``m`` of each marker since the first frame):

- the state of the field: median and 90th-percentile ``|m|``, the length of the mean motion,
  the 90th-percentile residual of the best affine fit (how far the field is from one elastic
  load) and the fit's dilation and absolute rotation;
- its change over 1 and 4 frames (velocity and short-term motion): the same magnitude
  statistics, the affine residual of the change and that residual relative to the change
  (stick moves the contact coherently; slip starts at the edge and spreads);
- the share of markers lost; the relaxation: how far the median ``|m|`` fell below its largest
  value of the last second (the gel snapping back as the contact slides away or lets go); the
  median change over the last second.

The vector of a frame is those values, their largest and smallest over the last :data:`WINDOW`
frames and their change over the last :data:`LONG` frames; then how abruptly the field changes
(:data:`SNAP_FEATURES`: a shaken grasp reverses smoothly over several frames, shear released by
a slip snaps back within one or two): the 90th-percentile acceleration (second difference of
each marker's motion), that over the last two velocities' 90th percentiles, the cosine between
the last two velocities (-1: a reversal), and the motion back towards rest of the displaced
markers (90th percentile, median, and median share of the displacement), with their largest
value over the last :data:`WINDOW` frames. A scorer trained before the snap-back values
(:data:`N_BASE_FEATURES` inputs) reads the vector's first :data:`N_BASE_FEATURES` values.
Computed in the Rust core (``rust/core/src/slip_features.rs``, a few microseconds a frame).

``still_filter=True`` reads the motion through a hysteresis that holds still markers exactly
still under camera noise (``rust/core/src/still_filter.rs``): a marker's motion is reported
unchanged until its tracked motion is more than ``h`` pitches from the value reported last, with
``h`` 8 times the stream's own frame-to-frame jitter floor (at most 0.01 pitch). In the MPEG-4
recordings the scorers learned from, a still marker is tracked at exactly the same place frame
after frame, so there ``h`` is 0 and nothing changes; sensor noise of a few grey levels moves
still markers by about 0.001 pitch a frame, which the scorers would read as a different gel.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch import _native
from tacswitch._checks import as_motion, as_points, as_valid

#: Frames over which the window maximum and minimum are taken (0.32 s at 25 frames/s).
WINDOW = 8
#: Frames of the long-term change and relaxation features (1 s at 25 frames/s).
LONG = 25
#: Names of the per-frame features, in order.
FRAME_FEATURES = (
    "median_disp", "p90_disp", "mean_vector", "affine_residual", "dilation", "rotation",
    "v1_p90", "v1_median", "v1_affine_residual", "v1_incoherence",
    "v4_p90", "v4_median", "v4_affine_residual", "v4_incoherence",
    "lost", "relaxation", "long_change",
)
N_FRAME = len(FRAME_FEATURES)
#: Names of the per-frame snap-back values, in order.
SNAP_FEATURES = ("snap_accel_p90", "snap_abruptness", "snap_reversal", "snap_back_p90",
                 "snap_back_median", "snap_back_share")
N_SNAP = len(SNAP_FEATURES)
#: Length of the vector before the snap-back values: the per-frame values, window max, window
#: min, change (the layout of scorers trained before them).
N_BASE_FEATURES = 4 * N_FRAME
#: Length of a frame's feature vector: the base vector, the snap-back values and their window max.
N_FEATURES = N_BASE_FEATURES + 2 * N_SNAP
#: Names of the whole vector, in order.
FEATURE_NAMES = (*(f"{n}{s}" for s in ("", "_wmax", "_wmin", "_change") for n in FRAME_FEATURES),
                 *SNAP_FEATURES, *(f"{n}_wmax" for n in SNAP_FEATURES))
assert (N_FEATURES == _native.SLIP_N_FEATURES and N_FRAME == _native.SLIP_N_FRAME
        and N_SNAP == _native.SLIP_N_SNAP and N_BASE_FEATURES == _native.SLIP_N_BASE_FEATURES)


#: Marker pitch (px) assumed when the reference has fewer than two distinct markers.
FALLBACK_PITCH_PX = 30.0


def marker_pitch(points: Any) -> float:
    """The pitch (px) of reference marker centres, the unit of every length feature:
    :func:`tacswitch.estimate_pitch`, or :data:`FALLBACK_PITCH_PX` when it has none."""
    from tacswitch.tracking import estimate_pitch

    pitch = estimate_pitch(points) if len(points) >= 2 else None
    return float(pitch) if pitch else FALLBACK_PITCH_PX


class FieldFeatures:
    """Streaming features of one marker field, one :data:`N_FEATURES` vector per frame.

    Args:
        points: ``N x 2`` reference marker centres ``(x, y)``, pixels.
        pitch: marker pitch, pixels (the unit of every length feature).
        still_filter: read the motion through the still-marker hysteresis (module docstring):
            tracked markers; not motion predicted on a markerless sensor, whose still gel
            was never exactly still in training.
    """

    def __init__(self, points: Any, pitch: float, still_filter: bool = False) -> None:
        pts = as_points(points, "points")
        if not (isinstance(pitch, (int, float, np.floating, np.integer))
                and np.isfinite(pitch) and pitch > 0):
            raise ValueError(f"pitch: must be a finite number > 0; got {pitch!r}")
        self._native = _native.SlipFeatures(pts, float(pitch), bool(still_filter))
        self.n_markers = len(pts)
        self.still_filter = bool(still_filter)

    def update(self, motion: Any, valid: Any = None) -> NDArray[np.float32]:
        """Features of the next frame: ``motion`` ``N x 2`` px since the first frame (NaN rows
        are lost markers), ``valid`` ``N`` bool (default: rows without NaN)."""
        m = as_motion(motion, "motion")
        v = (~np.isnan(m).any(axis=1)) if valid is None else as_valid(valid, len(m))
        return self._native.update(m, np.ascontiguousarray(v, bool))

    def reset(self) -> None:
        """Forgets the history: the next frame is treated as the first."""
        self._native.reset()


def sequence_features(motions: Any, valids: Any, points: Any, pitch: float, *,
                      still_filter: bool = False) -> NDArray[np.float32]:
    """``T x N_FEATURES`` features of a tracked sequence (``T x N x 2`` motions since the first
    frame, ``T x N`` valid), frame by frame as the online detector computes them
    (``still_filter``: :class:`FieldFeatures`)."""
    ff = FieldFeatures(points, pitch, still_filter)
    rows = [ff.update(m, v) for m, v in zip(motions, valids, strict=True)]
    return np.stack(rows) if rows else np.zeros((0, N_FEATURES), np.float32)
