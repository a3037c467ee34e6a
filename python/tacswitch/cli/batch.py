"""Batch helpers of the commands: an ordered thread map and an atomic video writer."""

from __future__ import annotations

import os
import tempfile
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")
R = TypeVar("R")


def default_workers() -> int:
    """All cores (``os.cpu_count()``; 1 when unknown)."""
    return os.cpu_count() or 1


@contextmanager
def ordered_map(fn: Callable[[T], R], items: Iterable[T], workers: int) -> Iterator[Iterator[R]]:
    """``fn`` over ``items`` on ``workers`` threads, results yielded **in input order**.

    For work that releases the GIL (the Rust core, OpenCV, image codecs). At most
    ``2 * workers`` items are in flight, so a long video is never decoded far ahead. ``items``
    is consumed on the calling thread (a ``cv2.VideoCapture`` stays on one thread). Leaving
    the ``with`` block early (an error, Ctrl-C) cancels what has not started and waits for
    what has. ``workers <= 1`` runs serially, with no thread.
    """
    if workers <= 1:
        yield (fn(item) for item in items)
        return
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="tacswitch")

    def results() -> Iterator[R]:
        pending: deque[Future[R]] = deque()
        for item in items:
            pending.append(pool.submit(fn, item))
            if len(pending) >= 2 * workers:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()

    try:
        yield results()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


#: Video codecs the commands write: fourcc, file suffix, and whether frames survive exactly.
CODECS: dict[str, tuple[str, str, bool]] = {
    "mp4v": ("mp4v", ".mp4", False),  # MPEG-4 Part 2: plays anywhere, lossy
    "ffv1": ("FFV1", ".mkv", True),  # FFmpeg's FFV1 in Matroska: lossless, bit-exact frames
}


class AtomicVideoWriter:
    """A ``cv2.VideoWriter`` (``codec``, see :data:`CODECS`; default mp4v) on a hidden
    temporary file next to ``target``, renamed to ``target`` by :meth:`commit`;
    :meth:`discard` (or an exception in a ``with`` block) removes it. An interrupted run never
    leaves a partial video under the final name.

    The frame size is taken from the first frame written; frames of another size are refused
    (``write`` returns False) instead of being dropped silently by OpenCV.
    """

    def __init__(self, target: str | os.PathLike[str], fps: float, codec: str = "mp4v") -> None:
        if codec not in CODECS:
            raise ValueError(f"codec: must be one of {sorted(CODECS)}; got {codec!r}")
        self.fourcc = CODECS[codec][0]
        self.target = Path(target)
        self.fps = fps
        self.size: tuple[int, int] | None = None
        self.frames = 0
        self._writer: Any = None
        self.target.parent.mkdir(parents=True, exist_ok=True)
        # The suffix keeps the container OpenCV chooses by extension.
        fd, tmp = tempfile.mkstemp(prefix=f".{self.target.stem}.",
                                   suffix=f".part{self.target.suffix}", dir=self.target.parent)
        os.close(fd)
        self._tmp = Path(tmp)

    def write(self, frame: np.ndarray) -> bool:
        """Appends a BGR uint8 frame; False (nothing written) if its size differs from the
        first frame's. ``ValueError`` if this OpenCV build cannot encode the codec."""
        import cv2

        h, w = frame.shape[:2]
        if self._writer is None:
            self.size = (w, h)
            self._writer = cv2.VideoWriter(str(self._tmp), cv2.VideoWriter.fourcc(*self.fourcc),
                                           self.fps, (w, h))
            if not self._writer.isOpened():
                self.discard()
                raise ValueError(f"--codec: this OpenCV build cannot write {self.fourcc} video "
                                 f"to {str(self.target)!r}; use --frames to write PNG frames "
                                 "instead")
        if (w, h) != self.size or frame.ndim != 3 or frame.dtype != np.uint8:
            return False
        self._writer.write(np.ascontiguousarray(frame))
        self.frames += 1
        return True

    def commit(self) -> Path:
        """Finishes the file and renames it to ``target``."""
        if self._writer is None:
            self.discard()
            raise ValueError(f"--out: no frame to write to {str(self.target)!r}")
        self._writer.release()
        self._writer = None
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(self._tmp, 0o666 & ~umask)  # mkstemp made it private
        with open(self._tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(self._tmp, self.target)
        return self.target

    def discard(self) -> None:
        """Drops the temporary file (idempotent)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> AtomicVideoWriter:
        return self

    def __exit__(self, *_: Any) -> None:
        self.discard()  # after commit() there is nothing left to drop
