"""The slip loop (extract + track + rule) at camera resolution, frames per second on one thread.

Ours: ``SlipDetector.update(frame)`` (public API: tracker + rule), and the two native calls it
wraps. Peer, measured in the same run: the pipeline users write today — the OpenCV extraction
chain, cKDTree matching against the reference, the paper's max-displacement rule in numpy.
The GelSight SDK's Python tracker (~22 ms/frame at 320x240, from the design notes) is not
installable here; its figure is quoted, not measured.

    python benches/bench_slip.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from bench_extract import opencv_chain
from harness import machine, single_thread, table
from scipy.spatial import cKDTree

import tacswitch as ts
from tacswitch import sim


class OpenCVSlipLoop:
    """The peer: OpenCV chain + cKDTree nearest neighbour to the reference + numpy rule."""

    def __init__(self, reference: np.ndarray, threshold_px: float) -> None:
        self.ref = opencv_chain(reference, "box")
        self.threshold = threshold_px
        self.base: np.ndarray | None = None

    def update(self, frame: np.ndarray) -> bool:
        cur = opencv_chain(frame, "box")
        _, j = cKDTree(cur).query(self.ref)
        motion = cur[j] - self.ref
        if self.base is None:
            self.base = motion
        return bool(np.hypot(*(motion - self.base).T).max() > self.threshold)


def fps(make, frames: list[np.ndarray], rounds: int) -> tuple[float, float]:
    """Median and min frames/s over ``rounds`` passes of a fresh loop over ``frames``."""
    rates = []
    for _ in range(rounds):
        loop = make()
        t0 = time.perf_counter()
        for f in frames:
            loop(f)
        rates.append(len(frames) / (time.perf_counter() - t0))
    return float(np.median(rates)), float(np.min(rates))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    single_thread()
    rounds = 3 if args.quick else 11
    print(f"Machine: {machine()}\n")
    rows = []
    for preset in ("gelsight", "gelsight_mini"):
        seq = sim.grasp_sequence(preset, "slip", n_frames=60, seed=0)
        frames = seq.frames[seq.grasp_start:]
        thr = ts.slip.scaled_threshold(seq.preset.width)

        def api(seq=seq):
            det = ts.SlipDetector(image_width=seq.preset.width)
            det.update(seq.frames[seq.grasp_start - 1])  # reference = the grasp's first frame
            return det.update

        def native(seq=seq, thr=thr):
            ref = ts.extract_markers(seq.frames[seq.grasp_start - 1]).centres
            tracker = ts._native.Tracker(ref)
            rule = ts._native.SlipDetector(thr)
            return lambda f: rule.update(*tracker.update_image(f)[:2])

        def peer(seq=seq, thr=thr):
            return OpenCVSlipLoop(seq.frames[seq.grasp_start - 1], thr).update

        r_api, r_native, r_peer = (fps(m, frames, rounds) for m in (api, native, peer))
        h, w = seq.reference.shape[:2]
        rows.append([
            f"{preset} {w}x{h}, {len(seq.rest)} markers",
            f"{r_api[0]:.0f} (min {r_api[1]:.0f})", f"{r_native[0]:.0f}",
            f"{r_peer[0]:.0f}", f"**{r_api[0] / r_peer[0]:.1f}x**",
            f"{22e-3 * r_api[0]:.0f}x" if preset == "gelsight_mini" else "",
        ])
    print("### Slip loop, frames/s (median over passes of a whole grasp, one thread)\n")
    print(table(["frames", "tacswitch API", "tacswitch native calls", "OpenCV + cKDTree + numpy",
                 "speed-up vs OpenCV loop", "vs GelSight SDK 22 ms (quoted)"], rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
