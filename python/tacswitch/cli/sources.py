"""Frame sources shared by the streaming commands: video files, image folders, cameras."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}
VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v"}

#: Consecutive unreadable frames after which a camera counts as disconnected.
MAX_FAILED_READS = 30


def collect_images(inputs: list[str]) -> list[Path]:
    """Image files named or found (sorted) in the named folders; ``FileNotFoundError`` if none."""
    files: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            files += sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        elif path.is_file():
            files.append(path)
        else:
            raise FileNotFoundError(f"input {item!r} does not exist")
    if not files:
        raise FileNotFoundError("no images found in the inputs")
    return files


def frames(source: str) -> Iterator[np.ndarray | None]:
    """Yields BGR frames from a folder, a video or a camera index; None for an unreadable frame.

    Raises ``FileNotFoundError``/``ValueError`` naming ``source`` when it cannot be opened, and
    ``ConnectionError`` when a camera stops delivering frames.
    """
    import cv2

    path = Path(source)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise FileNotFoundError(f"source: no images in folder {source!r}")
        for f in files:
            yield cv2.imread(str(f), cv2.IMREAD_COLOR)
        return
    if source.isdigit():
        cap = cv2.VideoCapture(int(source))
        if not cap.isOpened():
            raise FileNotFoundError(f"source: cannot open camera {source}")
    else:
        if not path.is_file():
            raise FileNotFoundError(f"source: {source!r} is not a file, folder or camera index")
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise ValueError(f"source: cannot decode video {source!r}")
    failed = 0
    try:
        while True:
            ok, frame = cap.read()
            if ok:
                failed = 0
                yield frame
                continue
            if not source.isdigit():
                return  # end of the video file
            failed += 1
            if failed >= MAX_FAILED_READS:
                raise ConnectionError(f"camera {source} stopped delivering frames")
            yield None
    finally:
        cap.release()


