"""The bench suite's runner: ``python -m benches [NAME ...] [--quick] [--update] [--list]``.

Run from the repository root. With no name it lists the sections (``benches/sections.py``):
each one's BENCHMARKS.md heading, commands and what it needs. ``NAME ...`` runs those sections
in order (``all``: every section); ``--quick`` runs each one's smoke version instead (a section
without one is skipped, saying so); ``--update`` lets the section's publishing script rewrite
its part of BENCHMARKS.md (sections curated by hand print their tables only, saying so).
Exit status: 0 when every step ran and passed, 1 when one failed, 2 for an unknown name.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from sections import SECTIONS, Section, by_name  # noqa: E402


def argv(step: tuple[str, ...]) -> list[str]:
    """The command line of one step, run from the repository root."""
    if step[0] == "-m":
        return [sys.executable, *step]
    return [sys.executable, str(HERE / step[0]), *step[1:]]


def steps(section: Section, quick: bool, update: bool) -> list[tuple[str, ...]]:
    """The steps of ``section`` for this run (empty: nothing to run in this mode)."""
    chosen = section.quick if quick else section.commands
    if not chosen:
        return []
    out = []
    for step in chosen:
        if update and section.update and step[0] == section.update[0]:
            step = (*step, section.update[1])
        out.append(step)
    return out


def describe() -> str:
    lines = ["Sections (python -m benches NAME [--quick] [--update]; 'all' runs every one):", ""]
    for s in SECTIONS:
        lines.append(f"{s.name}")
        where = s.heading[3:] if s.heading else "(a guide, not BENCHMARKS)"
        lines.append(f"    BENCHMARKS.md: {where}")
        for step in s.commands:
            shown = step if step[0] == "-m" else (f"benches/{step[0]}", *step[1:])
            lines.append(f"    run:   {shlex.join(shown)}")
        lines.append(f"    quick: {'yes' if s.quick else 'no'};  --update: "
                     f"{'writes BENCHMARKS.md' if s.update else 'curated by hand (prints)'}")
        if s.needs:
            lines.append(f"    needs: {s.needs}")
    lines += ["", "One-off studies (not sections): benches/studies/README.md"]
    return "\n".join(lines)


def main(args: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benches", description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help="sections to run ('all': every one)")
    ap.add_argument("--quick", action="store_true", help="the smoke version of each section")
    ap.add_argument("--update", action="store_true",
                    help="let publishing sections rewrite their part of BENCHMARKS.md")
    ap.add_argument("--list", action="store_true", help="list the sections (the default)")
    a = ap.parse_args(args)
    if a.list or not a.names:
        print(describe())
        return 0
    known = by_name()
    names = list(known) if a.names == ["all"] else a.names
    unknown = [n for n in names if n not in known]
    if unknown:
        print(f"python -m benches: unknown section(s) {unknown}; choose from "
              f"{['all', *known]}", file=sys.stderr)
        return 2
    failed = []
    for name in names:
        section = known[name]
        todo = steps(section, a.quick, a.update)
        if not todo:
            print(f"== {name}: no quick version; skipped", file=sys.stderr)
            continue
        if a.update and not section.update:
            print(f"== {name}: curated by hand; the tables are printed, not written",
                  file=sys.stderr)
        for step in todo:
            cmd = argv(step)
            print(f"== {name}: {shlex.join(cmd[1:])}", file=sys.stderr, flush=True)
            t0 = time.perf_counter()
            rc = subprocess.call(cmd, cwd=HERE.parent)
            print(f"== {name}: exit {rc} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
            if rc != 0:
                failed.append(name)
                break
    if failed:
        print(f"python -m benches: failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
