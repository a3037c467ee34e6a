"""Labelled grasp recordings: reading a folder of videos with per-experiment slip labels, tracking
each clip once and caching its features.

Layout (the one of the public GelSight Mini slip study, and what ``tacswitch evaluate slip`` /
``tacswitch train slip`` read)::

    DIR/labels.csv                      object,experiment,slip[,...]  (slip: 1 or 0)
    DIR/OBJECT/EXPERIMENT/*.avi|mp4     one video per sensor (finger) of that experiment

An experiment counts as slip when any of its videos fires. The labels say whether the object
slipped at some point, not when. Validation splits are by ``object`` (two experiments of one
object are not independent).
"""

from __future__ import annotations

import csv
import itertools
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.grasp.detector import SCORER_FLOW_PRESET, SCORER_FRAME_TO_FRAME, SCORER_REMOVAL
from tacswitch.grasp.features import marker_pitch, sequence_features
from tacswitch.grasp.timebase import needs_resampling, resample_field
from tacswitch.markers import extract_markers
from tacswitch.motion.sequence import MarkerlessTracker
from tacswitch.removal import remove_markers
from tacswitch.tracking import (
    REST_LOOK_AHEAD,
    MarkerTracker,
    lattice_irregularity,
    rest_thumbnail,
    settled_index,
    usable_rest_frame,
)

VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov")


@dataclass
class Experiment:
    """One labelled experiment: its object, name, label and video files (one per sensor)."""

    object: str
    name: str
    slip: bool
    videos: list[Path] = field(default_factory=list)


def read_labels(root: str | os.PathLike[str], labels: str | os.PathLike[str] | None = None
                ) -> list[Experiment]:
    """Experiments of a labelled folder (see the module doc). ``labels`` defaults to
    ``root/labels.csv``. One-line ``ValueError`` naming the argument on a missing file, missing
    columns, a label other than 0/1, or an experiment without videos."""
    base = Path(root)
    if not base.is_dir():
        raise ValueError(f"root: not a folder: {str(root)!r}")
    path = Path(labels) if labels is not None else base / "labels.csv"
    if not path.is_file():
        raise ValueError(f"labels: no such file: {str(path)!r}")
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            return _labelled_experiments(base, path, csv.DictReader(fh))
    except UnicodeDecodeError:
        raise ValueError(f"labels: {str(path)!r} is not a UTF-8 text CSV") from None


def _labelled_experiments(base: Path, path: Path, reader: csv.DictReader[str]
                          ) -> list[Experiment]:
    """The experiments ``reader`` (rows of the labels file ``path``) lists under ``base``."""
    # Spaces around the header's names and the cells are a spreadsheet's, not meaning.
    fields = [f.strip() for f in (reader.fieldnames or [])]
    reader.fieldnames = fields
    missing = {"object", "experiment", "slip"} - set(fields)
    if missing:
        raise ValueError(f"labels: {str(path)!r} lacks column(s) {sorted(missing)} "
                         f"(needs object, experiment, slip; found {fields})")
    out = []
    seen: dict[tuple[str, str], int] = {}
    for line, row in enumerate(reader, start=2):
        label = (row["slip"] or "").strip()
        if label not in ("0", "1"):
            raise ValueError(f"labels: line {line}: slip must be 0 or 1; got {label!r}")
        obj, exp = (row["object"] or "").strip(), (row["experiment"] or "").strip()
        if (obj, exp) in seen:
            raise ValueError(f"labels: line {line}: {obj}/{exp} is listed again (first on "
                             f"line {seen[(obj, exp)]})")
        seen[(obj, exp)] = line
        folder = base / obj / exp
        videos = sorted(p for p in folder.glob("*") if p.suffix.lower() in VIDEO_SUFFIXES)
        if not videos:
            raise ValueError(f"labels: line {line}: no video (*.avi, *.mp4, ...) in "
                             f"{str(folder)!r}")
        out.append(Experiment(obj, exp, label == "1", videos))
    if not out:
        raise ValueError(f"labels: {str(path)!r} lists no experiment")
    return out


def read_video(path: str | os.PathLike[str]) -> Iterator[NDArray[np.uint8]]:
    """Decoded BGR frames of a video (unreadable frames skipped)."""
    from tacswitch.cli.sources import video_frames

    for frame in video_frames(Path(path), "video"):
        if frame is not None and frame.ndim == 3:
            yield frame


