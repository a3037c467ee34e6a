"""Where a grasp starts in a recording: contact onset and the established contact.

The slip rule measures marker displacement since the start of the grasp, the frame where the
contact is *established* (the paper's baseline). A recording usually begins before that: no
contact, then a press that moves the markers by several pixels. Taking frame 0 as the start
flags the whole press and hold as slip. :class:`GraspSegmenter` reads the marker motion field
of each frame (measured from the first frame, which shows no contact; with
``first_frame_rest``, since the first frame whatever motion it carries) and finds:

- **contact onset**: the markers leave their rest positions, i.e. the motion statistic ``m``
  (the k-th largest marker displacement since the first frame, k = 2 % of the markers, at least
  2, so one mistracked marker does not count) rises by more than ``ON_FRACTION`` of the slip
  threshold, and twice the tracker's frame-to-frame jitter without contact (a jittering
  tracker moves ``m`` about as much as one frame's jitter; a press accumulates), within the
  last :data:`ONSET_WINDOW` frames, for :data:`ON_FRAMES` frames in a row (a slow drift of the
  field without contact is not a press);
- **established contact** (the grasp start): the first frame after onset where the markers stop
  moving, i.e. the per-frame motion statistic ``v`` (the same k-th largest, of the motion since
  the previous frame) falls below ``SETTLE_FRACTION`` of the slip threshold (or 3x the
  no-contact jitter): at that speed the contact would need ten frames to cover the threshold.
  A contact that keeps moving for ``max_wait`` frames starts anyway (a grasp that slips while
  it is being pressed is still evaluated);
- **release**: ``m`` falls back below the onset level for :data:`ON_FRAMES` frames; the next
  onset starts a new grasp.

The fractions are defined relative to the slip threshold (so they scale with the frame width
like the rule itself), not fitted to a data set. A recording that starts in contact has no
onset to find: the motion stays near zero and the grasp starts at the first frame where the
markers move and settle, or never; pass an explicit start (``--start``) for such recordings.
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Onset: the motion statistic above this fraction of the slip threshold ...
ON_FRACTION = 0.25
#: ... for this many frames in a row (one glitch is not a contact).
ON_FRAMES = 2
#: ... risen by that much within this many frames (1 s at 25 frames/s). Without contact the
#: tracked field of a real GelSight Mini drifts: on the real slip recordings the statistic
#: creeps from 0.1 to 0.47 px over the 300 frames before a grasp (baseball 1), which crossed the
#: onset level long before the contact and opened a "grasp" there (the paper rule then called
#: the press itself a slip). A press rises within a second. Measured from the first frame
#: instead, 110 of the 300 videos had their onset more than a second before the median marker
#: moved 0.5 px, 89 with the window (the rest are light contacts); the shipped marker committee
#: makes the same decision on every one of the 150 experiments either way.
ONSET_WINDOW = 25
#: Established: per-frame motion below this fraction of the slip threshold.
SETTLE_FRACTION = 0.1
#: The release: the markers back within this fraction of the onset level for ``ON_FRAMES``
#: frames. Below 1, a hysteresis: a faint imprint that holds the motion statistic near the
#: onset level no longer opens and closes a grasp every few frames (on the real GelSight Mini
#: slip recordings, 53 of 300 videos opened more than 5 "grasps", one 112 in 450 frames; at 0.5
#: one video does), and a grasp's committee votes are not reset mid-grasp (objects held out,
#: four seed sets of 8-member committees: balanced accuracy +0.009 to +0.031; BENCHMARKS.md).
OFF_FRACTION = 0.5
#: No-contact frames whose jitter sets the levels (the latest; 10 s at 25 frames/s).
NOISE_FRAMES = 250

NO_CONTACT, PRESSING, GRASP, BEFORE_START = "no contact", "pressing", "grasp", "before start"


def top_statistic(values: NDArray[np.floating]) -> float:
    """The k-th largest of ``values`` (k = 2 % of them, at least 2; the smallest if fewer):
    a motion that a few markers share, robust to one mistracked marker. 0 for no values."""
    v = np.asarray(values, np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0
    k = min(max(2, int(np.ceil(0.02 * v.size))), v.size)
    return float(np.partition(v, v.size - k)[v.size - k])


class RollingMedian:
    """Median of the last ``size`` values, updated in O(size) without sorting per read: a FIFO
    of the values and the same values kept sorted (the slip loop asks for it every frame)."""

    def __init__(self, size: int) -> None:
        self._fifo: deque[float] = deque()
        self._sorted: list[float] = []
        self.size = int(size)

    def __len__(self) -> int:
        return len(self._fifo)

    def append(self, value: float) -> None:
        if len(self._fifo) == self.size:
            old = self._fifo.popleft()
            del self._sorted[bisect.bisect_left(self._sorted, old)]
        self._fifo.append(value)
        bisect.insort(self._sorted, value)

    def median(self, extra: float | None = None) -> float:
        """Median of the window (and ``extra`` when given, without keeping it); 0 if empty.
        NaN values are not expected (the motion statistics are finite)."""
        v = self._sorted
        if extra is not None:
            v = v.copy()
            bisect.insort(v, extra)
        n = len(v)
        if n == 0:
            return 0.0
        return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


@dataclass(frozen=True)
class Step:
    """What :meth:`GraspSegmenter.update` concluded for one frame.

    Attributes:
        phase: ``"no contact"``, ``"pressing"`` (onset seen, not settled), ``"grasp"`` or
            ``"before start"`` (an explicit start not reached yet).
        starts: this frame is the start of a grasp (the slip rule's baseline).
        grasp: 1-based number of the current grasp, 0 before the first.
        start: frame index where the current grasp started, None outside a grasp.
        onset: frame index of the current contact's onset, None if not detected.
        moving: the motion statistic since the first frame, px.
        speed: the per-frame motion statistic, px.
    """

    phase: str
    starts: bool
    grasp: int
    start: int | None
    onset: int | None
    moving: float
    speed: float


class GraspSegmenter:
    """Contact onset, grasp start and release from a stream of marker motion fields.

    Args:
        threshold_px: the slip rule's displacement threshold, px (the levels scale with it).
        start: an explicit grasp start (frame index): no detection, the grasp starts there and
            lasts to the end.
        max_wait: frames after onset after which a contact that is still moving starts the
            grasp anyway.
        first_frame_rest: the first frame fed is the gel at rest whatever motion it carries:
            every field is read minus the first one. For a :class:`tacswitch.MarkerlessTracker`
            started without a no-contact frame, which gives its first frame the mechanics
            rule's motion (0.4-0.5 px of the k-th largest on real GelSight Mini frames without
            contact: above the onset level from the first frame, a grasp opened at frame 0 on
            most of the real slip recordings). Off (default): motion measured from a separate
            no-contact frame, where a contact from the first frame is seen at once.
    """

    def __init__(self, threshold_px: float, *, start: int | None = None,
                 max_wait: int = 30, first_frame_rest: bool = False) -> None:
        if not threshold_px > 0:
            raise ValueError(f"threshold_px: must be > 0; got {threshold_px!r}")
        if start is not None and start < 0:
            raise ValueError(f"start: must be >= 0; got {start}")
        self.threshold_px = float(threshold_px)
        self.fixed_start = start
        self.max_wait = max(1, int(max_wait))
        self.frame = -1
        self.phase = NO_CONTACT if start is None else BEFORE_START
        self.grasp = 0
        self.start: int | None = None
        self.onset: int | None = None
        self._above = 0  # frames in a row above the onset level (no contact) or below it (grasp)
        # Per-frame motion statistics without contact: the last NOISE_FRAMES of them, so a
        # long stream costs the same per frame.
        self._noise_v = RollingMedian(NOISE_FRAMES)
        self._prev: NDArray[np.float64] | None = None
        self.first_frame_rest = bool(first_frame_rest)
        # With first_frame_rest, the first frame's field, subtracted from every field.
        self._origin: NDArray[np.float64] | None = None
        # The motion statistic of the last ONSET_WINDOW frames without contact (below the
        # onset level): the onset is the rise over them.
        self._recent: deque[float] = deque(maxlen=ONSET_WINDOW)

    def _jitter(self, extra: float | None = None) -> float:
        """Median per-frame motion statistic of the no-contact frames (and ``extra``), px."""
        return self._noise_v.median(extra)

    @property
    def on_level(self) -> float:
        """The onset level, px: ``ON_FRACTION`` of the threshold, or twice the no-contact
        jitter."""
        return max(ON_FRACTION * self.threshold_px, 2.0 * self._jitter())

    @property
    def settle_level(self) -> float:
        """The settling speed, px per frame: ``SETTLE_FRACTION`` of the threshold, or 3x the
        no-contact per-frame noise."""
        return max(SETTLE_FRACTION * self.threshold_px, 3.0 * self._jitter())

    def update(self, motion: NDArray[np.floating], valid: NDArray[np.bool_]) -> Step:
        """Feeds the motion field of the next frame (``N x 2`` px since the first frame, and
        its ``N`` valid flags) and returns the frame's :class:`Step`."""
        self.frame += 1
        t = self.frame
        mv = np.where(np.asarray(valid, bool)[:, None], np.asarray(motion, np.float64), np.nan)
        if self.first_frame_rest:
            if t == 0:
                origin = np.nan_to_num(mv)
                # A field that starts at zero (tracked markers) needs no subtraction.
                self._origin = origin if origin.any() else None
            if self._origin is not None:
                mv = mv - self._origin
        moving = top_statistic(np.hypot(mv[:, 0], mv[:, 1]))
        speed = 0.0 if self._prev is None else top_statistic(
            np.hypot(*(mv - self._prev).T))
        self._prev = mv
        starts = False
        if self.fixed_start is not None:
            if t == self.fixed_start:
                self.phase, self.grasp, self.start, starts = GRASP, 1, t, True
        elif self.phase == NO_CONTACT:
            # This frame's own speed counts towards the jitter: without a lead-in, the first
            # frames of a press are judged against each other, not against nothing.
            level = max(ON_FRACTION * self.threshold_px,
                        2.0 * self._jitter(speed if t > 0 else None))
            # The rise over the recent frames without contact (those already rising past the
            # level are not the baseline).
            rise = moving - min(self._recent) if self._recent else moving
            if rise > level:
                self._above += 1
                if self._above >= ON_FRAMES:
                    self.phase, self.onset, self._above = PRESSING, t - ON_FRAMES + 1, 0
                    self._recent.clear()
            else:
                self._above = 0
                self._recent.append(moving)
                if t > 0:
                    self._noise_v.append(speed)
        if self.fixed_start is None and self.phase == PRESSING and (
                speed < self.settle_level
                or t - (t if self.onset is None else self.onset) >= self.max_wait):
            self.phase, self.start, starts = GRASP, t, True
            self.grasp += 1
        elif self.fixed_start is None and self.phase == GRASP and not starts:
            self._above = self._above + 1 if moving <= OFF_FRACTION * self.on_level else 0
            if self._above >= ON_FRAMES:  # released: back to no contact, a new grasp may come
                self.phase, self.start, self.onset, self._above = NO_CONTACT, None, None, 0
        return Step(self.phase, starts, self.grasp, self.start, self.onset, moving, speed)
