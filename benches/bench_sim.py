"""Simulator speed (samples/s per preset, one process) and marker ground-truth accuracy.

Run: ``python benches/bench_sim.py [--n 20]``. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import single_thread


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20, help="samples per preset")
    args = ap.parse_args()
    single_thread()
    import tacswitch as ts
    from tacswitch import sim

    print("| preset | optics | samples/s (1 process) | ms/sample | extraction error median / p95"
          " / max (px) | markers matched |")
    print("|---|---|---|---|---|---|")
    for name in ("gelsight", "gelsight_mini", "digit"):
        sim.render_sample(name, 0)  # warm-up: calibration load, imports
        errs, matched, total = [], 0, 0
        t0 = time.perf_counter()
        samples = [sim.render_sample(name, np.random.SeedSequence([0, i])) for i in range(args.n)]
        dt = (time.perf_counter() - t0) / args.n
        for s in samples:
            h, w = s.marker_mask.shape
            gt = s.rest + s.displacement
            d = s.params["marker_diameter"]
            keep = s.present & ~s.merged & (gt[:, 0] > d) & (gt[:, 0] < w - 1 - d) & (
                gt[:, 1] > d) & (gt[:, 1] < h - 1 - d)
            motion, valid = ts.match_markers(gt[keep], ts.extract_markers(s.image_markers).centres)
            errs.append(np.hypot(*motion[valid].T))
            matched += int(valid.sum())
            total += int(keep.sum())
        e = np.concatenate(errs)
        print(f"| {name} | {samples[0].params['optics']} | {1 / dt:.2f} | {dt * 1e3:.0f} | "
              f"{np.median(e):.3f} / {np.percentile(e, 95):.3f} / {e.max():.2f} | "
              f"{matched}/{total} |")


if __name__ == "__main__":
    main()
