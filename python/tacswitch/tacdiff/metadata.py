"""Rewriting the ``tacswitch.*`` metadata of an exported TacDiff model, weights untouched.

Used to record an inference setting on a shipped model without retraining or re-exporting it,
e.g. the TELEA radius of its prior (``tacswitch.prior_radius``, read by
:func:`tacswitch.tacdiff.infer.prior_radius`). Needs the ``onnx`` package (the ``train`` extra).
"""

from __future__ import annotations

import os
from pathlib import Path


def set_metadata(path: str | os.PathLike[str], updates: dict[str, str | None]) -> Path:
    """Sets (or, for a None value, removes) metadata entries of the ONNX model at ``path`` in
    place, atomically; the graph and its weights are written back byte for byte (checked).

    Raises:
        ValueError: ``updates`` names a key outside ``tacswitch.*`` or a non-string value, or
            ``path`` is not a TacDiff model.
    """
    import onnx

    from tacswitch._io import atomic_open

    for k, v in updates.items():
        if not (isinstance(k, str) and k.startswith("tacswitch.")):
            raise ValueError(f"updates: keys must start with 'tacswitch.'; got {k!r}")
        if v is not None and not isinstance(v, str):
            raise ValueError(f"updates: {k!r} must map to a string or None; got {v!r}")
    target = Path(path)
    model = onnx.load(str(target))
    props = {p.key: p.value for p in model.metadata_props}
    if props.get("tacswitch.kind") != "tacdiff":
        raise ValueError(f"path: {str(target)!r} is not a TacDiff model")
    graph = model.graph.SerializeToString()
    for k, v in updates.items():
        if v is None:
            props.pop(k, None)
        else:
            props[k] = v
    del model.metadata_props[:]
    for k, v in props.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    if model.graph.SerializeToString() != graph:  # pragma: no cover - protobuf invariant
        raise RuntimeError("set_metadata changed the graph")
    with atomic_open(target, "wb") as fh:
        fh.write(model.SerializeToString())
    return target
