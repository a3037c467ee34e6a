"""Which outputs in a folder were made with which options, so a rerun resumes only its own.

A command that skips existing outputs (an interrupted run resumes) records, per output, the
options that shaped it and the input it was made from (its resolved path, size and modification
time) in ``OUT/.tacswitch-COMMAND.json`` (written atomically). A rerun with other options
(another ``--method``, ``--radius``, ...) or from another input of the same name (every
experiment of a dataset holds a ``camera_0.avi``) then redoes those outputs instead of
reporting them "already done"; an output with no record (a folder from an older version, or
one written just before a hard kill) is redone too.

The record is saved every :data:`SAVE_EVERY_S` seconds and when the run ends, an interrupted
one included, so recording costs nothing noticeable on folders of thousands of images.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from types import TracebackType
from typing import Any

#: Bumped if the manifest's layout changes (an unknown layout counts as no record). 2: each
#: output's entry also names its input (2026-12-02).
VERSION = 2
#: Seconds between saves of the record during a run.
SAVE_EVERY_S = 2.0


def manifest_path(out: Path, command: str) -> Path:
    """The record of ``command``'s outputs in the folder ``out``."""
    return out / f".tacswitch-{command}.json"


def options_key(options: dict[str, Any]) -> str:
    """A short digest of ``options`` (JSON values), the same for equal options."""
    text = json.dumps(options, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def source_stamp(source: Path) -> str:
    """A short digest of the input ``source``: its resolved path, size and modification time
    (a file replaced or edited since reads as another input); the path alone if it cannot be
    read."""
    try:
        st = source.stat()
        text = f"{source.resolve()}|{st.st_size}|{st.st_mtime_ns}"
    except OSError:
        text = str(source)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


class OutputRecord:
    """The record of one run's outputs in ``out``: :meth:`made_here` tells whether an existing
    output was made from the same input with this run's ``options``; :meth:`add` records one
    just written. Use it as a context manager (the record is saved on leaving, also on an error
    or Ctrl-C)."""

    def __init__(self, out: Path, command: str, options: dict[str, Any]) -> None:
        self.out = out
        self.path = manifest_path(out, command)
        self.options = options
        self.key = options_key(options)
        self.outputs: dict[str, str] = {}
        self.known: dict[str, Any] = {}
        try:
            data = json.loads(self.path.read_text())
        except (OSError, ValueError):
            data = None
        if isinstance(data, dict) and data.get("version") == VERSION:
            self.outputs = {str(k): str(v) for k, v in dict(data.get("outputs", {})).items()}
            self.known = dict(data.get("options", {}))
        self._dirty = False
        self._saved = time.monotonic()

    def _name(self, target: Path) -> str:
        return target.relative_to(self.out).as_posix()

    def _entry(self, source: Path) -> str:
        return f"{self.key}:{source_stamp(source)}"

    def made_here(self, target: Path, source: Path) -> bool:
        """Whether ``target`` exists and was recorded as made from ``source`` with this run's
        options."""
        return target.exists() and self.outputs.get(self._name(target)) == self._entry(source)

    def add(self, target: Path, source: Path) -> None:
        """Records ``target`` as made from ``source`` with this run's options (saved every few
        seconds)."""
        self.outputs[self._name(target)] = self._entry(source)
        self._dirty = True
        if time.monotonic() - self._saved >= SAVE_EVERY_S:
            self.save()

    def save(self) -> None:
        """Writes the record (atomically) if anything changed; option sets no output uses any
        more are dropped."""
        from tacswitch._io import atomic_open

        if not self._dirty:
            return
        used = {entry.split(":", 1)[0] for entry in self.outputs.values()}
        options = {k: v for k, v in self.known.items() if k in used}
        options[self.key] = self.options
        with atomic_open(self.path) as fh:
            json.dump({"version": VERSION, "options": options,
                       "outputs": dict(sorted(self.outputs.items()))}, fh, indent=1)
        self._dirty = False
        self._saved = time.monotonic()

    def __enter__(self) -> OutputRecord:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.save()
