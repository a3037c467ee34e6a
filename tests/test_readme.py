"""Every ```python block of README.md runs as written; each is also a script in examples/ (the
same code after the script's docstring, so editing one means editing the other); every relative
link in README.md and docs/ points at a file, and heading, that exists.

How blocks are found, run and marked as not runnable here (``<!-- requires: torch -->``,
``<!-- not-tested: the reason -->``): tests/markdown_blocks.py. The blocks of docs/ run in
tests/test_docs_blocks.py.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from markdown_blocks import Block, params, python_blocks, run_block

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
LINK = re.compile(r"\]\(([^)\s]+)\)")

BLOCKS = python_blocks(README, ROOT)


def test_readme_has_python_examples() -> None:
    assert len(BLOCKS) >= 6


@pytest.mark.parametrize("block", params(BLOCKS))
def test_readme_block_runs(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run_block(block, tmp_path, monkeypatch)


def _code_of_example(path: Path) -> str:
    """An example script's code after its module docstring."""
    text = path.read_text(encoding="utf-8")
    assert text.startswith('"""'), f"{path.name}: starts with a docstring"
    return text[text.index('"""', 3) + 3:].lstrip("\n")


def test_examples_are_the_readme_blocks() -> None:
    examples = {p.name: _code_of_example(p) for p in sorted((ROOT / "examples").glob("*.py"))}
    readme = [b.code for b in BLOCKS]
    stale = [name for name, code in examples.items() if code not in readme]
    assert not stale, f"examples/{stale} differ from every README.md block"
    assert len(examples) == len(readme), "one examples/ script per README.md block"


def _slug(heading: str) -> str:
    """GitHub's anchor for a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return {_slug(m) for m in re.findall(r"^#+ (.*)$", text, flags=re.M)}


def _relative_links(path: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return [t for t in LINK.findall(text) if not re.match(r"[a-z]+:", t) and not t.startswith("#")]


@pytest.mark.parametrize("doc", [README, *sorted((ROOT / "docs").rglob("*.md"))],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(doc: Path) -> None:
    missing = []
    for link in _relative_links(doc):
        target, _, anchor = link.partition("#")
        path = (doc.parent / target).resolve()
        if not path.exists() or (anchor and path.suffix == ".md"
                                 and anchor not in _anchors(path)):
            missing.append(link)
    assert not missing, f"{doc.relative_to(ROOT)}: links to missing files or headings {missing}"


def test_readme_stays_short_and_self_contained() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    assert "../shared" not in text and "/work/" not in text


#: The data labels BENCHMARKS.md defines in its intro.
DATA_LABELS = ("real", "real pseudo-markerless", "real + painted",
               "real texture, modelled motion", "simulated")


def test_results_table_labels_every_row() -> None:
    # Every headline figure says what its frames were, with one of BENCHMARKS.md's labels
    # (a speed figure too: the frames it was timed on).
    intro = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8").split("## Contents")[0]
    for label in DATA_LABELS:
        assert f"**{label}**" in intro, label
    text = README.read_text(encoding="utf-8")
    table = text.split("## Results", 1)[1].split("\n## ", 1)[0]
    header = next(r for r in table.splitlines() if r.startswith("| what"))
    column = [c.strip() for c in header.strip().strip("|").split("|")].index("measured on")
    rows = [r for r in table.splitlines() if r.startswith("| ") and not r.startswith("| what")]
    assert len(rows) >= 10
    for row in rows:
        cell = [c.strip() for c in row.strip().strip("|").split("|")][column]
        labels = [m.strip() for m in re.findall(r"\*\*(.+?)\*\*", cell)]
        assert labels and all(lab in DATA_LABELS for lab in labels), row
