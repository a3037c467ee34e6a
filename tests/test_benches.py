"""The bench suite holds together: every BENCHMARKS.md section is made by exactly one runner
section, every script a section or a document names exists, the studies still start, and the
runner (``python -m benches``) lists, refuses unknown names and runs a quick section."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from sections import SECTIONS, SUPPORT  # benches/ is on the path: tests/conftest.py

ROOT = Path(__file__).resolve().parents[1]
BENCHES = ROOT / "benches"


def headings() -> list[str]:
    text = (ROOT / "BENCHMARKS.md").read_text()
    return [h for h in re.findall(r"^## .+$", text, flags=re.M) if h != "## Contents"]


def test_every_benchmarks_section_is_made_by_exactly_one_runner_section() -> None:
    made = [s.heading for s in SECTIONS if s.heading is not None]
    for h in headings():
        assert made.count(h) == 1, f"{h!r} is made by {made.count(h)} runner sections"
    missing = set(made) - set(headings())
    assert not missing, f"runner sections name headings BENCHMARKS.md lacks: {missing}"
    names = [s.name for s in SECTIONS]
    assert len(names) == len(set(names))


def test_every_section_script_exists_and_every_bench_file_has_a_place() -> None:
    scripts = {step[0] for s in SECTIONS for step in (*s.commands, *(s.quick or ()))
               if step[0] != "-m"}
    for name in scripts:
        assert (BENCHES / name).is_file(), name
    for s in SECTIONS:
        if s.update is not None:
            assert s.update[0] in {step[0] for step in s.commands}, s.name
    on_disk = {p.name for p in BENCHES.iterdir() if p.suffix in (".py", ".sh")}
    loose = on_disk - scripts - set(SUPPORT)
    assert not loose, f"bench files that are neither a section's, support nor a study: {loose}"
    studies = {p.name for p in (BENCHES / "studies").glob("*.py")}
    listed = (BENCHES / "studies" / "README.md").read_text()
    for name in studies:
        assert f"`{name}`" in listed, f"benches/studies/README.md does not list {name}"


def test_every_bench_path_named_in_the_documents_exists() -> None:
    docs = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *ROOT.glob("docs/**/*.md"),
            *ROOT.glob("python/tacswitch/**/*.md"), *ROOT.glob("python/tacswitch/**/*.py")]
    for doc in docs:
        for path in set(re.findall(r"benches/[\w/]+\.(?:py|sh)", doc.read_text())):
            assert (ROOT / path).is_file(), f"{doc.relative_to(ROOT)} names {path}"


@pytest.mark.parametrize("script", sorted(p.name for p in (BENCHES / "studies").glob("*.py")))
def test_a_study_still_starts(script: str) -> None:
    # --help imports the script and its helpers (harness, sibling studies) from benches/studies/.
    res = subprocess.run([sys.executable, str(BENCHES / "studies" / script), "--help"],
                         capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert res.returncode == 0, res.stderr[-2000:]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "benches", *args], capture_output=True,
                          text=True, timeout=300, cwd=ROOT)


def test_runner_lists_every_section() -> None:
    res = run()
    assert res.returncode == 0
    for s in SECTIONS:
        assert re.search(rf"^{re.escape(s.name)}$", res.stdout, flags=re.M), s.name


def test_runner_refuses_an_unknown_section() -> None:
    res = run("no-such-section")
    assert res.returncode == 2 and "no-such-section" in res.stderr


def test_runner_runs_a_quick_section() -> None:
    res = run("merge", "--quick")
    assert res.returncode == 0, res.stderr[-2000:]
    assert "| tile |" in res.stdout  # the patch-merging table
    assert "== merge: exit 0" in res.stderr


def test_every_benchmarks_section_and_readme_result_names_its_runner_section() -> None:
    names = {s.name for s in SECTIONS}
    text = (ROOT / "BENCHMARKS.md").read_text()
    for s in SECTIONS:
        if s.heading is None or s.heading + "\n" not in text:
            continue  # a missing heading fails the test above
        body = text.split(s.heading + "\n", 1)[1].split("\n## ", 1)[0]
        assert f"Bench section: `python -m benches {s.name}`" in body, s.heading
    readme = (ROOT / "README.md").read_text()
    table = readme.split("## Results", 1)[1].split("\n## ", 1)[0]
    rows = [r for r in table.splitlines() if r.startswith("| ") and not r.startswith("| what")]
    assert rows
    for row in rows:
        named = re.findall(r"`([a-z-]+)` \|$", row)
        assert named and named[0] in names, f"README result row names no bench section: {row}"


def test_a_section_update_keeps_the_text_written_around_its_table(tmp_path: Path) -> None:
    from harness import update_markdown

    doc = tmp_path / "B.md"
    doc.write_text("# Benchmarks\n\n## A\n\nBench section: `a`\n\nReading by hand.\n\n"
                   "Data: old\n\n| x |\n|---|\n| 1 |\n\nCommand: `python a.py` (notes)\n\n"
                   "After by hand.\n\n### Sub\n\nkept\n\n## B\n\nother\n")
    update_markdown("## A", "Data: new\n\n| x |\n|---|\n| 2 |\n\nCommand: `python a.py`", doc)
    text = doc.read_text()
    assert text == ("# Benchmarks\n\n## A\n\nBench section: `a`\n\nReading by hand.\n\n"
                    "Data: new\n\n| x |\n|---|\n| 2 |\n\nCommand: `python a.py`\n\n"
                    "After by hand.\n\n### Sub\n\nkept\n\n## B\n\nother\n")
    update_markdown("## C", "Data: c\n\nCommand: `python c.py`", doc)
    assert doc.read_text().endswith("## B\n\nother\n\n## C\n\nData: c\n\nCommand: `python c.py`\n")
