"""The ```python blocks of a Markdown file, and running one as a reader would paste it.

Every block runs on its own, in a fresh namespace, in a temporary working folder: a block that
uses a name it does not define fails, as it would for a reader.

An HTML comment on the line just before a block's fence (blank lines allowed between) changes how
it is tested:

- ``<!-- requires: torch, onnx -->``: the block needs these optional modules (the ``train`` extra);
  it runs when they import and is skipped with that reason when they do not. Such blocks carry
  the ``train`` marker, so ``python -m pytest -m train`` runs them after ``pip install ".[train]"``.
- ``<!-- not-tested: the reason -->``: never run (e.g. a GPU, a long training run, real data the
  repository does not hold); reported as skipped with the reason.

A block without either comment must run in the test install (``pip install ".[test]"``) within a
few seconds.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

NOT_TESTED = re.compile(r"<!--\s*not-tested:\s*(.*?)\s*-->")
REQUIRES = re.compile(r"<!--\s*requires:\s*(.*?)\s*-->")


@dataclass(frozen=True)
class Block:
    """One ```python block: where it is, its code and how it is tested."""

    name: str  # "docs/api.md:22" (path relative to the repository, line of the first code line)
    code: str
    skip: str | None  # the not-tested reason, if any
    requires: tuple[str, ...]  # modules the block needs beyond the test install


def python_blocks(path: Path, root: Path) -> list[Block]:
    """Every ```python block of the Markdown file ``path`` (named relative to ``root``)."""
    rel = path.relative_to(root).as_posix()
    lines = path.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        if lines[i].strip() == "```python":
            start = i + 1
            end = start
            while end < len(lines) and lines[end].strip() != "```":
                end += 1
            if end == len(lines):
                raise AssertionError(f"{rel}:{i + 1}: ```python block is never closed")
            before = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            skip = NOT_TESTED.search(before)
            req = REQUIRES.search(before)
            blocks.append(Block(
                name=f"{rel}:{start + 1}",
                code="\n".join(lines[start:end]) + "\n",
                skip=skip.group(1) if skip else None,
                requires=tuple(m.strip() for m in req.group(1).split(",") if m.strip())
                if req else (),
            ))
            i = end
        i += 1
    return blocks


def params(blocks: list[Block]) -> list[object]:
    """``pytest.param`` per block, id = its name; blocks with ``requires`` get the train marker."""
    return [pytest.param(b, id=b.name, marks=[pytest.mark.train] if b.requires else [])
            for b in blocks]


def run_block(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Runs ``block`` in a fresh namespace with ``tmp_path`` as the working folder.

    Skips, with the reason, a not-tested block or one whose required modules are missing.
    """
    if block.skip is not None:
        pytest.skip(f"{block.name}: not tested: {block.skip}")
    missing = [m for m in block.requires if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"{block.name}: needs {', '.join(missing)} (pip install \".[train]\")")
    monkeypatch.chdir(tmp_path)  # whatever a block writes lands in a temporary folder
    compiled = compile(block.code, block.name, "exec")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compiled, {"__name__": "__doc_block__"})
