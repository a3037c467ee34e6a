"""TacDiff speed per frame on this CPU at each step count K, and the hybrid mode, against our
TELEA r=3 and biharmonic fills on the same frames, median of repeated runs. Everything uses all
cores, as users run it (onnxruntime's threads, rayon's pool for TELEA and the biharmonic fill
TacDiff starts from).

    python benches/bench_tacdiff.py [--frames 3] [--rounds 3] [--fast-steps 1,2]

Quality is reported by ``tacswitch evaluate tacdiff`` (held-out frames, the paper's metrics).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import tacswitch as ts
from tacswitch.sim.scene import render_sample
from tacswitch.tacdiff import inpaint_hybrid, inpaint_tacdiff
from tacswitch.tacdiff.evaluate import HELD_OUT_SEED

BUDGET_MS = {"default (K=1)": 1000.0, "fastest (K=1)": 150.0}


def _median_ms(fn, rounds: int) -> float:
    fn()  # warm-up (session creation, first allocation)
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", default="1,2,4,8,20")
    ap.add_argument("--fast-steps", default="1,2", help="K for the shipped fast model")
    args = ap.parse_args()
    runs = [("default", int(k)) for k in args.steps.split(",")]
    runs += [("fast", int(k)) for k in args.fast_steps.split(",") if k]
    print("| preset | method | ms / frame (median over frames) | vs TELEA r=3 | share of holes "
          "through the network |")
    print("|---|---|---|---|---|")
    for preset in ("gelsight", "gelsight_mini"):
        samples = [render_sample(preset, (HELD_OUT_SEED, i)) for i in range(args.frames)]
        masks = [ts.dilate_mask(s.marker_mask) for s in samples]
        telea = float(np.median([_median_ms(lambda s=s, m=m: ts.inpaint_telea(
            s.image_markers, m, 3), args.rounds) for s, m in zip(samples, masks, strict=True)]))
        print(f"| {preset} | TELEA r=3 | {telea:.1f} | 1x | 0 |")
        bh = float(np.median([_median_ms(lambda s=s, m=m: ts.inpaint_biharmonic(
            s.image_markers, m), args.rounds) for s, m in zip(samples, masks, strict=True)]))
        print(f"| {preset} | biharmonic | {bh:.1f} | {bh / telea:.0f}x | 0 |")
        for model, k in runs:
            ms = float(np.median([_median_ms(lambda s=s, m=m, k=k, mo=model: inpaint_tacdiff(
                s.image_markers, m, k, model=mo), args.rounds)
                for s, m in zip(samples, masks, strict=True)]))
            name = "TacDiff" if model == "default" else f"TacDiff {model}"
            print(f"| {preset} | {name} K={k} | {ms:.0f} | {ms / telea:.0f}x | 1 |")
        for model, use_ref in (("default", True), ("default", False), ("fast", True)):
            shares = [inpaint_hybrid(s.image_markers, m, s.reference if use_ref else None,
                                     steps=1, model=model)[1].holes_fraction
                      for s, m in zip(samples, masks, strict=True)]
            ms = float(np.median([_median_ms(lambda s=s, m=m, u=use_ref, mo=model: inpaint_hybrid(
                s.image_markers, m, s.reference if u else None, steps=1, model=mo), args.rounds)
                for s, m in zip(samples, masks, strict=True)]))
            name = ("hybrid" if model == "default" else f"hybrid {model}") + (
                " (reference)" if use_ref else " (texture)")
            print(f"| {preset} | {name} K=1 | {ms:.0f} | {ms / telea:.0f}x | "
                  f"{np.mean(shares):.2f} |")


if __name__ == "__main__":
    main()
