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
