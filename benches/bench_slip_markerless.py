"""Slip detection on a markerless sensor: the slip rule fed motion predicted from markerless frames.

Rendered grasps (``tacswitch.sim.grasp.render_grasp``: press, shear ramp, then hold, slip — the
stuck zone vanishing — or vibration, a hard negative; 30 frames; SIMULATED data). From the grasp
start on, each markerless frame goes to ``predict_motion`` (dense optical flow, the shipped model,
the outward rule) with the markerless grasp-start frame (or the no-contact frame) as reference;
the paper's displacement rule (3.25 px at 640 wide, scaled), the rigid-fit criterion (half that
threshold on the residual of a rigid fit) and both together decide. The upper reference tracks the
true markers on the marker images. The paper reports 92.59 % on real sequences.

    python benches/bench_slip_markerless.py [--seeds 6] [--ref grasp_start|no_contact] [--update]
"""

from __future__ import annotations

import argparse
import os
from typing import Any

import numpy as np
from harness import machine, named_models, publish

from tacswitch.motion.evaluate import SLIP_CRITERIA, slip_on_grasps
from tacswitch.motion.infer import MotionModel, predict_motion

SECTION = "## Slip on a markerless sensor (simulated grasps)"


def sources(models: dict[str, str | None], with_model: bool) -> dict[str, Any]:
    out: dict[str, Any] = {
        "flow DIS medium": lambda i, r, c: predict_motion(i, r, c, method="flow"),
        "flow DIS fast": lambda i, r, c: predict_motion(i, r, c, method="flow", preset="fast"),
        "outward (no learning)": lambda i, r, c: predict_motion(i, r, c, method="outward"),
    }
    if with_model:
        for name, path in models.items():
            m = MotionModel(path, threads=2)
            out[f"model {name}"] = (lambda i, r, c, m=m: m(i, ref=r, centres=c))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=6, help="grasps per kind and sensor")
    ap.add_argument("--ref", choices=("grasp_start", "no_contact"), default="grasp_start")
    ap.add_argument("--presets", nargs="+", default=["gelsight_mini", "gelsight"])
    ap.add_argument("--model", action="append", default=[], metavar="NAME=PATH")
    ap.add_argument("--no-model", action="store_true", help="skip the ONNX model(s)")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    models = named_models(ap, args.model)
    rows = []
    for preset in args.presets:
        src = sources(models, not args.no_model)
        res = slip_on_grasps(src, preset=preset, n_per_kind=args.seeds, ref_frame=args.ref)
        for name in [*src, "tracked"]:
            for crit in SLIP_CRITERIA:
                r = res[(name, crit)]
                d = r["delays"]
                delay = (f"{np.median(d):+.0f} [{min(d):+d}, {max(d):+d}]" if d else "-")
                label = "tracking true markers" if name == "tracked" else name
                rows.append([preset, label, crit,
                             f"{r['correct']}/{r['n']} ({100 * r['accuracy']:.1f} %)",
                             f"{r['slips_found']}/{r['n_slip']}",
                             f"{r['fa_hold']}/{r['n_hold']}",
                             f"{r['fa_vibration']}/{r['n_vibration']}", delay,
                             "-" if name == "tracked" else f"{r['ms']:.0f}"])
    notes = [f"Machine: {machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', '-')}.",
             "",
             f"Simulated grasps, {args.seeds} per kind (slip / hold / vibration) and sensor, 30 "
             f"frames; motion predicted from the markerless frames with reference = "
             f"the markerless {args.ref.replace('_', '-')} frame"
             "; every criterion starts at the grasp start. Delay: frames from the slip onset to "
             "the first detection (median [min, max]). The paper's bar: 92.59 % (real "
             "sequences)."]
    header = ["sensor", "motion source", "criterion", "grasps right", "slips found",
              "false alarms hold", "false alarms vibration", "delay (frames)",
              "ms/frame (busy machine)"]
    cmd = (f"OMP_NUM_THREADS=1 python benches/bench_slip_markerless.py --seeds {args.seeds} "
           f"--ref {args.ref}" + "".join(f" --model {s}" for s in args.model) + " --update")
    publish(SECTION, notes, header, rows, cmd, args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
