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


def read_image(path: str | os.PathLike[str]) -> NDArray[np.uint8]:
    """Reads an image file as BGR uint8 (``cv2.IMREAD_COLOR``); ``ValueError`` if unreadable."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"path: cannot read an image from {str(path)!r}")
    return cast("NDArray[np.uint8]", img)  # IMREAD_COLOR always decodes to uint8


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