@dataclass
class TrackedClip:
    """A clip's tracked marker field: ``motion`` ``T x N x 2`` px since the rest frame,
    ``valid`` ``T x N``, reference ``points`` ``N x 2``, marker ``pitch`` px, frame ``width``
    px, the video's frame rate ``fps`` (frames/s; None: not known, taken to be the detector's
    time base, :data:`~tacswitch.grasp.timebase.TRAINED_FPS`) and its ``rest`` frame (index:
    the frames before it are rows of zero motion, not tracked; ``tacswitch slip`` starts its
    detector there, and so does :func:`~tacswitch.grasp.crossval.clip_flags`)."""

    motion: NDArray[np.float32]
    valid: NDArray[np.bool_]
    points: NDArray[np.float32]
    pitch: float
    width: int
    fps: float | None = None
    rest: int = 0

    def features(self, still_filter: bool = False) -> NDArray[np.float32]:
        """``T' x N_FEATURES`` online features (:func:`sequence_features`) on the detector's
        time base: a clip at another frame rate is resampled first
        (:func:`~tacswitch.grasp.timebase.resample_field`), as the detector does online.
        ``still_filter``: read through the still-marker hysteresis
        (:class:`~tacswitch.grasp.features.FieldFeatures`; tracked markers)."""
        motion, valid = self.motion, self.valid
        if needs_resampling(self.fps):
            assert self.fps is not None
            motion, valid = resample_field(motion, valid, self.fps)
        return sequence_features(motion, valid, self.points, self.pitch,
                                 still_filter=still_filter)


def clip_features(experiments: list[list[TrackedClip]], still_filter: bool = False
                  ) -> list[list[NDArray[np.float32]]]:
    """Every video's features (:meth:`TrackedClip.features`), experiment by experiment: the
    training input of :func:`tacswitch.grasp.train.train_committee`."""
    return [[c.features(still_filter) for c in exp] for exp in experiments]


