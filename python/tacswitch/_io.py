"""File output helpers: every write is atomic (temporary file in the same folder, then rename)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, cast

import numpy as np
from numpy.typing import NDArray


@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO]:
    """Opens a temporary sibling of ``path`` for writing and renames it over ``path`` on success.

    A crash or an exception leaves any previous ``path`` untouched and no partial file behind.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    # mkstemp creates the file private (0600); give it the mode a plain open() would have.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        with os.fdopen(fd, mode) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_image(path: str | os.PathLike[str], img: NDArray[np.uint8]) -> Path:
    """Encodes ``img`` (BGR or grey uint8) by the file extension and writes it atomically."""
    import cv2

    target = Path(path)
    ok, buf = cv2.imencode(target.suffix or ".png", img)
    if not ok:
        raise ValueError(f"path: cannot encode an image as {target.suffix!r}")
    with atomic_open(target, "wb") as fh:
        fh.write(buf.tobytes())
    return target


@contextmanager
def stderr_silenced() -> Iterator[None]:
    """Sends the process's file descriptor 2 to the null device for the block.

    libpng prints ``libpng error: ...`` on stderr itself when OpenCV decodes a damaged PNG,
    past OpenCV's log level; the callers report unreadable files in their own words. Use it
    on one thread, around the call that may print (not around work that reports errors).
    """
    import sys

    try:
        fd = sys.__stderr__.fileno() if sys.__stderr__ is not None else 2
    except (AttributeError, OSError, ValueError):
        fd = 2
    try:
        saved = os.dup(fd)
    except OSError:  # no descriptor 2 (a detached process): nothing to silence
        yield
        return
    try:
        if sys.stderr is not None:
            sys.stderr.flush()
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, fd)
        finally:
            os.close(null)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


def try_read_image(path: str | os.PathLike[str], *,
                   quiet: bool = False) -> NDArray[np.uint8] | None:
    """Reads an image file as BGR uint8 (``cv2.IMREAD_COLOR``), or None if it is missing,
    damaged or not an image. ``quiet``: keep the decoder's own messages off the terminal
    (:func:`stderr_silenced`; the command line, which reads on one thread)."""
    import cv2

    if not quiet:
        return cast("NDArray[np.uint8] | None", cv2.imread(str(path), cv2.IMREAD_COLOR))
    with stderr_silenced():
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    return cast("NDArray[np.uint8] | None", img)


def read_image(path: str | os.PathLike[str], name: str = "path", *,
               quiet: bool = False) -> NDArray[np.uint8]:
    """Reads an image file as BGR uint8 (``cv2.IMREAD_COLOR``); ``ValueError`` naming ``name``
    if it cannot be read (missing, damaged, not an image). ``quiet``: as
    :func:`try_read_image`."""
    img = try_read_image(path, quiet=quiet)
    if img is None:
        raise ValueError(f"{name}: cannot read an image from {str(path)!r}")
    return img


def write_onnx(tmp: Path, target: str | os.PathLike[str], meta: dict[str, str],
               extra: dict[str, object] | None = None) -> Path:
    """Moves the ONNX file a ``torch.onnx.export`` wrote to ``tmp`` onto ``target``
    (atomically), with ``meta`` and ``extra`` (keys prefixed ``tacswitch.``, non-strings as
    JSON) as its only metadata. Needs the ``onnx`` package (export time only)."""
    import json

    import onnx

    model = onnx.load(str(tmp))
    tmp.unlink()
    props = dict(meta)
    for k, v in (extra or {}).items():
        props[f"tacswitch.{k}"] = v if isinstance(v, str) else json.dumps(v)
    del model.metadata_props[:]
    for k, v in props.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    with atomic_open(target, "wb") as fh:
        fh.write(model.SerializeToString())
    return Path(target)


def save_torch(path: Path, state: dict[str, object]) -> None:
    """``torch.save(state)`` to ``path`` atomically (a resumable run's checkpoint is never left
    half-written). Needs torch (training only)."""
    import torch

    tmp = path.with_name(f".{path.name}.tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)
