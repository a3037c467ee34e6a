"""Training pairs for the motion model from a marker sensor's own videos (real data, no simulator).

The paper trains its markerless model on a sensor *with* markers: the markers are tracked for the
targets and removed for the inputs. This does that on videos. For each video:

1. the rest is its first frame (a recording that starts with the gripper open; or a no-contact
   frame given as ``reference``): its markers' centres are the read-out points;
2. :class:`tacswitch.MarkerTracker` follows the markers through every frame: the targets (each
   marker's motion from rest, px; NaN where the tracker lost it). A tracker cannot follow a
   sudden slip (markers jump more than :data:`MAX_STEP_PITCH` of the pitch between two frames):
   the video is used up to the frame before that;
3. every ``every``-th frame has its markers removed (TELEA) with the mask grown by ``grow_px``,
   by default on one mask for the whole video (``static``): the union of its frames' marker
   masks. A fill on each frame's own mask sits where the dots are, so its place moves with the
   gel: a network trained on such fills learns to follow them, scores well on frames cleaned
   the same way, and predicts motion that is not there on a truly markerless gel (real GelSight
   Mini presses whose gel does not move: 2.3 px from one frame, 3.5 px from the no-contact
   frame, against 0.1 and 1.2 px for the static recipe; BENCHMARKS.md, "Markerless motion on
   real GelSight Mini videos"). With one mask the fills stay put and only the gel between them
   shows the motion;
4. pairs ``(image, reference)`` of kept frames of one video: each kept frame against the rest
   frame, and against one earlier kept frame (drawn at random), with both frames' motions from
   rest, as :mod:`tacswitch.motion.train_stream`'s rendered pairs have them.

Frames are stored once (``frames``) and pairs as indices into them, so a few hundred videos fit
in memory; :meth:`RealPairs.batch` gathers a batch.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.inpaint import inpaint_telea
from tacswitch.markers import extract_markers
from tacswitch.tracking import MarkerTracker, estimate_pitch

#: A video is used up to the first frame where a tracked marker steps farther than this fraction
#: of the marker pitch since the previous frame (the tracker's truth is unsure there).
MAX_STEP_PITCH = 0.45
#: Default growth of the marker mask before the fill (px), and the fill's TELEA radius.
GROW_PX = 4
FILL_RADIUS = 5
#: Default: every third frame is kept (25 fps videos: about 8 training frames a second).
EVERY = 3
#: Default cap on the kept frames' memory (GiB): about 70,000 frames at 320x240.
MAX_GIB = 16.0
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v")


def grown(mask: NDArray[Any], grow_px: int) -> NDArray[np.bool_]:
    """``mask`` grown by ``grow_px`` px (an elliptical dilation)."""
    import cv2

    m: NDArray[Any] = np.asarray(mask).astype(np.uint8)
    if grow_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * grow_px + 1,) * 2)
        m = cv2.dilate(m, k)
    return np.asarray(m > 0)


def markerless(frame: NDArray[np.uint8], grow_px: int = GROW_PX,
               radius: float = FILL_RADIUS, mask: NDArray[Any] | None = None
               ) -> NDArray[np.uint8]:
    """``frame`` (BGR) with its markers removed: the extracted mask (or ``mask``) grown by
    ``grow_px`` px, filled by TELEA at ``radius`` px."""
    base = extract_markers(frame).mask if mask is None else mask
    return np.asarray(inpaint_telea(frame, grown(base, grow_px), radius=radius), np.uint8)


def union_mask(frames: list[NDArray[np.uint8]]) -> NDArray[np.bool_]:
    """The union of the frames' extracted marker masks: where any of them shows a dot."""
    union = np.zeros(frames[0].shape[:2], bool)
    for frame in frames:
        union |= extract_markers(frame).mask
    return union


def _frames_of(path: Path) -> list[NDArray[np.uint8]]:
    import cv2

    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise ValueError(f"videos: cannot open {str(path)!r} as a video")
    out: list[NDArray[np.uint8]] = []
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            if frame is not None and frame.ndim == 3 and frame.shape[2] == 3:
                out.append(np.asarray(frame, np.uint8))
    finally:
        cap.release()
    if not out:
        raise ValueError(f"videos: {str(path)!r} has no readable frame")
    return out


