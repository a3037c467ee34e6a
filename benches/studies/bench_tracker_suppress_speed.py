"""Speed of :class:`tacswitch.MarkerlessTracker`: the plain flow, the imprint suppressed
(``anchor="rest"``: the flow from the no-contact frame on every frame) and the default
(``anchor="contact"``: within a steady contact, the flow from the frame where it settled).

Data: **real** taxim press frames with modelled motion (GelSight 640 x 480, GelSight Mini
320 x 240): per press, one recording of the press building up over three frames, then sheared
over four (``proxy.make_ramp_proxy``), so the default tracker anchors as it would on a video.
The trackers run in alternating rounds inside one process (the machine is shared: the ratio is
the measurement, not the Hz), medians of ``--rounds`` rounds, OpenCV's default threads.

    python benches/studies/bench_tracker_suppress_speed.py [--rounds 9] [--presses 3]
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
    ap.add_argument("--presses", type=int, default=3, help="press recordings fed per round")
    args = ap.parse_args()
    print(f"{machine()}.\n")
    print("| frames | plain flow, ms (Hz) | imprint suppressed, anchor='rest', ms (Hz) | "
          "default, anchor='contact', ms (Hz) | suppressed / plain | default / suppressed |")
    print("|---|---|---|---|---|---|")
    kinds = {"plain": {"suppress_imprint": False, "anchor": "rest"},
             "suppressed": {"anchor": "rest"}, "default": {}}
    for sensor in ("gelsight", "gelsight_mini"):
        real = proxy.load_real_presses(sensor).subset(slice(0, args.presses))
        seqs = list(proxy.make_ramp_proxy(sensor, presses=real, kinds=("shear",)))
        times: dict[str, list[float]] = {k: [] for k in kinds}
        n = sum(len(sq.frames) for sq in seqs)
        for r in range(args.rounds + 1):
            for name, kw in kinds.items():
                t0 = time.perf_counter()
                for sq in seqs:
                    tr = MarkerlessTracker(sq.no_contact, sq.rest, **kw)  # type: ignore[arg-type]
                    for img in sq.frames:
                        tr.update(img)
                if r:  # round 0 warms OpenCV up
                    times[name].append((time.perf_counter() - t0) / n)
        med = {k: statistics.median(v) for k, v in times.items()}
        h, w = real.f0.shape[:2]
        cells = " | ".join(f"{1e3 * med[k]:.1f} ({1 / med[k]:.0f})" for k in kinds)
        print(f"| real {sensor} {w}x{h} | {cells} | {med['suppressed'] / med['plain']:.2f} | "
              f"{med['default'] / med['suppressed']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
