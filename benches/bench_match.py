"""Nearest-neighbour marker matching vs scipy.spatial.cKDTree.

Peer: cKDTree build on the current points + query of the reference points (no mutual check, no
gate: less work than ours), and the same with a mutual check (a second tree, as a user would do).
Ours: ``tacswitch.match_markers`` (mutual check + half-pitch gate), through the public API with its
argument validation, and the bare native call.

    python benches/bench_match.py [--quick]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from harness import interleaved, machine, single_thread, table
from scipy.spatial import cKDTree

import tacswitch as ts
from tacswitch import _native, sim


def points(n_side: tuple[int, int], seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rows, cols = n_side
    ref = sim.marker_grid(480, 640, rows, cols, 600 / max(cols, 1) * 0.9)
    rng = np.random.default_rng(seed)
    cur = ref + rng.normal(0, 2.0, ref.shape).astype(np.float32)
    return ref, cur[rng.permutation(len(cur))]


def scipy_plain(ref: np.ndarray, cur: np.ndarray) -> np.ndarray:
    return cKDTree(cur).query(ref)[1]


def scipy_mutual(ref: np.ndarray, cur: np.ndarray, gate: float) -> np.ndarray:
    d, j = cKDTree(cur).query(ref)
    _, back = cKDTree(ref).query(cur)
    ok = (d <= gate) & (back[j] == np.arange(len(ref)))
    return np.where(ok, j, -1)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    single_thread()
    rounds = 3 if args.quick else 15
    print(f"Machine: {machine()}\n")
    rows = []
    for grid in ((6, 8), (10, 10), (14, 19), (30, 34)):
        ref, cur = points(grid)
        gate = 0.5 * ts.estimate_pitch(ref)
        ours = ts.match_markers(ref, cur, return_index=True)[2]
        assert (ours == scipy_mutual(ref, cur, gate)).all()
        inner = 50 if len(ref) <= 300 else 5
        t = interleaved({
            "api": lambda r=ref, c=cur: ts.match_markers(r, c),
            "native": lambda r=ref, c=cur: _native.match_markers(r, c, None),
            "plain": lambda r=ref, c=cur: scipy_plain(r, c),
            "mutual": lambda r=ref, c=cur, g=gate: scipy_mutual(r, c, g),
        }, rounds=rounds, repeat=10, inner=inner)
        rows.append([
            f"{len(ref)}", t["api"].fmt("us"), t["native"].fmt("us"), t["plain"].fmt("us"),
            t["mutual"].fmt("us"),
            f"**{t['plain'].median / t['api'].median:.1f}x**",
            f"{t['mutual'].median / t['api'].median:.1f}x",
        ])
    print("### Matching (median [IQR] per call; results identical to the SciPy mutual check)\n")
    print(table(["markers", "tacswitch API", "tacswitch native", "cKDTree build+query",
                 "cKDTree mutual", "speed-up vs build+query", "vs mutual"], rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
