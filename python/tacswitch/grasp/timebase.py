"""The slip detector's time base: marker fields resampled to the frame rate its scorers read.

The learned slip rule reads how the marker field moves from frame to frame (velocities over 1
and 4 frames, accelerations, 8-frame windows) and the grasp phases count frames. Both were set
on real GelSight Mini grasps at 25 frames/s: the same grasp filmed at 50 frames/s moves its
markers half as far per frame, and at 12.5 frames/s twice as far. Measured with the shipped
marker committee on its real training grasps (seen in training, so a test of rate and not of
accuracy): balanced accuracy 0.954 at the recorded 25 frames/s, 0.899 with every second frame
dropped (12.5 frames/s) and 0.865 interpolated to 50 frames/s.

:class:`TimeBase` turns a stream at any frame rate into one at :data:`TRAINED_FPS`: each input
frame yields the time-base ticks that fall since the previous input frame (none, one or
several), each the linear interpolation of the two input frames around it. It is causal: a
tick is emitted when the input frame at or after it arrives, so nothing waits for the future.

The detector resamples only streams faster than the time base, beyond the 30 frames/s the
scorers also saw in training (:func:`needs_resampling`): there a tick falls between two frames
a short time apart, and a camera at twice the rate resampled is the 25 frames/s camera. A
slower stream would need frames made up between the real ones. Measured on the same grasps,
every 2nd / 3rd real frame (12.5 / 8.3 frames/s): resampled 0.931 / 0.854 against 0.899 /
0.872 read frame by frame; the interpolated frames spare every false alarm but miss 2-7 more
slips. So a slower stream is read as it comes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_number

#: Frame rate of the time base (frames/s): the real GelSight Mini grasps (25 frames/s) that the
#: shipped slip scorers and the grasp phases' frame counts were set on.
TRAINED_FPS = 25.0
#: Streams up to this many times the time base's rate are read frame by frame: the shipped
#: scorers were trained at 25 (the real grasps) and 30 frames/s (the rendered GelSight grasps),
#: and at 30 frames/s resampling changed one decision in 150 (BENCHMARKS.md).
NATIVE_RATIO = 1.25
#: Largest frame rate accepted (frames/s).
MAX_FPS = 10_000.0


def check_fps(fps: float | None, name: str = "fps") -> float | None:
    """``fps`` as a float (None stays None: the stream is taken to be at the time base);
    ``TypeError`` for a non-number, ``ValueError`` unless it is a rate in
    (0, :data:`MAX_FPS`], both naming ``name``."""
    if fps is None:
        return None
    try:
        v = as_number(fps, name, maximum=MAX_FPS)
    except ValueError:
        v = math.nan  # not finite, or too large: the message below says the range
    if not v > 0:
        raise ValueError(f"{name}: must be a frame rate in (0, {MAX_FPS:g}] frames/s; "
                         f"got {fps!r}")
    return v


def fps_from_stamps(stamps_ns: Sequence[int]) -> float | None:
    """A stream's frame rate (frames/s) from its frames' time stamps (ns):
    :func:`fps_from_intervals` of their differences."""
    # Differences in integers: ns stamps exceed a float's precision.
    stamps: NDArray[np.int64] = np.asarray(stamps_ns, np.int64)
    return fps_from_intervals(np.diff(stamps))


def fps_from_intervals(intervals_ns: Sequence[int] | NDArray[np.int64]) -> float | None:
    """A stream's frame rate (frames/s) from its frame intervals (ns): one over the median of
    the positive ones, which dropped frames and repeated stamps do not move; None with fewer
    than 5 such intervals or an implausible rate (outside (0, :data:`MAX_FPS`])."""
    gaps = np.asarray(intervals_ns, np.int64)
    gaps = gaps[gaps > 0]
    if len(gaps) < 5:
        return None
    fps = 1e9 / float(np.median(gaps))
    return fps if 0 < fps <= MAX_FPS else None


def needs_resampling(fps: float | None, target: float = TRAINED_FPS) -> bool:
    """Whether the detector resamples a stream at ``fps`` (None: unknown, taken as
    ``target``): only one faster than :data:`NATIVE_RATIO` times ``target``. A slower stream is
    read frame by frame: interpolating frames the camera never took smooths the motion it did
    see, and on the real grasps that lost as many slips as it spared false alarms (module
    doc)."""
    return fps is not None and fps > target * NATIVE_RATIO


class TimeBase:
    """Resamples a stream of marker fields at ``fps`` to ``target`` frames/s, causally.

    :meth:`push` takes each input frame's motion (``N x 2`` px) and valid flags (``N``) and
    returns the ticks of the time base up to that frame's time, as ``(tick, motion, valid)``:
    tick ``j`` is at ``j / target`` s, input frame ``k`` at ``k / fps`` s. A tick between two
    input frames is their linear interpolation, valid where both are; one on an input frame is
    that frame. Frame 0 is tick 0.
    """

    def __init__(self, fps: float, target: float = TRAINED_FPS) -> None:
        fps_v = check_fps(fps)
        target_v = check_fps(target, "target")
        assert fps_v is not None and target_v is not None
        #: Ticks per input frame.
        self.ratio = target_v / fps_v
        self.frame = -1
        self.next_tick = 0
        self._prev: tuple[NDArray[np.float32], NDArray[np.bool_]] | None = None

    def tick_time(self, tick: int) -> float:
        """Where tick ``tick`` falls, in input frames (fractional)."""
        return tick / self.ratio

    def frame_of(self, tick: int) -> int:
        """The input frame at which tick ``tick`` is emitted (the first at or after it)."""
        return max(0, math.ceil(self.tick_time(tick) - 1e-9))

    def push(self, motion: NDArray[np.float32], valid: NDArray[np.bool_]
             ) -> list[tuple[int, NDArray[np.float32], NDArray[np.bool_]]]:
        """The ticks up to the next input frame (see the class)."""
        self.frame += 1
        last = math.floor(self.frame * self.ratio + 1e-9)
        out = []
        for tick in range(self.next_tick, last + 1):
            w = self.tick_time(tick) - (self.frame - 1)  # in (0, 1] after frame 0
            if self._prev is None or w >= 1.0 - 1e-9:
                out.append((tick, motion, valid))
            else:
                pm, pv = self._prev
                out.append((tick, (pm + (motion - pm) * np.float32(w)).astype(np.float32),
                            pv & valid))
        self.next_tick = last + 1
        self._prev = (motion, valid)
        return out


def resample_field(motion: NDArray[np.floating], valid: NDArray[np.bool_], fps: float,
                   target: float = TRAINED_FPS
                   ) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """A whole tracked clip (``T x N x 2`` motions, ``T x N`` valid) at ``fps`` resampled to
    ``target`` frames/s, tick by tick as :class:`TimeBase` emits them online (the training
    data of a scorer is what the detector will see)."""
    tb = TimeBase(fps, target)
    m = np.asarray(motion, np.float32)
    v = np.asarray(valid, bool)
    ticks = [t for k in range(len(m)) for t in tb.push(m[k], v[k])]
    if not ticks:
        return m[:0], v[:0]
    return np.stack([t[1] for t in ticks]), np.stack([t[2] for t in ticks])
