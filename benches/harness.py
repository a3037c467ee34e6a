"""Shared timing harness for the benchmarks: warm-up, GC off, medians and spread, Markdown rows.

Run benchmarks on an otherwise idle machine; they print ratios against the peer measured in the
same run, which survive a noisy machine far better than absolute times.
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import statistics
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass
class Timing:
    """Per-call times of one function, seconds."""

    samples: list[float]

    @property
    def median(self) -> float:
        return statistics.median(self.samples)

    @property
    def iqr(self) -> tuple[float, float]:
        q = statistics.quantiles(self.samples, n=4)
        return q[0], q[2]

    def fmt(self, unit: str = "ms") -> str:
        k = {"ms": 1e3, "us": 1e6}[unit]
        lo, hi = self.iqr
        return f"{self.median * k:.3f} {unit} [{lo * k:.3f}, {hi * k:.3f}]"


def measure(fn: Callable[[], object], *, repeat: int = 200, inner: int = 1,
            warmup: int = 10) -> Timing:
    """Times ``fn``: ``warmup`` untimed calls, then ``repeat`` samples of ``inner`` calls each."""
    for _ in range(warmup):
        fn()
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        samples = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            for _ in range(inner):
                fn()
            samples.append((time.perf_counter() - t0) / inner)
    finally:
        if was_enabled:
            gc.enable()
    return Timing(samples)


def interleaved(fns: dict[str, Callable[[], object]], *, rounds: int = 15, repeat: int = 20,
                inner: int = 1) -> dict[str, Timing]:
    """Times several functions in alternating rounds so machine noise hits them alike."""
    out: dict[str, list[float]] = {k: [] for k in fns}
    for fn in fns.values():
        for _ in range(5):
            fn()
    for _ in range(rounds):
        for name, fn in fns.items():
            out[name] += measure(fn, repeat=repeat, inner=inner, warmup=1).samples
    return {k: Timing(v) for k, v in out.items()}


def single_thread() -> None:
    """Pins OpenCV, rayon and BLAS to one thread (call before the first measurement)."""
    os.environ.setdefault("RAYON_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import cv2

    cv2.setNumThreads(1)


def machine() -> str:
    """One line: CPU, cores, Python, OpenCV, commit."""
    import cv2
    import numpy as np

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=Path(__file__).parent).stdout.strip()
    except OSError:
        commit = "?"
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numpy {np.__version__}, OpenCV {cv2.__version__}, commit {commit}")


def table(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


#: Columns of the markerless-motion accuracy tables (:func:`motion_row`); the first names the
#: data and its reference.
MOTION_COLUMNS = ["method", "e_rmse mean (px)", "e_mag mean (px)", "NaN %", "cos",
                  "within 30 deg %", "min px", "frames / moved", "ms / frame (busy)"]


def motion_row(data: str, method: str, m: dict[str, float], min_px: float, frames: int,
               ms: float) -> list[str]:
    """One row of a markerless-motion accuracy table (:data:`MOTION_COLUMNS` after ``data``)
    from :func:`tacswitch.motion.evaluate.motion_metrics`' output ``m``."""
    return [data, method, f"{m['e_rmse_mean']:.3f}", f"{m['e_mag_mean']:.3f}",
            f"{m['nan_pct']:.0f}", f"{m['cos_mean']:.2f}", f"{m['within30_pct']:.0f}",
            f"{min_px:.2f}", f"{frames} / {m['n_orient']}", f"{ms:.0f}"]


