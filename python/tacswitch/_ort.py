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


#: What each export writes as ``tacswitch.kind``, for the error messages.
KINDS = {"tacdiff": "a TacDiff marker-removal model", "motion": "a marker-motion model",
         "slip": "a slip scorer"}


def model_kind(meta: dict[str, str]) -> str | None:
    """The kind of a tacswitch ONNX model from its metadata: ``tacswitch.kind`` when recorded
    (``"tacdiff"``, ``"motion"``), ``"motion"`` for motion models exported before the kind was
    recorded (they carry ``tacswitch.arch`` only), None for any other ONNX file."""
    kind = meta.get("tacswitch.kind")
    if kind:
        return kind
    return "motion" if "tacswitch.arch" in meta else None


def open_session(path: Path, threads: int | None = None,
                 kind: str | None = None) -> tuple[Any, dict[str, str]]:
    """A CPU session of the ONNX file ``path`` and its custom metadata.

    Every failure is a one-line error naming the ``model`` argument: ``FileNotFoundError`` when
    the file is missing, ``ValueError`` when it is not an ONNX model onnxruntime can load (an
    image, a truncated download) or, with ``kind`` given, when its metadata says it is another
    kind of model (a TacDiff model given to motion prediction, or the reverse).
    """
    import onnxruntime as ort

    if not path.is_file():
        raise FileNotFoundError(f"model: no ONNX file at {str(path)!r}")
    try:
        session = ort.InferenceSession(str(path), session_options(threads),
                                       providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own classes (InvalidProtobuf, Fail, ...)
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"model: {str(path)!r} is not an ONNX model onnxruntime can load "
                         f"({type(exc).__name__}: {reason[:160]})") from None
    meta = dict(session.get_modelmeta().custom_metadata_map)
    if kind is not None:
        found = model_kind(meta)
        if found != kind:
            what = KINDS.get(found or "", "not a tacswitch model (no tacswitch.kind metadata)")
            raise ValueError(f"model: {str(path)!r} is {what}; expected {KINDS.get(kind, kind)}")
    return session, meta


def cached(factory: Callable[[Path], T], path: Path) -> T:
    """``factory(path)``, made once per factory, file and process (sessions are not fork-safe,
    hence the pid in the key)."""
    key = (factory, str(path.resolve()), os.getpid())
    with _LOCK:
        obj = _CACHE.get(key)
        if obj is None:
            obj = _CACHE[key] = factory(path)
        return obj  # type: ignore[no-any-return]
