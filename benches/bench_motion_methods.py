"""Speed of every markerless motion method of ``predict_motion`` against the budgets.

python benches/bench_motion_methods.py [--repeat 15]

Times ``tacswitch.predict_motion`` end to end (validation, flow or network, read-out at the
default marker grid) on taxim's real GelSight Mini (320x240) and GelSight (640x480) presses
against their no-contact frames, for dense optical flow at each DIS preset, the outward rule and
the shipped model; onnxruntime and OpenCV use all cores, as users run them. Budgets (DESIGN):
>= 100 Hz at 320x240 and >= 30 Hz at 640x480 on 2 cores. Accuracy: bench_motion_real.py and
bench_motion_accuracy.py.
"""

from __future__ import annotations

import argparse

from harness import machine, measure

from tacswitch import predict_motion
from tacswitch.motion import proxy

METHODS = {
    "flow, DIS medium (default)": {"method": "flow", "preset": "medium"},
    "flow, DIS fast": {"method": "flow", "preset": "fast"},
    "flow, DIS ultrafast": {"method": "flow", "preset": "ultrafast"},
    "outward rule": {"method": "outward"},
    "model": {"method": "model"},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    frames = {}
    for sensor in ("gelsight_mini", "gelsight"):
        pr = proxy.load_real_presses(sensor)
        frames[sensor] = (pr.imgs[3], pr.f0)
    print(machine())
    print("| method | 320x240 ms | 640x480 ms | 320x240 Hz | 640x480 Hz |")
    print("|---|---|---|---|---|")
    for name, kw in METHODS.items():
        ms = []
        for sensor in ("gelsight_mini", "gelsight"):
            img, ref = frames[sensor]
            t = measure(lambda img=img, ref=ref, kw=kw: predict_motion(img, ref, **kw),
                        repeat=args.repeat)
            ms.append(t.median * 1e3)
        print(f"| {name} | {ms[0]:.1f} | {ms[1]:.1f} | {1e3 / ms[0]:.0f} | {1e3 / ms[1]:.0f} |")


if __name__ == "__main__":
    main()
