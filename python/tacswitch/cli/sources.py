"""Frame sources shared by the streaming commands: video files, image folders, cameras."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}
VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v"}

#: Consecutive unreadable frames after which a camera counts as disconnected.
MAX_FAILED_READS = 30


def natural_key(path: Path) -> tuple[tuple[int, int | str], ...]:
    """Sort key of a file name in natural order: runs of digits compare as numbers, so
    ``60.png`` comes before ``540.png`` and ``frame_2`` before ``frame_10`` (frame folders
    are rarely zero-padded)."""
    import re

    return tuple((0, int(part)) if part.isdigit() else (1, part)
                 for part in re.split(r"(\d+)", path.name) if part)


def sorted_files(folder: Path, suffixes: set[str]) -> list[Path]:
    """The files of ``folder`` whose suffix (lower case) is in ``suffixes``, in natural order
    (:func:`natural_key`)."""
    return sorted((p for p in folder.iterdir() if p.suffix.lower() in suffixes),
                  key=natural_key)


def _quiet_decoder() -> None:
    """Silences FFmpeg's own log (a damaged frame prints hundreds of lines on stderr; the
    commands count and report skipped frames instead). Takes effect at the first capture of
    the process; set ``OPENCV_FFMPEG_LOGLEVEL`` (e.g. 16: errors) to see the decoder's log."""
    import os

    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")


def quiet_opencv() -> None:
    """Keeps OpenCV's own log lines ("VIDEOIO WARN", "imread_ ... can't open", PNG chunk
    warnings) off the terminal: the commands report unreadable files and frames themselves.
    Set ``OPENCV_LOG_LEVEL`` (e.g. ``WARNING``) to see them. libpng's own "libpng error"
    lines bypass this log; the commands read images through
    :func:`tacswitch._io.try_read_image` with ``quiet=True`` for those."""
    import os

    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    _quiet_decoder()
    import cv2

    levels = {"SILENT": 0, "FATAL": 1, "ERROR": 2, "WARNING": 3, "INFO": 4, "DEBUG": 5,
              "VERBOSE": 6}
    level = levels.get(os.environ["OPENCV_LOG_LEVEL"].upper())
    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    if level is not None and logging is not None:
        logging.setLogLevel(level)  # cv2 may have been imported before the variable was set


def read_quiet(path: str | Path) -> np.ndarray | None:
    """A BGR uint8 image, or None when the file cannot be decoded (no decoder noise)."""
    from tacswitch._io import try_read_image

    return try_read_image(path, quiet=True)


def quoted_names(failed: list[tuple[Path, str]], limit: int = 8) -> str:
    """The first ``limit`` of ``(path, reason)`` inputs, quoted, and how many more."""
    names = ", ".join(repr(str(p)) for p, _ in failed[:limit])
    return names + (f" and {len(failed) - limit} more" if len(failed) > limit else "")


def report_unreadable(command: str, failed: list[tuple[Path, str]], done: int) -> None:
    """After a batch of which ``done`` inputs were read: ``ValueError`` when none was (the one
    reason, or a count with the names), else a warning naming the skipped inputs and the
    first one's reason."""
    from tacswitch.cli.progress import warn

    if not failed:
        return
    if done == 0:
        raise ValueError(failed[0][1] if len(failed) == 1 else
                         f"inputs: none of the {len(failed)} inputs could be read "
                         f"({quoted_names(failed)}); the first: {failed[0][1]}")
    # With the reason: an input is skipped for its size or a frame it lacks, not only for
    # being unreadable.
    first = "" if len(failed) == 1 else "the first: "
    warn(command, f"skipped {len(failed)} input{'s' if len(failed) > 1 else ''} that could "
         f"not be used: {quoted_names(failed)} ({first}{failed[0][1]})")


def collect_images(inputs: list[str]) -> list[Path]:
    """Image files named or found (natural order) in the named folders; ``FileNotFoundError``
    if none."""
    files: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            files += sorted_files(path, IMAGE_SUFFIXES)
        elif path.is_file():
            files.append(path)
        else:
            raise FileNotFoundError(f"input {item!r} does not exist")
    if not files:
        raise FileNotFoundError("no images found in the inputs")
    return files


