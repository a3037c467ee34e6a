"""Slip detection from marker motion (Rust core): the paper's rule plus a rigid-motion criterion."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from tacswitch import _native
from tacswitch._checks import (
    as_count,
    as_image_u8,
    as_motion,
    as_number,
    as_points,
    as_valid,
    positive_or_none,
)
from tacswitch.tracking import MarkerTracker, check_tracker_options, is_frame_input

#: The paper's threshold (pixels) on 640-pixel-wide frames.
PAPER_THRESHOLD_PX = 3.25
#: ``rigid_threshold_px="auto"`` is this fraction of the displacement threshold.
RIGID_FRACTION = 0.5
PAPER_IMAGE_WIDTH = 640
#: ``smooth_frames`` for motion predicted from markerless frames (``tacswitch slip
#: --markerless`` and the markerless slip benchmarks): the mean of the last two motion fields.
#: Optical flow on a markerless gel carries camera noise that changes every frame; on simulated
#: Mini grasps (dev seeds 200) its largest per-marker motion on held grasps fell from 1.5-1.9 to
#: 1.25 px (threshold 1.625 px), false alarms 2/12 -> 0/12, for +1 frame of detection delay.
MARKERLESS_SMOOTH_FRAMES = 2


def _window_mean(history: deque[tuple[NDArray[np.float32], NDArray[np.bool_]]]
                 ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """Per-marker mean of the motion fields in ``history`` over the frames where the marker was
    valid; a marker is valid if it is valid in the newest frame."""
    total = np.zeros_like(history[-1][0], np.float64)
    count = np.zeros(len(total), np.int64)
    for m, v in history:
        ok = v & np.isfinite(m).all(axis=1)
        total[ok] += m[ok]
        count += ok
    valid = history[-1][1] & (count > 0)
    out = np.full(total.shape, np.nan, np.float32)
    out[valid] = (total[valid] / count[valid, None]).astype(np.float32)
    return out, valid


def scaled_threshold(image_width: int) -> float:
    """The paper's 3.25 px threshold scaled to an image width in pixels (1.625 px at 320)."""
    return PAPER_THRESHOLD_PX * image_width / PAPER_IMAGE_WIDTH


@dataclass(frozen=True)
class SlipState:
    """What one :meth:`SlipDetector.update` concluded.

    Attributes:
        slip: slip in this frame by any enabled criterion.
        by_displacement: the paper's rule fired (largest displacement since the first frame of the
            grasp above ``threshold_px``).
        by_rigid: the rigid criterion fired (contact markers deviate from one rigid motion).
        max_displacement: largest displacement since the first frame, pixels.
        marker: index (into the reference markers) of that marker, -1 if none.
        rigid_residual: largest deviation from the best-fit rigid motion, pixels; NaN if not
            evaluated (criterion off, or fewer than 3 markers in the contact set).
        rigid_marker: index of that marker, -1 if none.
        n_compared: markers valid both now and in the first frame.
        frame: frame index within the grasp (0 = first).
    """

    slip: bool
    by_displacement: bool
    by_rigid: bool
    max_displacement: float
    marker: int
    rigid_residual: float
    rigid_marker: int
    n_compared: int
    frame: int

    @property
    def criterion(self) -> str | None:
        """``"displacement"``, ``"rigid"``, ``"both"`` or None: which criterion fired."""
        if self.by_displacement and self.by_rigid:
            return "both"
        if self.by_displacement:
            return "displacement"
        if self.by_rigid:
            return "rigid"
        return None


