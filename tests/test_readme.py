"""Every ```python block of README.md runs as written; each is also a script in examples/ (the
same code after the script's docstring, so editing one means editing the other); every relative
link in README.md and docs/*.md points at a file, and heading, that exists.

A block can be left out only with an HTML comment on the line just before its fence,
``<!-- not-tested: the reason -->`` (for what the test environment cannot run, e.g. torch or a
GPU); each such block is reported as skipped with its reason.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
NOT_TESTED = re.compile(r"<!--\s*not-tested:\s*(.*?)\s*-->")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def python_blocks(text: str) -> list[tuple[int, str, str | None]]:
    """(first line number, code, skip reason or None) of every ```python block of ``text``."""
    lines = text.splitlines()
    blocks: list[tuple[int, str, str | None]] = []
    i = 0
    while i < len(lines):
        if lines[i].strip() == "```python":
            start = i + 1
            end = start
            while end < len(lines) and lines[end].strip() != "```":
                end += 1
            if end == len(lines):
                raise AssertionError(f"README.md:{i + 1}: ```python block is never closed")
            before = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            m = NOT_TESTED.search(before)
            blocks.append((start + 1, "\n".join(lines[start:end]) + "\n",
                           m.group(1) if m else None))
            i = end
        i += 1
    return blocks


BLOCKS = python_blocks(README.read_text(encoding="utf-8"))


def test_readme_has_python_examples() -> None:
    assert len(BLOCKS) >= 6


@pytest.mark.parametrize(("line", "code", "skip"), BLOCKS,
                         ids=[f"README.md:{line}" for line, _, _ in BLOCKS])
def test_readme_block_runs(line: int, code: str, skip: str | None, tmp_path: Path,
                           monkeypatch: pytest.MonkeyPatch) -> None:
    if skip is not None:
        pytest.skip(f"README.md:{line}: {skip}")
    monkeypatch.chdir(tmp_path)  # whatever a block writes lands in a temporary folder
    compiled = compile(code, f"README.md:{line}", "exec")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compiled, {"__name__": "__readme__"})


def _code_of_example(path: Path) -> str:
    """An example script's code after its module docstring."""
    text = path.read_text(encoding="utf-8")
    assert text.startswith('"""'), f"{path.name}: starts with a docstring"
    return text[text.index('"""', 3) + 3:].lstrip("\n")


def test_examples_are_the_readme_blocks() -> None:
    examples = {p.name: _code_of_example(p) for p in sorted((ROOT / "examples").glob("*.py"))}
    readme = [code for _, code, _ in BLOCKS]
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


@pytest.mark.parametrize("doc", [README, *sorted((ROOT / "docs").glob("*.md"))],
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
