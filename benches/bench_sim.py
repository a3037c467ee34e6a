"""Simulator speed (samples/s per preset, one process) and marker ground-truth accuracy.

Run: ``python benches/bench_sim.py [--n 20] [--grain]``. Prints a Markdown table; with
``--grain`` also the gel grain of taxim's real presses against the simulator's at the same scale
(640 x 480, 0.0295 mm/px; :func:`tacswitch.sim.grain.measure_grain`; needs ``taxim``).
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
    ap.add_argument("--grain", action="store_true", help="also compare the gel grain with real")
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
    if args.grain:
        grain_table()


def grain_table(seeds: int = 4, frames: int = 5) -> None:
    """Real vs simulated fixed-pattern grain: correlation between frames, fixed-pattern and
    temporal std (grey levels of the high-passed grey image) and the radial cross spectrum's
    shape (bins 1-6 relative to bin 1; log-correlation with the real one)."""
    import dataclasses

    from tacswitch import sim
    from tacswitch.sim import grain

    print("\n| frames | corr | fixed (grey) | temporal (grey) | spectrum bins 1-6 / bin 1 | "
          "log-corr with real |")
    print("|---|---|---|---|---|---|")
    for name in ("gelsight", "gelsight_mini"):
        imgs, use = grain.taxim_presses(name)
        real = grain.measure_grain(imgs, use)
        r = np.asarray(real.radial_psd[1:7])

        def row(label: str, st: grain.GrainStats, r: np.ndarray = r) -> str:
            p = np.asarray(st.radial_psd[1:7])
            lc = np.corrcoef(np.log(np.maximum(p, 1e-9)), np.log(r))[0, 1]
            return (f"| {label} | {st.corr:.3f} | {st.fixed_std:.3f} | {st.temporal_std:.3f} | "
                    f"{' '.join(f'{v:.2f}' for v in p / p[0])} | {lc:.3f} |")

        print(row(f"real {name} (taxim, {real.n_pairs} pairs)", real))
        p = dataclasses.replace(sim.get_preset(name), height=480, width=640, mm_per_px=0.0295)
        for look in ("preset", "random"):
            for seed in range(seeds):
                sc = sim.Scene(p, seed, label="none", appearance=look)
                st = grain.measure_grain(np.stack([sc.render(k).image for k in range(frames)]))
                print(row(f"sim {name}, {look} look, seed {seed} (grain {sc.grain_std:.2f}, "
                          f"{sc.grain_profile})", st))


if __name__ == "__main__":
    main()
