"""Marker matching and tracking (Rust core)."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any, Literal, overload

import numpy as np
from numpy.typing import NDArray

from tacswitch import _native
from tacswitch._checks import as_image_u8, as_points, check_extract_options, positive_or_none
from tacswitch.markers import extract_markers

Motion = NDArray[np.float32]
Valid = NDArray[np.bool_]


#: Frames looked at for a stream's rest (reference) frame: about a second of a 30 frames/s
#: camera (``tacswitch track`` / ``slip``, :mod:`tacswitch.cli.rest_frame`; the ROS processor).
REST_LOOK_AHEAD = 30
#: A frame is usable as the rest frame when it shows at least this fraction of the largest
#: marker count of the look-ahead. Half: a frame that shows fewer has lost markers to a blank
#: image, blur or the contact, not to the small frame-to-frame changes of extraction; a higher
#: fraction would skip more of a recording's start (its contact onset) for a few markers. On
#: the 300 real GelSight Mini slip training recordings the first frame shows at least 0.81 of
#: the best count of their first 30 frames (no rest frame moves); with the extraction before
#: issue #35, 11 showed less than half (e.g. 0 markers, then frame 5 with 25 of 41).
REST_USABLE_FRACTION = 0.5


#: A camera that has just started may deliver, before the current image, frames that are not
#: the gel's state now: under-exposed frames while the exposure settles, and frames left in its
#: buffer from before (on the real GelSight Mini slip recordings: frame 0 about 30 % darker
#: than frame 2 in 56 of 300 videos, and in 33 a jump of the whole image at frame 5 between
#: still frames, the gel at rest after it and deformed before it). A rest frame taken there
#: offsets every later motion by the jump (6-12 px) and opens a "grasp" before any contact.
#: Jumps are looked for in this many first frames (stale buffers are short; later, a sudden
#: change is the scene's).
REST_STALE_FRAMES = 10
#: A jump: the mean absolute grey-level change of a frame's thumbnail (0-255) above this ...
REST_JUMP_GREY = 2.0
#: ... and this many times the change of each neighbouring frame (a press builds up over
#: frames; a stale buffer ends in one).
REST_JUMP_ISOLATION = 4.0
#: Exposure still settling: the thumbnail's mean differs from the next frame's by more than
#: this fraction.
REST_EXPOSURE_STEP = 0.05
#: Thumbnail size (width, height) px for the settling test: the whole image's change, not its
#: texture or the camera's noise.
REST_THUMBNAIL = (80, 60)
#: A stale start that fades instead of jumping: on the real GelSight Mini slip recordings some
#: videos open on the gel still deformed by the previous grasp (smeared markers, an imprint),
#: relaxing to rest over 2-5 frames (changes of 2-6 grey levels a frame, then under 1) with no
#: jump. Such a run among the first :data:`REST_STALE_FRAMES` frames, followed by this many
#: still frames, ...
REST_RELAX_STILL_FRAMES = 5
#: ... each changing by less than :data:`REST_JUMP_GREY` and by at most this in the median (a
#: still gel's thumbnail changes by 0.1-0.4 grey levels a frame in those MPEG-4 videos) ...
REST_RELAX_STILL_GREY = 0.5
#: ... ends the stale frames when the marker lattice after it is at least this much more regular
#: (:func:`lattice_irregularity`) than at the first frame: a gel relaxing to rest. A press at a
#: recording's start does the opposite (the load compresses and stretches the lattice: on 31
#: real contact onsets the loaded lattice was 0.86-1.96x as irregular as before; the relaxed
#: lattices of the stale starts 1.3-2.5x less), so a recording that starts with a press keeps
#: its first frame.
REST_RELAX_REGULARITY = 1.25


def rest_thumbnail(frame: Any) -> NDArray[np.float32]:
    """Grey thumbnail of a frame (``H x W`` grey or ``H x W x 3`` BGR uint8) for
    :func:`settled_index`: :data:`REST_THUMBNAIL` px, area-averaged, float32 grey levels."""
    import cv2

    img = as_image_u8(frame, "frame")
    grey = img if img.ndim == 2 else cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2GRAY)
    return np.asarray(cv2.resize(grey, REST_THUMBNAIL, interpolation=cv2.INTER_AREA),
                      np.float32)


def _content_change(a: NDArray[np.float32], mean_a: float, b: NDArray[np.float32],
                    mean_b: float) -> float:
    """Mean absolute grey-level change between two thumbnails once each is scaled to their
    common mean grey (a pure gain change reads 0)."""
    if min(mean_a, mean_b) <= 1.0:  # a black frame: no gain to take out
        return float(np.mean(np.abs(b - a)))
    common = 0.5 * (mean_a + mean_b)
    return float(np.mean(np.abs(b * (common / mean_b) - a * (common / mean_a))))


def _isolated_jump(change: Sequence[float], j: int) -> bool:
    """Frame ``j``'s change is a jump: above :data:`REST_JUMP_GREY` and
    :data:`REST_JUMP_ISOLATION` times each neighbouring frame's. The frame after it must have
    been seen: a stale buffer ends in a jump *between* still frames, and a change on the last
    frame looked at (a press as a short sequence ends) cannot show that."""
    if j + 1 >= len(change):
        return False
    around = [change[k] for k in (j - 1, j + 1) if 1 <= k < len(change)]
    return change[j] > REST_JUMP_GREY and change[j] > REST_JUMP_ISOLATION * max(around)


def lattice_irregularity(centres: Any) -> float:
    """How irregular a marker lattice is: the median absolute deviation of the distances from
    each marker to its neighbours (up to 4 nearest, within 1.5x the median nearest spacing), over
    their median. About 0.01-0.03 on a gel at rest (lens distortion, extraction noise); a load
    compresses and stretches the lattice and smeared stale frames scatter it. ``centres``:
    ``N x 2`` ``(x, y)`` px. NaN for fewer than 8 markers."""
    c = np.asarray(centres, np.float64).reshape(-1, 2)
    c = c[np.isfinite(c).all(axis=1)]
    if len(c) < 8:
        return float("nan")
    # The 4 nearest of every marker (of at most 512 evenly spread ones: a median needs no more),
    # a block of rows at a time, so a frame of thousands of found blobs stays cheap.
    rows = np.linspace(0, len(c) - 1, min(len(c), 512)).round().astype(int)
    near = np.empty((len(rows), 4))
    for lo in range(0, len(rows), 128):
        idx = rows[lo:lo + 128]
        d2 = np.sum((c[idx, None, :] - c[None, :, :]) ** 2, axis=2)
        d2[np.arange(len(idx)), idx] = np.inf
        near[lo:lo + len(idx)] = np.sqrt(np.partition(d2, 3, axis=1)[:, :4])
    spacing = float(np.median(near.min(axis=1)))
    d = near[near < 1.5 * spacing]
    mid = float(np.median(d))
    return float(np.median(np.abs(d - mid)) / mid) if mid > 0 else float("nan")


def _relaxed_start(raw: Sequence[float], irregularity: Sequence[float], start: int) -> int:
    """The frame ending a stale start that fades (:data:`REST_RELAX_STILL_FRAMES`), or
    ``start``."""
    changing = [j for j in range(start + 1, min(len(raw), start + REST_STALE_FRAMES + 1))
                if raw[j] > REST_JUMP_GREY]
    if not changing:
        return start
    end = changing[-1]
    still = raw[end + 1:end + 1 + REST_RELAX_STILL_FRAMES]
    if (len(still) < REST_RELAX_STILL_FRAMES or max(still) >= REST_JUMP_GREY
            or float(np.median(still)) > REST_RELAX_STILL_GREY):
        return start
    before, after = irregularity[start], irregularity[end]
    return end if before > REST_RELAX_REGULARITY * after else start  # NaN: keeps start


def settled_index(thumbs: Sequence[NDArray[np.float32]],
                  irregularity: Sequence[float] | None = None) -> int:
    """Index of the first frame of a stream's start that shows the gel as it is now (see
    :data:`REST_STALE_FRAMES`): after the last isolated jump among the first
    :data:`REST_STALE_FRAMES` frames (of the image, or of its content with the brightness
    taken out), and past the frames whose exposure is still changing by more than
    :data:`REST_EXPOSURE_STEP` a frame (unless it changes that much to the last frame: a
    flickering light). ``thumbs``: :func:`rest_thumbnail` of the
    first frames, in order. 0 for a stream that starts settled (or has one frame).
    ``irregularity``: :func:`lattice_irregularity` of the same frames' markers (a marker
    sensor): a stale start that fades over a few frames into a more regular lattice is skipped
    too (:data:`REST_RELAX_STILL_FRAMES`)."""
    n = len(thumbs)
    if irregularity is not None and len(irregularity) != n:
        raise ValueError(f"irregularity: one value per thumbnail ({n}); got {len(irregularity)}")
    means = [float(np.mean(t)) for t in thumbs]
    # Jumps of the image as it is, and of its content alone (each thumbnail scaled to the pair's
    # mean grey): under a flickering light every frame changes in brightness, which hides the
    # one isolated jump from the first test but not from the second.
    raw = [0.0] + [float(np.mean(np.abs(thumbs[j] - thumbs[j - 1]))) for j in range(1, n)]
    content = [0.0] + [_content_change(thumbs[j - 1], means[j - 1], thumbs[j], means[j])
                       for j in range(1, n)]
    start = 0
    for j in range(1, min(n, REST_STALE_FRAMES + 1)):
        if _isolated_jump(raw, j) or _isolated_jump(content, j):
            start = j
    settled = start
    while settled < n - 1 and abs(means[settled] - means[settled + 1]) > (
            REST_EXPOSURE_STEP * max(means[settled + 1], 1.0)):
        settled += 1
    # Brightness that keeps changing to the end of the frames looked at is a flickering light,
    # not an exposure settling: the frames are not skipped for it.
    settled = start if settled == n - 1 and n > 2 else settled
    if irregularity is not None:
        settled = _relaxed_start(raw, irregularity, settled)
    return settled


def usable_rest_frame(counts: Sequence[int], fraction: float = REST_USABLE_FRACTION,
                      start: int = 0) -> int | None:
    """Index of the rest frame among frames with these marker ``counts``: the first from
    ``start`` on (:func:`settled_index`) showing a marker and at least ``fraction`` of the
    largest count; before ``start`` only when no later frame qualifies; None when none shows
    a marker."""
    best = max(counts, default=0)
    if best <= 0:
        return None
    usable = [i for i, c in enumerate(counts) if c > 0 and c >= fraction * best]
    return next((i for i in usable if i >= start), usable[0])


def estimate_pitch(points: Any) -> float | None:
    """Marker pitch of a point set: the median nearest-neighbour distance, pixels.

    Duplicated points are ignored. Returns None with fewer than two distinct points (no
    distance exists); otherwise a finite float, computed in float64, so two points ``1e20``
    or even ``6e38`` apart give that distance. The median runs over up to 32 evenly spaced
    points, each one's nearest distinct neighbour found in a 2-d tree (``O(N log N)``).
    """
    return _native.estimate_pitch(as_points(points, "points"))


@overload
def match_markers(ref_pts: Any, cur_pts: Any, max_dist: float | None = None, *,
                  return_index: Literal[False] = False) -> tuple[Motion, Valid]: ...
@overload
def match_markers(ref_pts: Any, cur_pts: Any, max_dist: float | None = None, *,
                  return_index: Literal[True]) -> tuple[Motion, Valid, NDArray[np.int64]]: ...
def match_markers(
    ref_pts: Any,
    cur_pts: Any,
    max_dist: float | None = None,
    *,
    return_index: bool = False,
) -> tuple[Motion, Valid] | tuple[Motion, Valid, NDArray[np.int64]]:
    """Matches current marker centres to reference centres by mutual nearest neighbour.

    Reference ``i`` and current ``j`` match when each is the other's nearest neighbour and they lie
    at most ``max_dist`` apart. A reference marker whose nearest detection belongs to another marker
    stays unmatched (NaN, ``valid=False``): a lost marker never borrows a neighbour's detection.
    Equivalent to ``scipy.spatial.cKDTree`` queries both ways with a mutual check and a gate
    (ties go to the lowest index, so duplicated points match at most once);
    ``O((N + M) log(N + M))`` for any layout, duplicates included. A pair whose motion
    overflows float32 (coordinates near ``+-3.4e38`` on opposite sides) is left unmatched
    rather than given an infinite motion.
    For displacements beyond half the pitch use :class:`MarkerTracker`.

    Args:
        ref_pts: ``N x 2`` reference centres ``(x, y)``, pixels.
        cur_pts: ``M x 2`` current centres ``(x, y)``, pixels.
        max_dist: gate in pixels; default half the pitch estimated from ``ref_pts`` (no gate when
            the pitch cannot be estimated, i.e. fewer than two distinct reference points).
        return_index: also return, per reference marker, the index of its match in ``cur_pts``
            (``-1`` when unmatched).

    Returns:
        ``(motion, valid)``: ``N x 2`` float32 ``(dx, dy)`` = current - reference (NaN where
        unmatched) and ``N`` bool; plus ``index`` when ``return_index``.

    Raises:
        ValueError: bad shapes, NaN/Inf coordinates or a non-positive ``max_dist``.
    """
    # The native call checks for NaN/Inf and names the argument.
    ref = as_points(ref_pts, "ref_pts", check_finite=False)
    cur = as_points(cur_pts, "cur_pts", check_finite=False)
    gate = positive_or_none(max_dist, "max_dist")
    motion, valid, index, _ = _native.match_markers(ref, cur, gate)
    if return_index:
        return motion, valid, index
    return motion, valid


def is_frame_input(x: Any) -> bool:
    """A frame rather than points: any uint8 array, or one shaped like a frame (colour, or grey
    at least 8 px a side), so that a float or 16-bit frame gets the image check's dtype error
    rather than a points error."""
    if not isinstance(x, np.ndarray):
        return False
    return (x.dtype == np.uint8 or (x.ndim == 3 and x.shape[2] in (1, 3, 4))
            or (x.ndim == 2 and min(x.shape) >= 8))


#: Marker extraction options a :class:`MarkerTracker` accepts (``**extract_opts``).
TRACKER_OPTIONS = frozenset({"polarity", "block_size", "threshold", "min_area", "max_area",
                             "min_fill", "max_aspect", "exclude_border"})


def check_tracker_options(opts: dict[str, Any], owner: str = "MarkerTracker", *,
                          extra: tuple[str, ...] = ()) -> dict[str, Any]:
    """``opts`` checked as :class:`MarkerTracker` extraction options (and the ``extra`` names
    the owner passes on unchecked): ``TypeError`` naming an unknown one (a typo would otherwise
    be ignored), else the checked extraction values."""
    allowed = TRACKER_OPTIONS | set(extra)
    unknown = set(opts) - allowed
    if unknown:
        raise TypeError(f"{owner}: unknown option(s) {sorted(unknown)}; "
                        f"allowed: {sorted(allowed)}")
    return check_extract_options({k: v for k, v in opts.items() if k not in extra})


class MarkerTracker:
    """Follows markers frame to frame against a fixed reference.

    Each frame's detections are matched to where every marker is predicted to be: its last tracked
    position, or, for a marker lost earlier, its reference position moved by the median motion of
    its tracked neighbours (so lost markers are re-acquired). The per-frame gate is half the marker
    pitch, so displacements of a whole pitch or more (real presses reach 30-42 px) are followed as
    long as one frame moves less than half a pitch.

    Args:
        ref_img_or_pts: the no-contact reference: a uint8 image (markers are extracted from it) or
            ``N x 2`` float ``(x, y)`` centres.
        max_dist: per-frame gate, pixels; default half the reference pitch.
        **extract_opts: options of :func:`extract_markers` used on every image (``polarity``,
            ``block_size``, ``threshold``, ``min_area``, ``max_area``, ``min_fill``,
            ``max_aspect``, ``exclude_border``).

    Cost: construction ``O(N log N)`` (each marker's 6 nearest neighbours from a 2-d tree), each
    frame ``O((N + M) log(N + M))``, memory ``O(N + M)`` (``BENCHMARKS.md``, "Tracker scaling").

    Threads: one tracker may be shared between threads; calls are serialised by a lock (a frame
    is tracked against the state the previous call left, so feed frames in order from one
    thread if the order matters). Use one tracker per stream for parallelism.

    Example:
        >>> tracker = MarkerTracker(ref_frame)              # doctest: +SKIP
        >>> motion, valid = tracker.update(frame)           # doctest: +SKIP
    """

    def __init__(self, ref_img_or_pts: Any, max_dist: float | None = None, **extract_opts: Any):
        extract_opts = check_tracker_options(extract_opts)
        # The native tracker is mutably borrowed during a call (with the GIL released), so a
        # second thread would get "Already borrowed": serialise calls instead.
        self._lock = threading.Lock()
        if is_frame_input(ref_img_or_pts):
            ref = extract_markers(as_image_u8(ref_img_or_pts, "ref_img_or_pts"),
                                  **extract_opts).centres
            self.reference_shape: tuple[int, int] | None = (
                int(ref_img_or_pts.shape[0]), int(ref_img_or_pts.shape[1]))
        else:
            ref = as_points(ref_img_or_pts, "ref_img_or_pts")
            self.reference_shape = None
        self._native = _native.Tracker(ref, positive_or_none(max_dist, "max_dist"), **extract_opts)
        # The reference never changes: kept here so that reading it (SlipDetector does, every
        # frame) takes neither the lock nor a native call.
        self._reference: NDArray[np.float32] = self._native.reference

    @property
    def reference(self) -> NDArray[np.float32]:
        """Reference centres, ``N x 2`` float32 ``(x, y)`` (a fresh copy each time)."""
        return self._reference.copy()

    @property
    def positions(self) -> NDArray[np.float32]:
        """Last tracked centres (for a lost marker, where it was last seen)."""
        with self._lock:
            return self._native.positions

    @property
    def max_dist(self) -> float:
        """Per-frame matching gate, pixels."""
        return self._native.max_dist

    @property
    def frame(self) -> int:
        """Frames processed since construction or :meth:`reset`."""
        with self._lock:
            return self._native.frame

    def __len__(self) -> int:
        return int(self._reference.shape[0])

    def update(self, img_or_pts: Any) -> tuple[Motion, Valid]:
        """Tracks one frame: a uint8 image (markers are extracted) or ``M x 2`` detected centres.

        Returns ``(motion, valid)`` aligned with :attr:`reference`: ``N x 2`` float32
        ``(dx, dy)`` from the reference (NaN where lost) and ``N`` bool.
        """
        if is_frame_input(img_or_pts):
            arr = as_image_u8(img_or_pts, "img_or_pts")
            if self.reference_shape is not None and arr.shape[:2] != self.reference_shape:
                raise ValueError(
                    f"img_or_pts: image is {arr.shape[0]}x{arr.shape[1]} but the reference was "
                    f"{self.reference_shape[0]}x{self.reference_shape[1]}"
                )
            with self._lock:
                motion, valid, _ = self._native.update_image(arr)
        else:
            pts = as_points(img_or_pts, "img_or_pts")
            with self._lock:
                motion, valid, _ = self._native.update_points(pts)
        return motion, valid

    def reset(self) -> None:
        """Forgets the motion history; markers are expected back at the reference."""
        with self._lock:
            self._native.reset()
