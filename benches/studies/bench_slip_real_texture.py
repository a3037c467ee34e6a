"""Markerless slip on REAL texture: grasp videos made of taxim's real presses, per codec.

``proxies.slip_proxy.real_grasps``: per real press (taxim's GelSight 640 x 480 and
GelSight Mini 320 x 240, every ``--every``-th), three grasp videos (hold, slip, vibration) with
the phases and draws of the simulator's grasps, the real imprint sliding with the object on slip,
captured as a recorder would (read noise, hunting exposure, then no codec, MJPEG per frame or one
H.264 stream). From the grasp start on, each frame's marker motion is predicted from the
markerless frames with the grasp-start frame as reference (``predict_motion``, as
``tacswitch slip --markerless`` does), and the slip rule decides (displacement: the paper's
3.25 px at 640 wide, scaled; rigid fit; both) on the mean of the last ``--smooth-frames`` frames
(the markerless default 2) and on each frame alone, over the markers near the contact (the
default of ``tacswitch slip --markerless``) or over all of them. Real texture, modelled motion:
a check of the simulated-grasp numbers (``bench_slip_markerless.py``) under real gel texture and
codecs.

    python benches/studies/bench_slip_real_texture.py [--every 4] [--codecs none mjpeg:85 h264:23 h264:28]
                                               [--smooth-frames 2] [--update]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, publish
from proxies import motion_proxy as proxy
from proxies.slip_proxy import real_grasps

from tacswitch.motion.evaluate import SLIP_CRITERIA, slip_on_videos
from tacswitch.motion.infer import predict_motion
from tacswitch.slip import MARKERLESS_SMOOTH_FRAMES

SECTION = "## Slip on a markerless sensor: real-texture grasp videos (codecs)"


def _codec(spec: str) -> tuple[str, int | None]:
    name, _, q = spec.partition(":")
    return name, (int(q) if q else None)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=int, default=4, help="every N-th real press")
    ap.add_argument("--codecs", nargs="+", default=["none", "mjpeg:85", "h264:23", "h264:28"])
    ap.add_argument("--smooth-frames", type=int, default=MARKERLESS_SMOOTH_FRAMES)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--sensors", nargs="+", default=["gelsight_mini", "gelsight"])
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    sources = {"predict_motion (auto: flow)": lambda i, r, c: predict_motion(i, r, c)}
    rows = []
    for sensor in args.sensors:
        data = proxy.load_real_presses(sensor).subset(slice(None, None, args.every))
        for spec in args.codecs:
            codec, q = _codec(spec)
            grasps = list(real_grasps(data, codec=codec, quality=q, seed=args.seed))
            runs = [(args.smooth_frames, True), (args.smooth_frames, False)]
            if args.smooth_frames > 1:
                runs.append((1, False))
            for smooth, gate in runs:
                res = slip_on_videos(sources, grasps, smooth_frames=smooth,
                                     near_contact_only=gate)
                for name in sources:
                    for c in SLIP_CRITERIA:
                        r = res[(name, c)]
                        d = r["delays"]
                        delay = (f"{np.median(d):+.0f} [{min(d):+d}, {max(d):+d}]" if d
                                 else "-")
                        label = (f"{name}, markers near the contact (default)" if gate else
                                 f"{name}, all markers" if smooth == args.smooth_frames else
                                 f"{name}, all markers, unsmoothed")
                        rows.append([sensor, spec, label, c,
                                     f"{r['correct']}/{r['n']} ({100 * r['accuracy']:.1f} %)",
                                     f"{r['slips_found']}/{r['n_slip']}",
                                     f"{r['fa_hold']}/{r['n_hold']}",
                                     f"{r['fa_vibration']}/{r['n_vibration']}", delay,
                                     f"{r['ms']:.0f}"])
                        print(" | ".join(rows[-1]), flush=True)
    load = os.getloadavg()[0]
    notes = [f"Machine: {machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', '-')}; "
             f"load average {load:.1f} at the end (2 cores).", "",
             f"REAL texture, modelled motion (`benches/proxies/slip_proxy.py`): every "
             f"{args.every}-th of taxim's real presses per sensor, one hold, slip and vibration "
             f"grasp video each (30 frames; seed {args.seed}), captured with read noise, a "
             "hunting exposure and the codec of the row (`mjpeg:Q` per frame, `h264:CRF` one "
             "stream). Motion from the grasp-start frame by `predict_motion` (auto: flow for a "
             f"same-contact reference), slip rule on the mean of the last {args.smooth_frames} "
             "frames (`unsmoothed`: each frame alone) over the markers near the grasp-start "
             "frame's contact (`near_contact` against the video's first, no-contact frame; what "
             "`tacswitch slip --markerless` does) or over all markers (before). Delay: frames "
             "from the slip onset to the first detection (median [min, max]). Nothing was "
             "chosen on these videos (the development videos: seed 1, presses 2, 8, 14, ... of "
             "taxim's recordings; presses 8, 20, 32 and 44 are in both sets, with other "
             "draws)."]
    header = ["sensor", "capture", "motion source", "criterion", "grasps right", "slips found",
              "false alarms hold", "false alarms vibration", "delay (frames)", "ms/frame"]
    cmd = ("python benches/studies/bench_slip_real_texture.py --every "
           f"{args.every} --codecs {' '.join(args.codecs)} --smooth-frames {args.smooth_frames}"
           f" --seed {args.seed} --update")
    publish(SECTION, notes, header, rows, cmd, args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