@dataclass
class VideoTrack:
    """One video's kept frames (markers removed), its rest centres and their motions."""

    frames: NDArray[np.uint8]  # K x H x W x 3
    rest: NDArray[np.float32]  # N x 2 (x, y) px
    motion: NDArray[np.float32]  # K x N x 2 px from rest, NaN = not tracked
    used: int  # frames of the video used (up to a sudden slip)
    total: int


def track_video(path: str | os.PathLike[str], reference: NDArray[np.uint8] | None = None, *,
                every: int = EVERY, grow_px: int = GROW_PX, static: bool = True
                ) -> VideoTrack:
    """Targets and markerless inputs of one marker video (see the module docstring).
    ``static``: every kept frame is filled on one mask, the union of the used frames' marker
    masks: the fills stay where they are, so their places say nothing of the motion and only
    the gel between them does (a stricter recipe against following the dots' traces)."""
    if every < 1:
        raise ValueError(f"every: must be >= 1; got {every}")
    raw = _frames_of(Path(path))
    first = raw[0] if reference is None else reference
    if first.shape != raw[0].shape:
        raise ValueError(f"reference: shape {first.shape} differs from {str(path)!r}'s frames "
                         f"{raw[0].shape}")
    tracker = MarkerTracker(first)
    rest = tracker.reference.astype(np.float32)
    if len(rest) < 3:
        raise ValueError(f"videos: {str(path)!r}: fewer than 3 markers in the rest frame")
    pitch = estimate_pitch(rest) or 30.0
    prev = np.zeros_like(rest)
    kept, motions = [], []
    used = len(raw)
    for t, frame in enumerate(raw):
        m, v = tracker.update(frame)
        m = np.where(np.asarray(v)[:, None], np.asarray(m, np.float32), np.nan)
        if t > 0 and np.nanmax(np.linalg.norm(m - prev, axis=1), initial=0.0) \
                > MAX_STEP_PITCH * pitch:
            used = t
            break
        prev = m
        if t % every == 0:
            kept.append(frame)
            motions.append(m.astype(np.float32))
    if static:
        union = union_mask(raw[:used])
        clean = [markerless(f, grow_px, mask=union) for f in kept]
    else:
        clean = [markerless(f, grow_px) for f in kept]
    return VideoTrack(np.stack(clean), rest, np.stack(motions), used, len(raw))


def _track_job(job: tuple[str, Any, int, int, bool]) -> VideoTrack:
    import cv2

    cv2.setNumThreads(1)
    path, ref, every, grow, static = job
    return track_video(path, ref, every=every, grow_px=grow, static=static)


def collect_videos(inputs: list[str | os.PathLike[str]]) -> list[Path]:
    """Video files among ``inputs`` (files, or folders searched recursively), sorted."""
    out: list[Path] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            out += sorted(q for q in p.rglob("*") if q.suffix.lower() in VIDEO_SUFFIXES)
        elif p.is_file():
            out.append(p)
        else:
            raise ValueError(f"videos: {str(p)!r} does not exist")
    if not out:
        raise ValueError(f"videos: no video ({', '.join(VIDEO_SUFFIXES)}) in "
                         f"{[str(i) for i in inputs]}")
    return out


@dataclass
class RealPairs:
    """Frames stored once and pairs as indices (see the module docstring).

    Attributes:
        frames: ``F x H x W x 3`` uint8 BGR, markers removed.
        motion: ``F x N x 2`` float32, each frame's marker motion from its video's rest (px, NaN
            = not tracked or padding; ``N`` = the most markers of any video).
        rest: ``V x N x 2`` float32 rest centres of each video (padding rows 0).
        video: ``F`` index of each frame's video.
        pairs: ``P x 2`` (image frame, reference frame) indices.
        names: the videos, in order.
    """

    frames: NDArray[np.uint8]
    motion: NDArray[np.float32]
    rest: NDArray[np.float32]
    video: NDArray[np.int64]
    pairs: NDArray[np.int64]
    names: list[str]

    def __len__(self) -> int:
        return len(self.pairs)

    def batch(self, idx: Any) -> dict[str, NDArray[Any]]:
        """The pairs ``idx`` as arrays: ``image``, ``reference``, ``rest``, ``displacement``
        (motion from reference to image), ``disp_image``, ``disp_reference`` (from rest)."""
        return gather_pairs(self.frames, self.motion, self.rest, self.video,
                            self.pairs[np.asarray(idx)])

    def subset(self, videos: Any) -> RealPairs:
        """The pairs whose frames come from the given video indices (e.g. a validation split)."""
        keep = np.isin(self.video[self.pairs[:, 0]], np.asarray(videos))
        return RealPairs(self.frames, self.motion, self.rest, self.video, self.pairs[keep],
                         self.names)