def check_distinct_outputs(jobs: list[tuple[Path, Path]]) -> None:
    """``ValueError`` naming both inputs when two ``(input, output)`` pairs of ``jobs`` write
    the same output file (``a/x.png`` and ``b/x.png`` into one folder), before any work: one
    result would silently replace the other."""
    seen: dict[Path, Path] = {}
    for path, target in jobs:
        if target in seen and seen[target] == path:
            raise ValueError(f"inputs: {str(path)!r} is given twice")
        if target in seen:
            raise ValueError(f"inputs: {str(seen[target])!r} and {str(path)!r} would both "
                             f"write {str(target)!r}; give them different names")
        seen[target] = path


def _named_video(path: Path) -> bool:
    """A named file is a video: by its suffix, or, with a suffix neither list knows (or none,
    as a camera's dump may have), when OpenCV reads no image signature in it."""
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES or suffix in IMAGE_SUFFIXES:
        return suffix in VIDEO_SUFFIXES
    import cv2

    return not cv2.haveImageReader(str(path))


def collect_inputs(inputs: list[str]) -> tuple[list[Path], list[Path]]:
    """Images and videos named or found (natural order) in the named folders, told apart by suffix
    (:data:`VIDEO_SUFFIXES`, :data:`IMAGE_SUFFIXES`; a named file with another suffix or none is
    an image if OpenCV knows its signature, else a video). ``FileNotFoundError`` naming the
    input if one does not exist, or if there is nothing to do."""
    images: list[Path] = []
    videos: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            images += sorted_files(path, IMAGE_SUFFIXES)
            videos += sorted_files(path, VIDEO_SUFFIXES)
        elif path.is_file():
            (videos if _named_video(path) else images).append(path)
        else:
            raise FileNotFoundError(f"inputs: {item!r} does not exist")
    if not images and not videos:
        raise FileNotFoundError("inputs: no images or videos found")
    return images, videos


def open_video(path: str | Path, name: str = "source") -> Any:
    """An opened ``cv2.VideoCapture`` of a video file; ``ValueError`` naming the argument
    ``name`` if it cannot be decoded (corrupt, truncated, unknown codec)."""
    import cv2

    _quiet_decoder()
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise ValueError(f"{name}: cannot decode video {str(path)!r}")
    return cap


def video_info(path: str | Path, name: str = "source") -> tuple[float, int | None]:
    """``(fps, frame_count)`` of a video file; fps 0 when the file does not say, frame_count
    None when unknown (the container's count, which some formats only estimate)."""
    import cv2

    cap = open_video(path, name)
    try:
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    return (fps if np.isfinite(fps) and fps > 0 else 0.0), (count if count > 0 else None)


def stated_fps(path: str | Path, name: str = "source") -> float | None:
    """The frame rate a video file states (frames/s); None when it states none or an
    implausible one (outside 1-1000 frames/s: some containers store a time base there)."""
    fps = video_info(path, name)[0]
    return fps if 1.0 <= fps <= 1000.0 else None


#: FOURCCs (lower case) of codecs that predict frames from earlier ones (H.264, HEVC, MPEG-1 /
#: 2 / 4 part 2, H.263, WMV, Theora, VP8 / VP9, AV1): their decoded gel texture drifts and
#: refreshes from frame to frame.
INTER_FRAME_CODECS = frozenset({"avc1", "h264", "x264", "davc", "hev1", "hvc1", "hevc", "h265",
                                "mpg1", "mpg2", "mpeg", "pim1", "mp4v", "xvid", "divx", "fmp4",
                                "dx50", "h263", "s263", "wmv1", "wmv2", "wmv3", "wvc1", "theo",
                                "vp80", "vp08", "vp90", "vp09", "av01"})


def video_codec(path: str | Path) -> str | None:
    """The FOURCC of a video file's codec, lower case (e.g. ``"avc1"`` for H.264, ``"mjpg"``),
    or None when it cannot be told (not a video, no codec tag)."""
    import cv2

    _quiet_decoder()
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            return None
        code = int(cap.get(cv2.CAP_PROP_FOURCC))
    finally:
        cap.release()
    if code <= 0:
        return None
    text = "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4))
    return text.strip().lower() if text.isprintable() and text.strip() else None


