"""Frames per second of the whole slip loop, tracking included, one thread: marker tracking +
the learned grasp slip detector (``tacswitch slip``'s default) vs tracking + the paper's rule,
measured in alternating rounds in one run.

Frames: a REAL GelSight Mini grasp video (320x240, from the slip study's training split) when the
data folder is there, else rendered; a rendered GelSight grasp at 640x480. Budget: >= 1000
frames/s at 320x240 with the learned detector.

``--markerless``: the loop of ``tacswitch slip --markerless`` on a markerless sensor instead:
``MarkerlessTracker``'s motion from rest (the preset the markerless scorer learned,
``SCORER_FLOW_PRESET``, with its frame-to-frame path, ``SCORER_FRAME_TO_FRAME``, beside the
same without that path, as before 2026-12-01) + the learned detector with the markerless
scorer, on the same frames with the markers removed beforehand (the removal
is not part of a markerless sensor's loop); the budget is camera rate (25 frames/s).

    python benches/bench_slip_loop.py [--rounds 9] [--video VIDEO] [--markerless]
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np
from harness import machine, single_thread

import tacswitch as ts
from tacswitch import sim
from tacswitch.grasp.dataset import read_video

DEFAULT_VIDEO = (Path(__file__).resolve().parents[2]
                 / "shared/data/real/gsmini_slip_train/avocado_real/exp_num_5/camera_0.avi")


def loop_fps(frames: list[np.ndarray], rule: str | None) -> float:
    """Frames/s of one pass: tracker update, then the detector (None: tracking alone)."""
    tracker = ts.MarkerTracker(frames[0])
    det = (None if rule is None else
           ts.GraspSlipDetector(tracker.reference, image_width=frames[0].shape[1], rule=rule))
    t0 = time.perf_counter()
    for f in frames:
        m, v = tracker.update(f)
        if det is not None:
            det.update(m, v)
    return len(frames) / (time.perf_counter() - t0)


def markerless_fps(frames: list[np.ndarray], weight: float, centres: np.ndarray) -> float:
    """Frames/s of one pass of the markerless slip loop: ``MarkerlessTracker`` (plain flow
    from the first frame with the scorer's preset and frame-to-frame ``weight``, as ``tacswitch
    slip --markerless`` runs it) + the learned detector with the markerless scorer."""
    from tacswitch.grasp.detector import SCORER_FLOW_PRESET

    tracker = ts.MarkerlessTracker(frames[0], centres, suppress_imprint=False, anchor="rest",
                                   preset=SCORER_FLOW_PRESET, frame_to_frame=weight)
    det = ts.GraspSlipDetector(centres, model="markerless", image_width=frames[0].shape[1])
    t0 = time.perf_counter()
    for f in frames:
        det.update(tracker.update(f))
    return len(frames) / (time.perf_counter() - t0)


def markerless_main(sets: list[tuple[str, list[np.ndarray]]], rounds: int) -> None:
    """The markerless loop's table: frames/s with the scorer's frame-to-frame weight (what
    ships) and without that path, medians of alternating rounds."""
    from tacswitch.grasp.dataset import scorer_removal
    from tacswitch.grasp.detector import SCORER_FRAME_TO_FRAME, SCORER_REMOVAL_TEXT

    weights = [SCORER_FRAME_TO_FRAME, 0.0]
    print(f"| frames (markers removed: `remove_markers(frame, {SCORER_REMOVAL_TEXT})`) | "
          + " | ".join(f"frame_to_frame={w:g} + markerless detector" for w in weights)
          + " | ratio |\n|---|" + "---|" * (len(weights) + 1))
    for name, marked in sets:
        centres = ts.extract_markers(marked[0]).centres
        frames = [scorer_removal(f) for f in marked]
        markerless_fps(frames[:10], weights[0], centres)  # warm-up
        rates: dict[float, list[float]] = {w: [] for w in weights}
        for _ in range(rounds):
            for w in weights:
                rates[w].append(markerless_fps(frames, w, centres))
        med = [float(np.median(rates[w])) for w in weights]
        print(f"| {name} ({len(frames)} frames, {rounds} rounds, medians) | "
              + " | ".join(f"{m:.0f}" for m in med) + f" | {med[0] / med[-1]:.2f} |")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--video", type=Path, default=DEFAULT_VIDEO)
    ap.add_argument("--markerless", action="store_true",
                    help="the markerless slip loop (module doc)")
    args = ap.parse_args()
    single_thread()
    sets = []
    if args.video.is_file():
        sets.append(("REAL GelSight Mini video 320x240",
                     list(itertools.islice(read_video(args.video), 450))))
    else:
        seq = sim.grasp_sequence("gelsight_mini", "slip", n_frames=60, seed=0)
        sets.append(("rendered GelSight Mini 320x240", [seq.reference, *seq.frames]))
    seq = sim.grasp_sequence("gelsight", "slip", n_frames=60, seed=0)
    sets.append(("rendered GelSight 640x480", [seq.reference, *seq.frames]))
    print(machine())
    if args.markerless:
        markerless_main(sets, args.rounds)
        return 0
    print("| frames | tracking alone | tracking + paper rule | tracking + learned detector | "
          "learned / paper |\n|---|---|---|---|---|")
    for name, frames in sets:
        loop_fps(frames, "learned")  # warm-up: the scorer's session, caches
        rates: dict[str | None, list[float]] = {None: [], "paper": [], "learned": []}
        for _ in range(args.rounds):
            for rule in rates:
                rates[rule].append(loop_fps(frames, rule))
        med = {k: float(np.median(v)) for k, v in rates.items()}
        print(f"| {name} ({len(frames)} frames, {args.rounds} rounds, medians) | "
              f"{med[None]:.0f} | {med['paper']:.0f} | {med['learned']:.0f} | "
              f"{med['learned'] / med['paper']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
