"""The learned single-frame motion model against the rules, on REAL frames.

One markerless frame, no reference (the paper's setting); every method predicts each marker's
motion from rest. Three data, the first two with a real measurement as the truth:

1. **real GelSight presses, the gel's own motion** (taxim's 640 x 480 presses: the coating's
   grain block-matched between the no-contact frame and each press, each press's fitted
   similarity removed, markers >= 2 contact radii from the contact; as
   ``bench_press_calibration.py``). The least-squares output scale of each model is fitted on
   the EVEN presses (as the rules' real gains were) and every method is scored on the ODD ones.
2. **real marker motion**: the two FOTS GelSight Mini frames (hand-tracked markers, markers
   removed by the default ``remove_markers``; a press, then the same contact sheared); cosine
   over markers moving >= 2.5 px (whole-pixel truth).
3. **real frames, modelled field** (taxim's real presses with the calibrated simulator's field
   of their recorded contact, ``proxies.motion_proxy.make_contact_proxy``; every 2nd press):
   the truth is the simulator's press law, the mechanics rule's own physics.

Methods: zero; the outward rule; the mechanics rule at its default gain; the ensemble (the mean
of the rule and the single-frame model at its recorded scale: the default of ``predict_motion``
without ``ref``, ``tacswitch.motion.ensemble``); the shipped single-frame model
(``model="single"``) at its recorded scale, at scale 1, and at the scale fitted here on the
even presses; the shipped consistent model's single-frame output; and any ``--model
NAME=PATH``. On the real GelSight presses the rule, the ensemble and flow also run against the
no-contact frame (what ``predict_motion`` does with that reference), and the real GelSight Mini
presses (whose gel barely moves) show each method's false motion at the default gain and at the
Mini's.

    python benches/bench_motion_model_real.py [--model NAME=PATH ...] [--update]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

# Helpers of two studies (benches/studies/) this section builds on.
sys.path.insert(0, str(Path(__file__).parent / "studies"))
sys.path.insert(0, str(Path(__file__).parent))
import bench_motion_fots as fots
import bench_press_calibration as press
from harness import MOTION_COLUMNS, machine, motion_row, publish

SECTION = "## Learned single-frame motion model on real frames"

Fn = Callable[[np.ndarray, np.ndarray], np.ndarray]


def ls_scale(pred: np.ndarray, true: np.ndarray) -> float:
    return max(0.0, float((pred * true).sum() / max(float((pred * pred).sum()), 1e-12)))


def main() -> int:
    import bench_motion_single as single

    from tacswitch import remove_markers
    from tacswitch.motion.ensemble import ensemble_motion
    from tacswitch.motion.evaluate import motion_metrics
    from tacswitch.motion.flow import flow_motion
    from tacswitch.motion.heuristic import outward_motion
    from tacswitch.motion.infer import MotionModel
    from tacswitch.motion.mechanics import MECHANICS_GAIN, mechanics_motion
    from tacswitch.sim.presets import MECHANICS_GAINS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                    help="another single-frame or consistent motion model to score")
    ap.add_argument("--fots", type=Path, default=fots.DATA, help="folder of the FOTS frames")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    models = {"single": MotionModel("single", threads=2),
              "consistent (default model)": MotionModel(threads=2)}
    extra: list[str] = []  # the --model names
    for spec in args.model:
        name, _, path = spec.partition("=")
        if not path:
            ap.error(f"--model: expected NAME=PATH; got {spec!r}")
        models[name] = MotionModel(path, threads=2)
        extra.append(name)

    g = press.grain_truth("gelsight", press.calibrate("gelsight")["sims"])
    even = [j for j, o in enumerate(g["odd"]) if not o]
    scales = {}
    for name, m in models.items():
        p = np.concatenate([m(g["img"][j], centres=g["rest"][j], gain=1.0)[g["ok"][j]]
                            for j in even])
        t = np.concatenate([g["true"][j][g["ok"][j]] for j in even])
        scales[name] = ls_scale(p, t)

    def fns() -> dict[str, Fn]:
        out: dict[str, Fn] = {
            "zero": lambda im, c: np.zeros((len(c), 2), np.float32),
            "outward rule": lambda im, c: outward_motion(im, None, c),
            "mechanics rule": lambda im, c: mechanics_motion(im, None, c),
            "ensemble (predict_motion default)": lambda im, c: ensemble_motion(im, None, c)}
        for name, m in models.items():
            rec = m.single_frame_gain
            out[f"model {name}, recorded scale {rec:g}"] = \
                (lambda mm: lambda im, c: mm(im, centres=c))(m)
            if rec != 1.0:
                out[f"model {name}, scale 1"] = \
                    (lambda mm: lambda im, c: mm(im, centres=c, gain=1.0))(m)
            out[f"model {name}, scale {scales[name]:.3f} fitted on even presses"] = \
                (lambda mm, s: lambda im, c: mm(im, centres=c, gain=s))(m, scales[name])
        return out

    rows: list[list[str]] = []
    odd = [j for j, o in enumerate(g["odd"]) if o]
    true = np.concatenate([g["true"][j][g["ok"][j]] for j in odd])

    def score_odd(title: str, methods: dict[str, Fn]) -> None:
        for meth, fn in methods.items():
            pred = np.concatenate([fn(g["img"][j], g["rest"][j])[g["ok"][j]] for j in odd])
            rows.append(motion_row(title, meth, motion_metrics(pred, true, min_px=0.5), 0.5,
                                   len(odd), float("nan")))

    score_odd("real GelSight presses, grain-matched gel motion (odd presses)", fns())
    f0 = press.proxy.load_real_presses("gelsight").f0
    pair_fns: dict[str, Fn] = {
        "zero": lambda im, c: np.zeros((len(c), 2), np.float32),
        "mechanics rule": lambda im, c: mechanics_motion(im, f0, c),
        "ensemble (predict_motion default)": lambda im, c: ensemble_motion(im, f0, c),
        "flow": lambda im, c: flow_motion(im, f0, c),
        "flow, suppress_imprint (MarkerlessTracker's default)":
            lambda im, c: flow_motion(im, f0, c, suppress_imprint=True)}
    for name, m in models.items():
        if name in extra and m.design in ("consistent", "plain") and (
                m.design == "consistent" or m.use_ref):
            pair_fns[f"model {name}, pair"] = (lambda mm: lambda im, c: mm(im, f0, c))(m)
    score_odd("the same, from the no-contact frame", pair_fns)
    mini = press.proxy.load_real_presses("gelsight_mini")
    mrest, _ = press.proxy.marker_grid("gelsight_mini")
    for gain in (MECHANICS_GAIN, MECHANICS_GAINS["gelsight_mini"]):
        mini_fns: dict[str, Fn] = {
            "mechanics rule": lambda im, c, g=gain: mechanics_motion(im, None, c, gain=g),
            "ensemble (predict_motion default)":
                lambda im, c, g=gain: ensemble_motion(im, None, c, gain=g)}
        if gain == MECHANICS_GAIN:
            mini_fns["flow from the no-contact frame"] = lambda im, c: flow_motion(im, mini.f0, c)
            mini_fns["flow from the no-contact frame, suppress_imprint (MarkerlessTracker)"] = (
                lambda im, c: flow_motion(im, mini.f0, c, suppress_imprint=True))
            for name in extra:
                m = models[name]
                mini_fns[f"model {name}, single frame"] = (lambda mm: lambda im, c: mm(
                    im, centres=c))(m)
                if m.design == "consistent":
                    mini_fns[f"model {name}, pair from the no-contact frame"] = (
                        lambda mm: lambda im, c: mm(im, mini.f0, c))(m)
        for meth, fn in mini_fns.items():
            # The truth is ~0 (grain-matched: 0.15 px), so the error is the motion predicted.
            mag = np.concatenate([np.linalg.norm(fn(im, mrest), axis=1) for im in mini.imgs])
            rows.append([f"real GelSight Mini presses, gel does not move (truth 0), gain "
                         f"{gain:g}", meth, f"{mag.mean():.3f}", "", "", "", "", "",
                         f"{len(mini.imgs)} / 0", ""])
    frames = fots.load(args.fots)
    if len(frames) == 2:
        for (name, im, rest, d) in frames:
            clean = remove_markers(im)
            for meth, fn in fns().items():
                rows.append(motion_row(f"real FOTS GelSight Mini {name}.png, markers removed",
                                       meth, motion_metrics(fn(clean, rest), d, min_px=2.5), 2.5,
                                       1, float("nan")))
    else:
        print(f"(no FOTS frames under {args.fots}: skipped)", file=sys.stderr)
    for title, (samples, min_px) in single.contact_settings(2).items():
        if "gelsight_mini" in title or "no_contact" in title:
            continue
        t = np.concatenate([s[3] for s in samples])
        for meth, fn in fns().items():
            pred = np.concatenate([fn(s[0], s[2]) for s in samples])
            rows.append(motion_row(title, meth, motion_metrics(pred, t, min_px=min_px), min_px,
                                   len(samples), float("nan")))
    notes = [f"{machine()}.", "",
             "Single frame, no reference. e_rmse = mean per-marker error (px, the frame's own "
             "pixels), cos = mean direction cosine over markers moving at least `min px`. "
             "Output scales fitted on the even real GelSight presses (grain-matched): "
             + ", ".join(f"{k} {v:.3f}" for k, v in scales.items()) + "."]
    publish(SECTION, notes, ["data", *MOTION_COLUMNS], rows,
            "python benches/bench_motion_model_real.py" + (" --update" if args.update else ""),
            args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
