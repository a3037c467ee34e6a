"""onnxruntime plumbing shared by the shipped models: tuned CPU sessions and a per-process cache.

Imports onnxruntime only when a session is made, so importing this module is free.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")

_CACHE: dict[tuple[Any, str, int], Any] = {}
_LOCK = threading.Lock()


def session_options(threads: int | None = None) -> Any:
    """onnxruntime options tuned for small CPU models: ``threads`` intra-op threads (default
    ``os.cpu_count()``), one inter-op thread, sequential execution, no spin-waiting (spinning
    threads would steal the cores the camera and control loops run on between frames)."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = int(threads or os.cpu_count() or 1)
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.add_session_config_entry("session.intra_op.allow_spinning", "0")
    so.add_session_config_entry("session.inter_op.allow_spinning", "0")
    return so


def open_session(path: Path, threads: int | None = None) -> tuple[Any, dict[str, str]]:
    """A CPU session of the ONNX file ``path`` and its custom metadata; ``FileNotFoundError``
    naming the ``model`` argument when the file is missing."""
    import onnxruntime as ort

    if not path.is_file():
        raise FileNotFoundError(f"model: no ONNX file at {str(path)!r}")
    session = ort.InferenceSession(str(path), session_options(threads),
                                   providers=["CPUExecutionProvider"])
    return session, dict(session.get_modelmeta().custom_metadata_map)


def cached(factory: Callable[[Path], T], path: Path) -> T:
    """``factory(path)``, made once per factory, file and process (sessions are not fork-safe,
    hence the pid in the key)."""
    key = (factory, str(path.resolve()), os.getpid())
    with _LOCK:
        obj = _CACHE.get(key)
        if obj is None:
            obj = _CACHE[key] = factory(path)
        return obj  # type: ignore[no-any-return]