class SlipDetector:
    """Streaming slip detector for one grasp at a time.

    Feed it, frame by frame, either images (markers are tracked internally, the first image is the
    no-contact reference) or motion fields from a tracker or from :func:`predict_motion` (so the
    same rule runs on a markerless sensor). The first frame after construction or :meth:`reset` is
    the start of the grasp; displacements are measured from it.

    Args:
        threshold_px: displacement threshold, pixels. Default: the paper's 3.25 px at 640-pixel
            width, scaled to ``image_width`` (or to the width of the first image fed).
        rigid_threshold_px: enables the rigid criterion with this threshold (pixels), or
            ``"auto"``: half the displacement threshold (``RIGID_FRACTION``). On simulated
            grasps (``benches/bench_slip_accuracy.py``) it keeps every slip and drops most false
            alarms of the displacement rule on vibrations, which move the contact rigidly.
        active_fraction: markers with at least this fraction of the largest displacement form the
            contact set fitted by the rigid criterion.
        points: reference marker centres ``N x 2`` (needed for the rigid criterion on motion input;
            taken from the tracker on image input).
        image_width: width in pixels used to scale the default threshold for motion input.
        use_displacement: set False to run the rigid criterion alone.
        smooth_frames: the rule sees the mean motion of the last ``smooth_frames`` frames of the
            grasp (1 = off, the default: the paper's rule on each frame). For motion predicted
            from markerless frames, whose noise changes every frame, use
            :data:`MARKERLESS_SMOOTH_FRAMES` (costs about one frame of delay).
        **tracker_opts: options of :class:`MarkerTracker` for image input.
    """

    def __init__(
        self,
        threshold_px: float | None = None,
        *,
        rigid_threshold_px: float | str | None = None,
        active_fraction: float = 0.5,
        points: Any = None,
        image_width: int | None = None,
        use_displacement: bool = True,
        smooth_frames: int = 1,
        **tracker_opts: Any,
    ):
        self._threshold = positive_or_none(threshold_px, "threshold_px")
        self._rigid_auto = isinstance(rigid_threshold_px, str)
        if self._rigid_auto and rigid_threshold_px != "auto":
            raise ValueError(f"rigid_threshold_px: a number of pixels or 'auto'; "
                             f"got {rigid_threshold_px!r}")
        # Not "auto" here, so not a str (``_rigid_auto`` is the isinstance check above).
        self._rigid = None if self._rigid_auto else positive_or_none(
            cast("float | None", rigid_threshold_px), "rigid_threshold_px")
        fraction = as_number(active_fraction, "active_fraction", 0.0, 1.0)
        if fraction == 0.0:
            raise ValueError(f"active_fraction: must be in (0, 1]; got {active_fraction!r}")
        self._active_fraction = fraction
        self._points = None if points is None else as_points(points, "points")
        self._image_width = None if image_width is None else as_count(
            image_width, "image_width", 1)
        if not isinstance(use_displacement, (bool, np.bool_)):
            raise TypeError(f"use_displacement: expected True or False; got "
                            f"{type(use_displacement).__name__}")
        self._use_displacement = bool(use_displacement)
        if not self._use_displacement and self._rigid is None and not self._rigid_auto:
            raise ValueError("use_displacement: False needs rigid_threshold_px, or nothing is "
                             "checked")
        self._smooth = as_count(smooth_frames, "smooth_frames", 1, 1000)
        self._history: deque[tuple[NDArray[np.float32], NDArray[np.bool_]]] = deque(
            maxlen=self._smooth)
        # Checked now, though only image input uses them: a typo is named, not ignored.
        check_tracker_options(tracker_opts, "SlipDetector", extra=("max_dist",))
        self._tracker_opts = tracker_opts
        self.tracker: MarkerTracker | None = None
        self._native: Any = None

    def _epsilon(self) -> float:
        """The displacement threshold ε: given, else the paper's scaled to the image width (the
        paper's own 3.25 px while no width is known)."""
        if self._threshold is not None:
            return self._threshold
        if self._image_width is not None:
            return scaled_threshold(self._image_width)
        return PAPER_THRESHOLD_PX

    @property
    def threshold_px(self) -> float | None:
        """Displacement threshold in force (pixels); None when that criterion is off."""
        return self._epsilon() if self._use_displacement else None

    @property
    def first_slip(self) -> int | None:
        """Frame index of the first slip in this grasp, or None."""
        return None if self._native is None else self._native.first_slip

    def reset(self) -> None:
        """Starts a new grasp: the next frame is the baseline (a tracker keeps its reference)."""
        self._history.clear()
        if self._native is not None:
            self._native.reset()

    def _ensure_native(self, points: Any) -> None:
        if self._native is not None:
            return
        # Fixed for the detector's life from the first frame on (its width is known by then).
        epsilon = self._threshold = self._epsilon()
        if self._rigid_auto:
            self._rigid = RIGID_FRACTION * epsilon
        self._native = _native.SlipDetector(
            epsilon if self._use_displacement else None, self._rigid, self._active_fraction,
            points if self._rigid is not None else None,
        )

    @property
    def rigid_threshold_px(self) -> float | None:
        """Rigid-criterion threshold in force (pixels); None when disabled (or, for ``"auto"``,
        before the first frame)."""
        return self._rigid

    def update(self, motion_or_img: Any, valid: Any = None) -> SlipState:
        """Feeds one frame and returns its :class:`SlipState`.

        Args:
            motion_or_img: a uint8 image (BGR or grey), or an ``N x 2`` motion field ``(dx, dy)``
                aligned with fixed reference markers (NaN rows = lost).
            valid: ``N`` bool flags for a motion field; default: rows without NaN.
        """
        if is_frame_input(motion_or_img):
            # Checked here so that the error names this argument, not the tracker's.
            motion_or_img = as_image_u8(motion_or_img, "motion_or_img")
            if self.tracker is None:
                self.tracker = MarkerTracker(motion_or_img, **self._tracker_opts)
                if self._image_width is None:
                    self._image_width = int(motion_or_img.shape[1])
            motion, valid_arr = self.tracker.update(motion_or_img)
            points: NDArray[np.float32] | None = self.tracker.reference
        else:
            motion = as_motion(motion_or_img, "motion_or_img")
            if valid is None:
                valid_arr = cast("NDArray[np.bool_]", ~np.isnan(motion).any(axis=1))
            else:
                valid_arr = as_valid(valid, motion.shape[0])
            points = self._points
            if (self._rigid is not None or self._rigid_auto) and points is None:
                raise ValueError("points: the rigid criterion on motion input needs the reference "
                                 "marker centres (SlipDetector(points=...))")
        self._ensure_native(points)
        if self._smooth > 1:
            if self._history and len(motion) != len(self._history[-1][0]):
                raise ValueError(f"motion_or_img: has {len(motion)} rows but earlier frames of "
                                 f"this grasp had {len(self._history[-1][0])}; call reset() "
                                 "for a new grasp")
            # Copies: a tracker may hand back buffers it reuses next frame.
            self._history.append((np.array(motion, np.float32), np.array(valid_arr, bool)))
            motion, valid_arr = _window_mean(self._history)
        st = self._native.update(motion, valid_arr)
        return SlipState(**st)