def scorer_removal(frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``frame`` (``H x W x 3`` uint8 BGR, with markers) with its markers removed as for the
    markerless slip scorer's training: :func:`tacswitch.remove_markers` with
    :data:`~tacswitch.grasp.detector.SCORER_REMOVAL`."""
    return remove_markers(frame, dilate=SCORER_REMOVAL["dilate"],
                          radius=SCORER_REMOVAL["radius"])


def track_clip(frames: Iterator[NDArray[np.uint8]], *, markerless: bool = False
               ) -> TrackedClip:
    """Tracks markers through ``frames``. With markers the reference is the rest frame
    ``tacswitch slip`` takes (:mod:`tacswitch.cli.rest_frame`: the first usable frame after
    the camera settled, among the first :data:`~tacswitch.tracking.REST_LOOK_AHEAD`); the
    frames before it are not tracked and read as rest (zero motion), so frame numbers stay
    the video's. ``markerless``: the markers are removed from every frame first
    (:func:`scorer_removal`) and the motion predicted by :class:`tacswitch.MarkerlessTracker`
    from the first frame after the camera settled (no marker count: ``tacswitch slip
    --markerless`` starts there too), at its marker centres, with the frame-to-frame path at
    :data:`~tacswitch.grasp.detector.SCORER_FRAME_TO_FRAME`: the markerless sensor this
    recording would have been."""
    it = iter(frames)
    head = list(itertools.islice(it, REST_LOOK_AHEAD))
    if not head:
        raise ValueError("frames: no readable frame")
    width = int(head[0].shape[1])
    rest, points = clip_rest_frame(head, markerless=markerless)
    n = len(points)
    motions: list[NDArray[np.float32]] = [np.zeros((n, 2), np.float32)] * rest
    valids: list[NDArray[np.bool_]] = [np.ones(n, bool)] * rest
    if markerless:
        mtracker = MarkerlessTracker(None, points, preset=SCORER_FLOW_PRESET,
                                     frame_to_frame=SCORER_FRAME_TO_FRAME)
        for frame in itertools.chain(head[rest:], it):
            m = (mtracker.update(scorer_removal(frame)) if n
                 else np.zeros((0, 2), np.float32))
            motions.append(np.asarray(m, np.float32))
            valids.append(np.ones(n, bool))
    else:
        tracker = MarkerTracker(points) if n else None
        for frame in itertools.chain(head[rest:], it):
            if tracker is None:
                motions.append(np.zeros((0, 2), np.float32))
                valids.append(np.zeros(0, bool))
                continue
            m, v = tracker.update(frame)
            motions.append(np.array(m, np.float32))
            valids.append(np.array(v, bool))
    return TrackedClip(np.stack(motions), np.stack(valids), points, marker_pitch(points), width,
                       rest=rest)


def clip_rest_frame(head: list[NDArray[np.uint8]], *, markerless: bool = False
                    ) -> tuple[int, NDArray[np.float32]]:
    """The rest frame :func:`track_clip` takes among a video's first frames ``head`` (its
    index, and the marker centres found on it): the first after the camera settled, with
    markers also one with a regular lattice and a usable marker count."""
    thumbs = [rest_thumbnail(f) for f in head]
    if markerless:
        rest = settled_index(thumbs)
        return rest, extract_markers(head[rest]).centres
    found = [extract_markers(f).centres for f in head]
    rest = settled_index(thumbs, [lattice_irregularity(c) for c in found])
    rest = usable_rest_frame([len(c) for c in found], start=rest) or 0
    return rest, found[rest]


#: The version of the tracking rules a cached clip was made with, in its file name; an older
#: cache is tracked again. "-v2": the rest frame after the camera settles (2026-11-28); "-v3"
#: (markers): also after a stale start that fades (2026-11-29); "-v3" (markerless): the
#: refined flow on markers removed with ``SCORER_REMOVAL`` (2026-11-30); "-v4" (markerless): the
#: frame-to-frame path at ``SCORER_FRAME_TO_FRAME`` (2026-12-01).
MARKER_TRACKS_TAG = "markers-v3"
MARKERLESS_TRACKS_TAG = "markerless-v4"


def source_stamp(video: Path) -> NDArray[np.int64]:
    """``[size in bytes, modification time in ns]`` of a video: a cached clip of an edited or
    replaced file is tracked again."""
    st = video.stat()
    return np.array([st.st_size, st.st_mtime_ns], np.int64)


def source_digest(video: Path) -> str:
    """A BLAKE2b digest (hex) of the video's bytes: a copied or re-extracted dataset (new
    modification times, the same files) keeps its cache."""
    import hashlib

    h = hashlib.blake2b(digest_size=16)
    with open(video, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def save_clip(path: Path, clip: TrackedClip, video: Path | None = None) -> None:
    """Writes ``clip`` to ``path`` (``.npz``) atomically, so an interrupted run leaves no
    partial file; with ``video``, its :func:`source_stamp` and :func:`source_digest` too."""
    from tacswitch._io import atomic_open

    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, Any] = {"motion": clip.motion, "valid": clip.valid,
                              "points": clip.points, "pitch": clip.pitch, "width": clip.width,
                              "fps": np.nan if clip.fps is None else clip.fps,
                              "rest": clip.rest}
    if video is not None:
        arrays["source"] = source_stamp(video)
        arrays["source_digest"] = np.array(source_digest(video))
    with atomic_open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _cache_matches(path: Path, video: Path) -> bool:
    """The cached clip at ``path`` was tracked from ``video`` as it is now: the same size and
    modification time, or the same size and bytes (a cache written without a stamp is
    trusted)."""
    with np.load(path) as z:
        if "source" not in z.files:
            return True
        stored, now = z["source"], source_stamp(video)
        if stored.shape != now.shape or stored[0] != now[0]:
            return False
        if stored[1] == now[1]:
            return True
        return "source_digest" in z.files and str(z["source_digest"]) == source_digest(video)


def load_clip(path: Path, video: Path | None = None, *, markerless: bool = False
              ) -> TrackedClip:
    """The clip :func:`save_clip` wrote. A file written before the frame rate was stored takes
    ``video``'s stated rate (None without ``video``); one written before the rest frame was
    stored finds it again from ``video``'s first frames (:func:`clip_rest_frame`, tracked with
    markers or ``markerless``; 0 without ``video``)."""
    return _load_clip(path, video, markerless)[0]


def _load_clip(path: Path, video: Path | None, markerless: bool) -> tuple[TrackedClip, bool]:
    """:func:`load_clip`, and whether the file stored the rest frame."""
    from tacswitch.cli.sources import stated_fps

    with np.load(path) as z:
        if "fps" in z.files:
            fps = None if np.isnan(z["fps"]) else float(z["fps"])
        else:
            fps = None if video is None else stated_fps(video, "video")
        stored = "rest" in z.files
        clip = TrackedClip(z["motion"], z["valid"], z["points"], float(z["pitch"]),
                           int(z["width"]), fps, int(z["rest"]) if stored else 0)
    if stored or video is None:
        return clip, stored
    head = list(itertools.islice(read_video(video), REST_LOOK_AHEAD))
    rest = clip_rest_frame(head, markerless=markerless)[0] if head else 0
    # Never past a tracked row (the rules may have changed since the file was written): the
    # rows before the rest frame are zeros.
    moved = np.flatnonzero(np.abs(clip.motion).reshape(len(clip.motion), -1).max(axis=1,
                                                                                initial=0) > 0)
    if moved.size:
        rest = min(rest, int(moved[0]))
    return replace(clip, rest=min(rest, max(len(clip.motion) - 1, 0))), False


def cached_clip(video: Path, cache: Path | None, *, markerless: bool = False) -> TrackedClip:
    """The :class:`TrackedClip` of one video (with the frame rate the file states), from
    ``cache`` when there (:func:`save_clip`: an interrupted run resumes where it stopped)."""
    from tacswitch.cli.sources import stated_fps

    target = None
    if cache is not None:
        tag = MARKERLESS_TRACKS_TAG if markerless else MARKER_TRACKS_TAG
        key = f"{video.parent.parent.name}__{video.parent.name}__{video.stem}__{tag}.npz"
        target = cache / key
        if target.is_file() and _cache_matches(target, video):
            clip, stored = _load_clip(target, video, markerless)
            if not stored:  # written before the rest frame was stored: add it once
                try:
                    save_clip(target, clip, video)
                except OSError:  # a read-only cache is still read
                    pass
            return clip
    clip = replace(track_clip(read_video(video), markerless=markerless),
                   fps=stated_fps(video, "video"))
    if target is not None:
        save_clip(target, clip, video)
    return clip


def experiment_clips(experiments: list[Experiment], cache: Path | None = None, *,
                     markerless: bool = False, workers: int = 1,
                     progress: bool = False,
                     unreadable: list[tuple[Path, str]] | None = None
                     ) -> list[list[TrackedClip]]:
    """Tracked clips of every video of every experiment (a list per experiment), computed in
    ``workers`` processes (the caller's main module must be import-safe for ``workers > 1``;
    never more than there are videos or CPU cores: each process holds a tracker and its
    frames, and a thousand of them would exhaust the machine before tracking one video).
    ``unreadable``: a list to collect the videos that cannot be tracked (no readable frame:
    ``(video, reason)``); they are left out of their experiment's list instead of stopping
    the whole run (None: the first such video raises ``ValueError``)."""
    jobs = [(v, cache, markerless) for e in experiments for v in e.videos]
    job = _job if unreadable is None else _job_or_reason
    flat: list[TrackedClip | str] = []
    from tacswitch._checks import process_count

    workers = process_count(workers, len(jobs))
    if workers > 1:
        from multiprocessing import get_context

        with get_context("spawn").Pool(workers) as pool:
            for i, clip in enumerate(pool.imap(job, jobs, chunksize=1)):
                flat.append(clip)
                if progress:
                    print(f"\r{i + 1}/{len(jobs)} videos", end="", flush=True, file=sys.stderr)
    else:
        for i, one in enumerate(jobs):
            flat.append(job(one))
            if progress:
                print(f"\r{i + 1}/{len(jobs)} videos", end="", flush=True, file=sys.stderr)
    if progress:
        print(file=sys.stderr)
    out: list[list[TrackedClip]] = []
    k = 0
    for e in experiments:
        clips = []
        for video, got in zip(e.videos, flat[k:k + len(e.videos)], strict=True):
            if isinstance(got, str):
                assert unreadable is not None
                unreadable.append((video, got))
            else:
                clips.append(got)
        out.append(clips)
        k += len(e.videos)
    return out


def _job(job: tuple[Path, Path | None, bool]) -> TrackedClip:
    return cached_clip(job[0], job[1], markerless=job[2])


def _job_or_reason(job: tuple[Path, Path | None, bool]) -> TrackedClip | str:
    """:func:`_job`, or why the video cannot be tracked (a video without a readable frame)."""
    try:
        return _job(job)
    except ValueError as exc:
        return str(exc)
