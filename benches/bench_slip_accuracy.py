"""Slip detection accuracy on rendered grasps: the paper's rule vs the rigid-motion criterion.

Sequences come from the physical simulator (``tacswitch.sim.grasp.render_grasp``: press, shear
ramp, then hold, slip — the stuck zone vanishing — or vibration, a hard negative). Markers are
tracked on the marker images; each detector starts at the established grasp.

    python benches/bench_slip_accuracy.py [--seeds 6]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from harness import machine, table

import tacswitch as ts
from tacswitch.sim.grasp import render_grasp

DETECTORS = {
    "displacement (paper, 3.25 px at 640 wide)": {},
    "rigid, auto (half the threshold)": {"rigid_threshold_px": "auto", "use_displacement": False},
    "both": {"rigid_threshold_px": "auto"},
}


def run(preset: str, kind: str, seed: int) -> tuple[dict[str, int | None], int | None]:
    seq = render_grasp(preset, kind, n_frames=30, seed=seed)
    tracker = ts.MarkerTracker(seq.reference)
    width = seq.reference.shape[1]
    dets = {k: ts.SlipDetector(image_width=width, points=tracker.reference, **kw)
            for k, kw in DETECTORS.items()}
    first: dict[str, int | None] = dict.fromkeys(dets)
    for t, frame in enumerate(seq.frames):
        motion, valid = tracker.update(frame.image_markers)
        for k, d in dets.items():
            if t == seq.grasp_start:
                d.reset()
            if t >= seq.grasp_start and d.update(motion, valid).slip and first[k] is None:
                first[k] = t
    onset = seq.slip.index(True) if True in seq.slip else None
    return first, onset


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    print(f"Machine: {machine()}\n")
    rows = []
    for preset in ("gelsight", "gelsight_mini"):
        stats = {k: {"hit": 0, "slip": 0, "delay": [], "fa_hold": 0, "fa_vib": 0, "n_hold": 0,
                     "n_vib": 0} for k in DETECTORS}
        for kind in ("hold", "slip", "vibration"):
            for seed in range(args.seeds):
                first, onset = run(preset, kind, seed)
                for k, f in first.items():
                    s = stats[k]
                    if kind == "slip":
                        s["slip"] += 1
                        if f is not None:
                            s["hit"] += 1
                            s["delay"].append(f - onset)
                    else:
                        s["n_hold" if kind == "hold" else "n_vib"] += 1
                        s["fa_hold" if kind == "hold" else "fa_vib"] += f is not None
        for k, s in stats.items():
            n = s["slip"] + s["n_hold"] + s["n_vib"]
            correct = s["hit"] + (s["n_hold"] - s["fa_hold"]) + (s["n_vib"] - s["fa_vib"])
            delay = f"{np.median(s['delay']):+.0f}" if s["delay"] else "-"
            rows.append([preset, k, f"{correct}/{n} ({100 * correct / n:.0f} %)",
                         f"{s['hit']}/{s['slip']}", f"{s['fa_hold']}/{s['n_hold']}",
                         f"{s['fa_vib']}/{s['n_vib']}", delay])
    print("### Slip detection on rendered grasps (30 frames each)\n")
    print(table(["sensor", "criterion", "sequences right", "slips found", "false alarms hold",
                 "false alarms vibration", "median delay (frames)"], rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
