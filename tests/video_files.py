"""Writing and decoding small video files for the tests that feed videos (no shared data)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def write_video(path: Path, frames: list[np.ndarray], fourcc: str = "MJPG",
                fps: int = 25) -> Path:
    """Writes BGR ``frames`` to ``path`` with OpenCV (codec ``fourcc``); returns ``path``."""
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*fourcc), fps, (w, h))
    assert writer.isOpened(), f"OpenCV cannot write {fourcc} to {path}"
    for f in frames:
        writer.write(f)
    writer.release()
    return path


def decode(path: Path) -> list[np.ndarray]:
    """Every frame OpenCV decodes from ``path``, in order."""
    cap = cv2.VideoCapture(str(path))
    assert cap.isOpened(), f"OpenCV cannot open {path}"
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    return frames


def frame_rate(path: Path) -> float:
    """The frame rate OpenCV reads from ``path``'s container, frames/s."""
    cap = cv2.VideoCapture(str(path))
    assert cap.isOpened(), f"OpenCV cannot open {path}"
    fps = float(cap.get(cv2.CAP_PROP_FPS))
    cap.release()
    return fps
