"""Speed of :class:`tacswitch.MarkerlessTracker` with and without imprint suppression.

Data: **real** taxim presses (GelSight 640 x 480, GelSight Mini 320 x 240), each tracker fed
the first ``--frames`` presses after its no-contact frame. The two trackers run in alternating
rounds inside one process (the machine is shared: the ratio is the measurement, not the Hz),
medians of ``--rounds`` rounds, OpenCV's default threads.

    python benches/studies/bench_tracker_suppress_speed.py [--rounds 9] [--frames 10]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness, proxies
from harness import machine
from proxies import motion_proxy as proxy


def main() -> int:
    from tacswitch.motion.sequence import MarkerlessTracker

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=9, help="alternating rounds (median)")
    ap.add_argument("--frames", type=int, default=10, help="presses fed per round")
    args = ap.parse_args()
    print(f"{machine()}.\n")
    print("| frames | plain flow, ms (Hz) | imprint suppressed (default), ms (Hz) | "
          "suppressed / plain |")
    print("|---|---|---|---|")
    for sensor in ("gelsight", "gelsight_mini"):
        real = proxy.load_real_presses(sensor)
        imgs = real.imgs[:args.frames]
        trackers = {"plain": MarkerlessTracker(real.f0, suppress_imprint=False),
                    "suppressed": MarkerlessTracker(real.f0)}
        for tr in trackers.values():
            tr.update(imgs[0])  # warm-up: the default centres, OpenCV's first calls
        times: dict[str, list[float]] = {k: [] for k in trackers}
        for _ in range(args.rounds):
            for name, tr in trackers.items():
                t0 = time.perf_counter()
                for img in imgs:
                    tr.update(img)
                times[name].append((time.perf_counter() - t0) / len(imgs))
        med = {k: statistics.median(v) for k, v in times.items()}
        h, w = real.f0.shape[:2]
        print(f"| real {sensor} {w}x{h} | {1e3 * med['plain']:.1f} ({1 / med['plain']:.0f}) | "
              f"{1e3 * med['suppressed']:.1f} ({1 / med['suppressed']:.0f}) | "
              f"{med['suppressed'] / med['plain']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
