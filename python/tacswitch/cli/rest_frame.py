"""The rest (reference) frame of a marker stream: the first frame, unless it is unusable.

``tacswitch track`` and ``tacswitch slip`` measure every frame's marker motion from a rest
frame, the frame whose markers are the reference. A recording may start on a frame that cannot
serve: a blank frame while the camera settles, or a frame where few markers are found (motion
blur, a textured object in contact), or a frame from before the camera settled: under-exposed,
or left in its buffer from before the recording (:func:`tacswitch.tracking.settled_index`: a
jump of the whole image between still frames, early in the stream). Tracking against it would
stop (no marker), lose most markers for the whole recording, or offset every motion by the
jump. So the first :data:`LOOK_AHEAD` readable frames are read ahead, counted and compared,
and the rest frame is the first of them, from the settled one on, whose marker count reaches
:data:`USABLE_FRACTION` of the most any of them shows: frame 0 whenever it is settled and
usable, the recording's own timing otherwise. Frames before it are not tracked. Only when none
of them shows a marker does the command stop, with one line naming the source.

The frames read ahead are replayed unchanged, so the commands see the same stream (and the same
frame numbers) as without the look-ahead; a camera is read ahead by about one second.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from tacswitch.tracking import (
    REST_LOOK_AHEAD,
    REST_USABLE_FRACTION,
    lattice_irregularity,
    rest_thumbnail,
    settled_index,
    usable_rest_frame,
)

#: The look-ahead and the usable fraction: :mod:`tacswitch.tracking`'s rest-frame rule (shared
#: with the ROS processor). Module globals here so a test can shorten the look-ahead.
LOOK_AHEAD = REST_LOOK_AHEAD
USABLE_FRACTION = REST_USABLE_FRACTION


@dataclass(frozen=True)
class RestFrame:
    """The chosen rest frame. Frame numbers count the stream's readable frames from 0, as the
    commands' logs do.

    Attributes:
        index: the rest frame.
        markers: markers found on it.
        first: markers found on frame 0.
        best: the most markers found on a frame of the look-ahead ...
        best_index: ... on this frame (the first with that many).
        looked: readable frames looked at (at most the look-ahead).
        settled: the first frame after the camera settled
            (:func:`tacswitch.tracking.settled_index`).
    """

    index: int
    markers: int
    first: int
    best: int
    best_index: int
    looked: int
    settled: int = 0
    #: False when markers were not counted (a markerless stream: only the settling decides).
    counted: bool = True

    def message(self) -> str:
        """Which frame is the rest frame and why, one line (for a rest frame after frame 0)."""
        skipped = ("frame 0 is" if self.index == 1 else f"frames 0-{self.index - 1} are")
        if 0 < self.settled <= self.index and self.first >= USABLE_FRACTION * self.best:
            before = "frame 0 comes" if self.settled == 1 else (
                f"frames 0-{self.settled - 1} come")
            found = f" ({self.markers} markers)" if self.counted else ""
            return (f"source: {before} before the camera settled (exposure changing, or "
                    f"frames left from before: a jump of the whole image, or a deformed gel "
                    f"relaxing, up to frame {self.settled}), so frame {self.index} "
                    f"is the rest frame{found}; {skipped} not tracked")
        shows = "no markers" if self.first == 0 else f"only {self.first} markers"
        return (f"source: frame 0 shows {shows}, so frame {self.index} is the rest frame "
                f"({self.markers} markers; the first of frames 0-{self.looked - 1} with at "
                f"least {USABLE_FRACTION:.0%} of the most found, {self.best} on frame "
                f"{self.best_index}); {skipped} not tracked")


def choose_rest_frame(stream: Iterable[np.ndarray | None],
                      count: Callable[[np.ndarray], int | np.ndarray] | None,
                      *, source: str, max_frames: int | None = None, hint: str = ""
                      ) -> tuple[RestFrame | None, Iterator[np.ndarray | None]]:
    """Reads up to :data:`LOOK_AHEAD` readable frames of ``stream`` ahead (at most
    ``max_frames``) and picks the first usable one as the rest frame.

    Args:
        stream: frames, None for an unreadable one (:func:`tacswitch.cli.sources.frames`).
        count: markers found on a frame (the command's own extraction options): their number,
            or their ``N x 2`` centres, which also lets a stale start that fades into a more
            regular marker lattice be skipped (:func:`tacswitch.tracking.settled_index`); None
            for a markerless stream (the first settled frame is the rest frame).
        source: the source as the user named it (for the error).
        max_frames: the command's ``--max-frames`` (frames past it are never tracked).
        hint: appended to the error (e.g. ``"; check --polarity"``).

    Returns:
        ``(rest, frames)``: the :class:`RestFrame` (None when the stream has no readable frame:
        the caller reports that as it always did) and the whole stream again, the frames read
        ahead first. An error the stream raised while read ahead (a camera that stops) is
        raised again where it happened, after the frames read before it.

    Raises:
        ValueError: none of the frames looked at shows a marker (names ``source``).
    """
    look_ahead = LOOK_AHEAD if max_frames is None else max(1, min(LOOK_AHEAD, max_frames))
    it = iter(stream)
    end = object()
    buffer: list[np.ndarray | None] = []
    counts: list[int] = []
    thumbs: list[np.ndarray] = []
    irregular: list[float] = []
    error: Exception | None = None
    try:
        while len(counts) < look_ahead:
            item = next(it, end)
            if item is end:
                break
            frame: np.ndarray | None = item  # type: ignore[assignment]
            buffer.append(frame)
            if frame is not None:
                found = 1 if count is None else count(frame)
                if isinstance(found, np.ndarray):
                    counts.append(len(found))
                    irregular.append(lattice_irregularity(found))
                else:
                    counts.append(int(found))
                thumbs.append(rest_thumbnail(frame))
    except Exception as exc:  # replayed where it happened (a disconnected camera, ...)
        if not counts:
            raise
        error = exc
    rest = None
    if counts:
        settled = settled_index(thumbs, irregular if len(irregular) == len(thumbs) else None)
        index = usable_rest_frame(counts, USABLE_FRACTION, settled)
        if index is None:
            if error is not None:
                raise error
            after = (f" nor in the {len(counts) - 1} after it" if len(counts) > 1 else "")
            raise ValueError(f"source: no markers found in the first frame of {source!r}{after} "
                             f"(a blank or markerless recording?){hint}")
        best = max(counts)
        rest = RestFrame(index, counts[index], counts[0], best, counts.index(best), len(counts),
                         settled, count is not None)
    return rest, _replay(buffer, error, it)


def _replay(buffer: list[np.ndarray | None], error: Exception | None,
            rest: Iterator[np.ndarray | None]) -> Iterator[np.ndarray | None]:
    yield from buffer
    if error is not None:
        raise error
    yield from rest
