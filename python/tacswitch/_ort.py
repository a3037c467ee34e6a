"""onnxruntime plumbing shared by the shipped models: tuned sessions on the CPU or a CUDA GPU
(:func:`providers`) and a per-process cache.

Imports onnxruntime only when a session is made, so importing this module is free.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")

_CACHE: dict[tuple[Any, str, str, int], Any] = {}

#: What ``device=`` takes on the model entry points (and ``--device`` on the CLI).
DEVICES = ("auto", "cpu", "cuda")
CUDA, CPU = "CUDAExecutionProvider", "CPUExecutionProvider"


def providers(device: str = "auto") -> list[str]:
    """onnxruntime's execution providers for ``device``, in order of preference.

    ``"auto"``: CUDA then the CPU when onnxruntime offers ``CUDAExecutionProvider`` (the
    ``onnxruntime-gpu`` package with a CUDA runtime it can load), else the CPU alone;
    ``"cpu"``: the CPU alone (the same session as before ``device`` existed); ``"cuda"``: CUDA
    then the CPU (nodes CUDA cannot run fall back to the CPU), a one-line ``ValueError`` naming
    ``device`` when onnxruntime does not offer CUDA here.
    """
    if not isinstance(device, str) or device not in DEVICES:
        raise ValueError(f"device: must be 'auto', 'cpu' or 'cuda'; got {device!r}")
    if device == "cpu":
        return [CPU]
    import onnxruntime as ort

    available = ort.get_available_providers()
    if CUDA in available:
        return [CUDA, CPU]
    if device == "cuda":
        raise ValueError(f"device: 'cuda' needs onnxruntime's CUDAExecutionProvider, which this "
                         f"onnxruntime {ort.__version__} does not offer (it has "
                         f"{', '.join(available)}); pip install onnxruntime-gpu in place of "
                         "onnxruntime on a machine with CUDA, or run on the CPU ('auto' or 'cpu')")
    return [CPU]
_LOCK = threading.Lock()


def session_options(threads: int | None = None) -> Any:
    """onnxruntime options tuned for small CPU models: ``threads`` intra-op threads (default
    ``os.cpu_count()``), one inter-op thread, sequential execution, no spin-waiting (spinning
    threads would steal the cores the camera and control loops run on between frames)."""
    import onnxruntime as ort

    from tacswitch._checks import as_count

    so = ort.SessionOptions()
    # None or 0: every core (0 is onnxruntime's own "default").
    n = 0 if threads is None else as_count(threads, "threads", 0, 1024)
    so.intra_op_num_threads = n or os.cpu_count() or 1
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


def open_session(path: Path, threads: int | None = None, kind: str | None = None,
                 device: str = "auto") -> tuple[Any, dict[str, str]]:
    """A session of the ONNX file ``path`` on ``device`` (:func:`providers`) and its custom
    metadata.

    Every failure is a one-line error naming the ``model`` argument: ``FileNotFoundError`` when
    the file is missing, ``ValueError`` when it is not an ONNX model onnxruntime can load (an
    image, a truncated download) or, with ``kind`` given, when its metadata says it is another
    kind of model (a TacDiff model given to motion prediction, or the reverse).
    """
    import onnxruntime as ort

    chosen = providers(device)  # a bad device fails before the file is read
    if not path.is_file():
        raise FileNotFoundError(f"model: no ONNX file at {str(path)!r}")
    try:
        session = ort.InferenceSession(str(path), session_options(threads),
                                       providers=chosen)
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


def cached(factory: Callable[..., T], path: Path, device: str = "auto") -> T:
    """``factory(path, device=device)``, made once per factory, file, device and process
    (sessions are not fork-safe, hence the pid in the key)."""
    key = (factory, str(path.resolve()), device, os.getpid())
    with _LOCK:
        obj = _CACHE.get(key)
        if obj is None:
            obj = _CACHE[key] = factory(path, device=device)
        return obj  # type: ignore[no-any-return]