def update_markdown(section: str, body: str, path: Path | None = None) -> None:
    """Replaces (or appends) ``section`` in BENCHMARKS.md (or ``path``), leaving other sections
    alone. Within the section, the text written by hand around the generated ``body`` stays:
    what comes before the line where the old body began (the first line starting as ``body``'s
    first line does, up to its first colon) and after the old body's command line (the last
    line starting as ``body``'s last ``Command: `...``` line does: readings, ``###``
    subsections). The file is replaced atomically, so an interrupted run never truncates it."""
    path = Path(__file__).resolve().parents[1] / "BENCHMARKS.md" if path is None else path
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    body = body.strip()
    start = text.find(section + "\n")
    if start < 0:
        text = text.rstrip("\n") + "\n\n" + f"{section}\n\n{body}\n"
    else:
        nxt = text.find("\n## ", start + len(section))
        old = text[start:nxt] if nxt >= 0 else text[start:]
        lines = old.splitlines()[1:]
        # The line naming the runner section (benches/sections.py) stays under the heading.
        named = [ln for ln in lines if ln.startswith("Bench section:")][:1]
        lines = [ln for ln in lines if not ln.startswith("Bench section:")]
        # The body's first line up to its label ("Data:", "Measured ...:"), else its start.
        head = body.splitlines()[0]
        first = head[:head.index(":") + 1] if ":" in head[:40] else head[:12]
        commands = [ln.split("`")[1] for ln in body.splitlines()
                    if ln.startswith("Command: `") and ln.count("`") >= 2]
        begin = next((i for i, ln in enumerate(lines) if first and ln.startswith(first)), None)
        end = None
        if commands:
            end = next((i for i in reversed(range(len(lines)))
                        if lines[i].startswith(f"Command: `{commands[-1]}`")), None)
        before = "\n".join(lines[:begin]).strip() if begin is not None else ""
        after = ("\n".join(lines[end + 1:]).strip()
                 if end is not None and (begin is None or end >= begin) else "")
        parts = [section, *named, before, body, after]
        block = "\n\n".join(x for x in parts if x) + "\n"
        text = text[:start] + block + (text[nxt:] if nxt >= 0 else "")
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def publish(section: str, notes: list[str], header: list[str], rows: list[list[str]],
            command: str, update: bool) -> None:
    """Prints a benchmark's notes, table and command; with ``update`` also writes them as
    ``section`` of BENCHMARKS.md."""
    body = "\n".join([*notes, "", table(header, rows), "", f"Command: `{command}`"])
    print(body)
    if update:
        update_markdown(section, body)


def named_models(ap: argparse.ArgumentParser, specs: list[str]) -> dict[str, str | None]:
    """``--model NAME=PATH`` options (repeatable) as ``{name: path}``, after the shipped model
    (``"shipped": None``); a spec without ``=PATH`` is a usage error of ``ap``."""
    models: dict[str, str | None] = {"shipped": None}
    for spec in specs:
        name, _, path = spec.partition("=")
        if not path:
            ap.error(f"--model: expected NAME=PATH, got {spec!r}")
        models[name] = path
    return models


def held_out_motion_pairs(root: Path, n: int) -> dict[str, Any]:
    """The simulated held-out motion pairs the motion benches score on: the first ``n``
    samples of each of ``gel_test_indenter`` and ``gel_test_depth`` (preset ``mixed``, seed 0;
    written under ``root`` if absent), concatenated field by field."""
    import numpy as np

    from tacswitch.motion import data as mdata

    parts = []
    for split in ("gel_test_indenter", "gel_test_depth"):
        if not list(root.glob(f"{split}_*.npz")):
            mdata.generate_split(root, split, n, preset="mixed", seed=0, shard=100)
        d = mdata.load_split(root, split)
        parts.append({k: v[:n] for k, v in d.items()})
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def pure_press_gains(rule: Callable[..., Any], n: int = 40) -> dict[tuple[str, str], float]:
    """Least-squares scale of a motion rule against the true marker motion of the simulator's
    pure presses (no shear; ``n`` per preset, seeds ``[7, k]``): ``rule(img, ref, rest,
    gain=1.0)`` with the no-contact reference (``"ref"``) and single-frame (``"single"``).
    Keys ``(preset, mode)`` for GelSight Mini and GelSight, plus ``("pooled", mode)`` and
    ``("pooled", "both")``. The calibration of the no-learning rules (never the proxies)."""
    import numpy as np

    from tacswitch.sim.indenters import CLASSES
    from tacswitch.sim.scene import Scene

    num: dict[tuple[str, str], float] = {}
    den: dict[tuple[str, str], float] = {}
    for preset in ("gelsight_mini", "gelsight"):
        for k in range(n):
            rng = np.random.default_rng([7, k])
            scene = Scene(preset, rng, label=CLASSES[1 + k % (len(CLASSES) - 1)])
            f = scene.render(rng, depth=scene.depth)
            ref = scene.render(rng, depth=0.0).image
            for mode, r in (("ref", ref), ("single", None)):
                p = rule(f.image, r, scene.rest, gain=1.0)
                for key in ((preset, mode), ("pooled", mode), ("pooled", "both")):
                    num[key] = num.get(key, 0.0) + float((p * f.displacement).sum())
                    den[key] = den.get(key, 0.0) + float((p * p).sum())
    return {key: num[key] / max(den[key], 1e-12) for key in num}