def video_frames(path: str | Path, name: str = "source") -> Iterator[np.ndarray | None]:
    """Yields the frames of a video file, None for each frame that does not decode.

    A decoder that fails in the middle of a file goes on with the next frame (the failed read
    consumed it); :data:`MAX_FAILED_READS` failures in a row, or reaching the container's frame
    count, is the end. Failures after the last good frame count as frames only up to the
    container's frame count.
    """
    import cv2

    cap = open_video(path, name)
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    n = failed = 0  # frames yielded; failed reads since the last good one
    try:
        while failed < MAX_FAILED_READS and (count <= 0 or n + failed < count):
            ok, frame = cap.read()
            if not ok:
                failed += 1
                continue
            for _ in range(failed):
                yield None
            n += failed + 1
            failed = 0
            yield frame
        for _ in range(min(failed, max(count - n, 0))):
            yield None
    finally:
        cap.release()


def frame_count(source: str, limit: int | None = None) -> int | None:
    """Frames :func:`frames` will yield for ``source``, at most ``limit`` (None: unknown, e.g.
    a camera without a limit). For progress bars only: a source that cannot be opened gives
    None here and its error where it is read."""
    path = Path(source)
    count: int | None = None
    if path.is_dir():
        count = sum(1 for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    elif not source.isdigit() and path.is_file():
        try:
            count = video_info(path)[1]
        except ValueError:
            count = None
    if limit is None:
        return count
    return limit if count is None else min(count, limit)


class SkipCount:
    """The frames a streaming command skipped, for its summary line: every skip, and how many
    undecodable frames have come since the last decoded one (those that end the stream read
    as a video cut short)."""

    def __init__(self) -> None:
        self.total = 0
        self.trailing = 0

    def undecodable(self) -> None:
        """A frame that did not decode."""
        self.total += 1
        self.trailing += 1

    def decoded(self) -> None:
        """A frame that decoded (skipped or not)."""
        self.trailing = 0

    def unusable(self) -> None:
        """A decoded frame the command cannot use (e.g. another size)."""
        self.total += 1

    def __str__(self) -> str:
        """``"3 skipped"``, and when the last of them end the stream undecoded, says so."""
        if not self.trailing:
            return f"{self.total} skipped"
        last = "the last frame" if self.trailing == 1 else f"the last {self.trailing}"
        return f"{self.total} skipped, {last} at the end of the source: a video cut short?"


def check_source(source: str) -> None:
    """``FileNotFoundError`` naming ``source`` unless it is a file, a folder or a camera index
    (checked before anything is written, e.g. a log)."""
    if not source.isdigit() and not Path(source).is_dir() and not Path(source).is_file():
        raise FileNotFoundError(f"source: {source!r} is not a file, folder or camera index")


def frames(source: str) -> Iterator[np.ndarray | None]:
    """Yields BGR frames from a folder, a video or a camera index; None for an unreadable frame.

    Raises ``FileNotFoundError``/``ValueError`` naming ``source`` when it cannot be opened, and
    ``ConnectionError`` when a camera stops delivering frames.
    """
    import cv2

    path = Path(source)
    if path.is_dir():
        files = sorted_files(path, IMAGE_SUFFIXES)
        if not files:
            raise FileNotFoundError(f"source: no images in folder {source!r}")
        for f in files:
            yield read_quiet(f)
        return
    if not source.isdigit():
        check_source(source)
        yield from video_frames(path)
        return
    _quiet_decoder()
    cap = cv2.VideoCapture(int(source))
    if not cap.isOpened():
        raise FileNotFoundError(f"source: cannot open camera {source}")
    failed = 0
    try:
        while True:
            ok, frame = cap.read()
            if ok:
                failed = 0
                yield frame
                continue
            failed += 1
            if failed >= MAX_FAILED_READS:
                raise ConnectionError(f"camera {source} stopped delivering frames")
            yield None
    finally:
        cap.release()
