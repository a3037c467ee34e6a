"""MarkerTracker and match_markers at 10^2 .. 10^5 (10^6) markers: time and peak memory.

Each size runs in its own process so that peak RSS (``ru_maxrss``) is that size's alone; the
figure reported is the peak growth over the process's state just before the tracker is built.
Points: a jittered square grid of pitch 10 px; each frame moves every marker by (2, 1) px plus
0.3 px noise, shuffled (as detections come); per-frame times are the best of the frames (the
machine is shared, so the best is the least disturbed), match_markers of the first frame
(2.2 px motion) with a 5 px gate, repeated as often. ``--python PATH`` runs the same
measurement under another interpreter (e.g. a venv holding an older build): before/after.

    python benches/bench_tracker_scaling.py [--quick] [--max-n 100000] [--publish]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from harness import machine, table, update_markdown

CHILD = r"""
import json, resource, sys, time
import numpy as np
import tacswitch as ts
n, frames = int(sys.argv[1]), int(sys.argv[2])
side = int(np.ceil(np.sqrt(n)))
rng = np.random.default_rng(0)
g = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n]
ref = (g * 10.0 + rng.normal(0, 0.5, (n, 2))).astype(np.float32)
curs = []
for k in range(1, frames + 1):
    c = ref + np.float32(k) * np.array([2.0, 1.0], np.float32)
    c = (c + rng.normal(0, 0.3, c.shape)).astype(np.float32)
    curs.append(c[rng.permutation(n)])
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
tr = ts.MarkerTracker(ref)
build = time.perf_counter() - t
ups = []
for c in curs:
    t = time.perf_counter()
    motion, valid = tr.update(c)
    ups.append(time.perf_counter() - t)
match = []
for _ in curs:
    t = time.perf_counter()
    _, v2 = ts.match_markers(ref, curs[0], 5.0)
    match.append(time.perf_counter() - t)
match = min(match)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"n": n, "build_s": build, "update_s": min(ups),
                  "match_s": match, "valid": float(valid.mean()),
                  "match_valid": float(v2.mean()), "peak_mb": (peak - base) / 1024}))
"""


def run(python: str, n: int, frames: int, timeout: float) -> dict | None:
    """One size in a fresh process; None when it ran past ``timeout`` seconds."""
    try:
        out = subprocess.run([python, "-c", CHILD, str(n), str(frames)], capture_output=True,
                             text=True, timeout=timeout, check=True,
                             env={"OMP_NUM_THREADS": "1", "RAYON_NUM_THREADS": "1",
                                  "PATH": "/usr/bin:/bin"})
    except subprocess.TimeoutExpired:
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--max-n", type=int, default=100_000)
    ap.add_argument("--python", default=sys.executable)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--publish", action="store_true")
    args = ap.parse_args()
    frames = 2 if args.quick else 7
    sizes = [n for n in (100, 1_000, 10_000, 100_000, 1_000_000) if n <= args.max_n]
    rows = []
    for n in sizes:
        r = run(args.python, n, frames, args.timeout)
        if r is None:
            rows.append([f"{n:,}", f"> {args.timeout:.0f} s", "", "", "", ""])
            print(rows[-1], flush=True)
            continue
        rows.append([f"{n:,}", f"{r['build_s'] * 1e3:.1f}", f"{r['update_s'] * 1e3:.1f}",
                     f"{r['match_s'] * 1e3:.1f}", f"{r['peak_mb']:.0f}",
                     f"{r['valid']:.3f} / {r['match_valid']:.3f}"])
        print(rows[-1], flush=True)
    header = ["markers", "MarkerTracker() ms", "update ms (best)", "match_markers ms (best)",
              "peak RSS growth MB", "valid (tracker / match)"]
    text = table(header, rows)
    print(f"\nMachine: {machine()}\nInterpreter: {args.python}\n\n{text}")
    if args.publish:
        body = (f"`python benches/bench_tracker_scaling.py --max-n {args.max_n}`, one process "
                f"per size, 1 thread, {frames} frames, {machine()}.\n\n{text}\n")
        update_markdown("## Tracker scaling", body)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    sys.exit(main())
