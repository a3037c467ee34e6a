"""Every ```python block of docs/ runs as written, on its own (tests/markdown_blocks.py says how
a block that needs the train extra, or cannot run here at all, is marked)."""

from __future__ import annotations

from pathlib import Path

import pytest
from markdown_blocks import Block, params, python_blocks, run_block

ROOT = Path(__file__).resolve().parents[1]
BLOCKS = [b for doc in sorted((ROOT / "docs").rglob("*.md")) for b in python_blocks(doc, ROOT)]


def test_docs_have_python_blocks() -> None:
    assert len(BLOCKS) >= 10


def test_every_block_that_is_not_run_says_why() -> None:
    # A not-tested comment with an empty reason would hide a block silently.
    assert all(b.skip is None or b.skip.strip() for b in BLOCKS)


@pytest.mark.parametrize("block", params(BLOCKS))
def test_docs_block_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run_block(block, tmp_path, monkeypatch)


def test_markers_and_failures_are_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    md = tmp_path / "guide.md"
    md.write_text("<!-- requires: no_such_module_here -->\n```python\nraise SystemExit(1)\n```\n\n"
                  "<!-- not-tested: needs a GPU -->\n\n```python\nraise SystemExit(1)\n```\n"
                  "```python\nx = 1\n```\n```python\nprint(x)\n```\n")
    blocks = python_blocks(md, tmp_path)
    assert [(b.name, b.requires, b.skip) for b in blocks] == [
        ("guide.md:3", ("no_such_module_here",), None), ("guide.md:9", (), "needs a GPU"),
        ("guide.md:12", (), None), ("guide.md:15", (), None)]
    for block, reason in zip(blocks[:2], ["needs no_such", "not tested: needs a GPU"], strict=True):
        with pytest.raises(pytest.skip.Exception, match=reason):
            run_block(block, tmp_path, monkeypatch)
    run_block(blocks[2], tmp_path, monkeypatch)
    with pytest.raises(NameError):  # each block runs on its own: x is not defined here
        run_block(blocks[3], tmp_path, monkeypatch)