def gather_pairs(frames: Any, motion: Any, rest: Any, video: Any, pairs: Any) -> dict[str, Any]:
    """The batch of ``pairs`` (``B x 2`` image, reference frame indices) from the arrays of a
    :class:`RealPairs` (numpy arrays or torch tensors alike: indexing and a difference only)."""
    di, dr = motion[pairs[:, 0]], motion[pairs[:, 1]]
    return {"image": frames[pairs[:, 0]], "reference": frames[pairs[:, 1]],
            "rest": rest[video[pairs[:, 0]]], "displacement": di - dr, "disp_image": di,
            "disp_reference": dr}


def pairs_from_videos(videos: list[str | os.PathLike[str]],
                      reference: NDArray[np.uint8] | None = None, *, every: int = EVERY,
                      grow_px: int = GROW_PX, static: bool = True, seed: int = 0,
                      workers: int = 1, max_gib: float = MAX_GIB,
                      progress: bool = False) -> RealPairs:
    """:class:`RealPairs` of marker videos (files or folders; all frames of one size), tracked
    and cleaned in ``workers`` processes. ``reference``: a no-contact frame with markers for
    every video (default: each video's first frame). ``static``: see :func:`track_video`.
    The kept frames are held in memory (and on the training device): more than ``max_gib``
    GiB of them is a ``ValueError`` naming ``every``, before memory runs out."""
    paths = collect_videos(videos)
    if grow_px < 0:
        raise ValueError(f"grow_px: must be >= 0; got {grow_px}")
    jobs = [(str(p), reference, every, grow_px, static) for p in paths]
    tracks: list[VideoTrack] = []

    def keep(tr: VideoTrack) -> None:
        tracks.append(tr)
        gib = sum(t.frames.nbytes for t in tracks) / 2**30
        if gib > max_gib:
            raise ValueError(f"every: the kept frames of the first {len(tracks)} of "
                             f"{len(jobs)} videos already take {gib:.1f} GiB (limit "
                             f"{max_gib:g}); keep fewer frames (every > {every}) or train "
                             "on fewer videos")
        if progress:
            print(f"\r{len(tracks)}/{len(jobs)} videos tracked and cleaned", end="",
                  flush=True)

    if workers > 1:
        from multiprocessing import get_context

        from tacswitch._checks import process_count

        with get_context("spawn").Pool(process_count(workers, len(jobs))) as pool:
            for tr in pool.imap(_track_job, jobs, chunksize=1):
                keep(tr)
    else:
        for job in jobs:
            keep(_track_job(job))
    if progress:
        print(flush=True)
    shapes = {t.frames.shape[1:] for t in tracks}
    if len(shapes) > 1:
        raise ValueError(f"videos: frames of one size needed; got {sorted(shapes)}")
    n = max(len(t.rest) for t in tracks)
    rng = np.random.default_rng(seed)
    frames, motion, rest, video, pairs = [], [], [], [], []
    base = 0
    for v, t in enumerate(tracks):
        k = len(t.frames)
        m = np.full((k, n, 2), np.nan, np.float32)
        m[:, :len(t.rest)] = t.motion
        r = np.zeros((n, 2), np.float32)
        r[:len(t.rest)] = t.rest
        frames.append(t.frames)
        motion.append(m)
        rest.append(r)
        video.append(np.full(k, v, np.int64))
        for i in range(1, k):
            pairs.append((base + i, base))
            if i > 1:
                pairs.append((base + i, base + int(rng.integers(1, i))))
        base += k
    if not pairs:
        raise ValueError("videos: too short to form a pair (need 2 kept frames)")
    return RealPairs(np.concatenate(frames), np.concatenate(motion), np.stack(rest),
                     np.concatenate(video), np.asarray(pairs, np.int64),
                     [str(p) for p in paths])
