"""Marker motion on the real-texture proxy: taxim's real markerless presses warped by known fields.

Every method is scored against the known field at the sensor's marker grid
(:mod:`proxies.motion_proxy`): GelSight 640 x 480 (8 x 6 markers, 48 presses) and GelSight Mini
320 x 240 (11 x 9 markers, 24 presses), press / shear / twist / mixed fields up to 1.68 mm (one
Mini pitch), exposure drift and MJPEG / H.264 compression. Settings: ``no_contact`` (reference =
the real no-contact frame, a separate capture), ``press`` (reference = the unwarped press: shares
the capture's noise, optimistic), ``single`` (no reference, the paper's setting).

Metrics (px, frame pixels): e_rmse (mean per-marker Euclidean error), e_mag, NaN %, and on markers
that moved at least 0.1 Mini pitch (0.168 mm) the mean direction cosine and the share within 30
degrees. Speed: one call per frame at 320 x 240 and 640 x 480 with 2 threads (OpenCV and
onnxruntime).

    python benches/bench_motion_real.py [--quick | --every N] [--slow] [--model NAME=PATH]
                                        [--update]
    python benches/bench_motion_real.py --calibrate-outward
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from harness import interleaved, machine, named_models, publish, pure_press_gains, table
from proxies import motion_proxy as proxy

from tacswitch.motion.evaluate import motion_metrics
from tacswitch.motion.infer import MotionModel, predict_motion

SECTION = "## Marker motion on real texture (proxy)"
Predict = Callable[[np.ndarray, Any, np.ndarray], np.ndarray]


def _flow(algorithm: str, preset: str | None = None) -> Predict:
    def f(img: np.ndarray, ref: Any, rest: np.ndarray) -> np.ndarray:
        return predict_motion(img, ref, rest, method="flow", algorithm=algorithm, preset=preset)
    return f


def _outward(img: np.ndarray, ref: Any, rest: np.ndarray) -> np.ndarray:
    return predict_motion(img, ref, rest, method="outward")


def _mechanics(img: np.ndarray, ref: Any, rest: np.ndarray) -> np.ndarray:
    return predict_motion(img, ref, rest, method="mechanics")


def _ensemble(img: np.ndarray, ref: Any, rest: np.ndarray) -> np.ndarray:
    return predict_motion(img, ref, rest, method="ensemble")


def _outward_unit(img: np.ndarray, ref: Any, rest: np.ndarray) -> np.ndarray:
    from tacswitch.motion.heuristic import outward_motion

    return outward_motion(img, ref, rest, gain=1.0)


#: The outward rule with its scale fitted by least squares on the very samples it is scored on:
#: an upper bound for any scale choice (its cosine is the rule's own).
ORACLE = "outward, scale fitted on this data (upper bound)"


#: DIS presets compared (OpenCV's three and the library's own).
DIS_PRESETS = ("ultrafast", "fast", "balanced", "refined", "medium")


def _dis_label(preset: str) -> str:
    """Row name of a DIS preset; the library's default one says so."""
    from tacswitch.motion import flow

    return f"flow DIS {preset}" + (" (default)" if preset == flow.DEFAULT_PRESET else "")


def _zero(img: np.ndarray, ref: Any, rest: np.ndarray) -> np.ndarray:
    return np.zeros_like(rest)


def methods(models: dict[str, str | None], slow: bool, sensor: str
            ) -> dict[str, tuple[Predict, tuple[str, ...]]]:
    """name -> (predict(img, ref, rest), the settings it runs in)."""
    refs = ("no_contact", "press")
    out: dict[str, tuple[Predict, tuple[str, ...]]] = {
        "zero motion": (_zero, proxy.SETTINGS),
        "outward from contact (no learning)": (_outward, proxy.SETTINGS),
        ORACLE: (_outward_unit, proxy.SETTINGS),
        "contact-mechanics rule (no learning)": (_mechanics, proxy.SETTINGS),
        "ensemble (rule + learned single-frame model)": (_ensemble, ("single", "no_contact")),
        **{_dis_label(p): (_flow("dis", p), refs) for p in DIS_PRESETS},
        "flow Farneback": (_flow("farneback"), refs),
    }
    if slow and sensor == "gelsight_mini":  # 2-5 s a frame at 640 x 480 on this machine
        out["flow PCAFlow"] = (_flow("pcaflow"), refs)
        out["flow dense RLOF"] = (_flow("rlof"), refs)
        out["flow DeepFlow"] = (_flow("deepflow"), refs)
    for name, path in models.items():
        m = MotionModel(path, threads=2)
        single_ok = (not m.use_ref) or getattr(m, "design", "plain") == "consistent"

        def f(img: np.ndarray, ref: Any, rest: np.ndarray, m: MotionModel = m) -> np.ndarray:
            return m(img, ref=ref, centres=rest)
        out[f"model {name}"] = (f, proxy.SETTINGS if single_ok else refs)
    return out


def evaluate(sensor: str, meths: dict[str, tuple[Predict, tuple[str, ...]]], every: int,
             per_press: int, seed: int, stream: bool = False
             ) -> dict[tuple[str, str], dict[str, float]]:
    """Metrics per (setting, method) over the proxy samples of ``sensor``."""
    presses = proxy.load_real_presses(sensor)
    preds: dict[tuple[str, str], list[np.ndarray]] = {}
    times: dict[tuple[str, str], list[float]] = {}
    trues: list[np.ndarray] = []
    for s in proxy.make_proxy(presses=presses, per_press=per_press, seed=seed, stream=stream):
        if s.press % every:  # every kind of field on every ``every``-th press
            continue
        trues.append(s.motion)
        for name, (fn, settings) in meths.items():
            for setting in settings:
                t0 = time.perf_counter()
                p = fn(s.img, s.ref(setting), s.rest)
                times.setdefault((setting, name), []).append(time.perf_counter() - t0)
                preds.setdefault((setting, name), []).append(p)
    true = np.concatenate(trues)
    min_px = 0.1 * proxy.MAX_AMPLITUDE_MM / proxy.MM_PER_PX[sensor]
    res = {}
    for key, p in preds.items():
        pred = np.concatenate(p)
        if key[1] == ORACLE:
            pred = pred * float((pred * true).sum() / max(float((pred * pred).sum()), 1e-12))
        res[key] = motion_metrics(pred, true, min_px=min_px)
        res[key]["ms"] = 1e3 * float(np.mean(times[key]))
        res[key]["n_frames"] = len(p)
    return res


def speed(models: dict[str, str | None]) -> list[list[str]]:
    """Median time per call at 320 x 240 and 640 x 480 (2 threads), on real Mini / GelSight
    frames with the sensor's marker grid."""
    import cv2

    cv2.setNumThreads(2)
    rows = []
    frames = {}
    for sensor in ("gelsight_mini", "gelsight"):
        pr = proxy.load_real_presses(sensor)
        frames[sensor] = (pr.imgs[0], pr.f0, proxy.marker_grid(sensor)[0])
    fns: dict[str, Predict] = {
        **{_dis_label(p): _flow("dis", p) for p in DIS_PRESETS},
        "flow Farneback": _flow("farneback"),
        "outward from contact": _outward,
        "contact-mechanics rule": _mechanics,
    }
    for name, path in models.items():
        m = MotionModel(path, threads=2)
        fns[f"model {name}"] = (lambda i, r, c, m=m: m(i, ref=r, centres=c))
    res = {}
    for sensor, (img, ref, rest) in frames.items():
        calls = {n: (lambda f=f, i=img, r=ref, c=rest: f(i, r, c)) for n, f in fns.items()}
        res[sensor] = interleaved(calls, rounds=5, repeat=8)
    for n in fns:
        a, b = res["gelsight_mini"][n].median, res["gelsight"][n].median
        rows.append([n, f"{1e3 * a:.1f} ms ({1 / a:.0f} Hz)", f"{1e3 * b:.1f} ms ({1 / b:.0f} Hz)"])
    return rows


def calibrate_outward(n: int = 40) -> int:
    """Least-squares scale (in marker pitches) of the outward rule's unit output against the true
    marker motion of simulated presses (no shear), against the no-contact frame and single-frame:
    the source of ``tacswitch.motion.heuristic.OUTWARD_GAIN`` (never the proxy)."""
    from tacswitch.motion.heuristic import outward_motion

    # gain 1: the largest motion is one pitch, so the fitted scale is in pitches.
    gains = pure_press_gains(outward_motion, n)
    for preset in ("gelsight_mini", "gelsight"):
        print(f"{preset}: least-squares OUTWARD_GAIN (pitches) with ref "
              f"{gains[preset, 'ref']:.4f}, single-frame "
              f"{gains[preset, 'single']:.4f} ({n} simulated presses)")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="every 4th press, no speed table")
    ap.add_argument("--every", type=int, default=1, help="use every N-th press (default: all)")
    ap.add_argument("--slow", action="store_true",
                    help="also PCAFlow, dense RLOF and DeepFlow (GelSight Mini only)")
    ap.add_argument("--model", action="append", default=[], metavar="NAME=PATH",
                    help="score this ONNX motion model too (default: the shipped one)")
    ap.add_argument("--per-press", type=int, default=1, help="random fields per press and kind")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stream", action="store_true",
                    help="capture no-contact frame, press and warp as one recording "
                         "(proxy.make_proxy(stream=True))")
    ap.add_argument("--sensors", nargs="+", default=["gelsight_mini", "gelsight"],
                    choices=sorted(proxy.SENSORS))
    ap.add_argument("--calibrate-outward", action="store_true")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    if args.calibrate_outward:
        return calibrate_outward()
    models = named_models(ap, args.model)
    every = 4 if args.quick else max(1, args.every)
    notes = [f"Machine: {machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', '-')}.",
             "",
             "Real markerless frames (taxim: GelSight 640 x 480, 48 presses, 8 x 6 marker grid; "
             "GelSight Mini 320 x 240, 24 presses, 11 x 9 grid), each warped by a press, shear, "
             "twist and mixed field (one each, up to 1.68 mm = one Mini pitch) centred on the "
             "real contact; the real grain moves with the warp. The warped frame gets an "
             "exposure / white-balance drift (gain 0.85-1.15, +-8 grey levels) and MJPEG (q "
             "75-95) or H.264 (CRF 18-28) compression; references get their own compression. "
             "`no_contact`: reference = the real no-contact frame (a separate capture); `press`: "
             "reference = the unwarped press (same capture noise: optimistic); `single`: no "
             "reference. The truth is the warp alone (a real press's own lateral motion is "
             "unknown and not in it). cos / within 30: over markers that moved >= 0.168 mm.",
             ""]
    rows = []
    for sensor in args.sensors:
        meths = methods(models, args.slow, sensor)
        res = evaluate(sensor, meths, every, args.per_press, args.seed, args.stream)
        for setting in proxy.SETTINGS:
            for name in meths:
                r = res.get((setting, name))
                if r is None:
                    continue
                rows.append([sensor, setting, name, f"{r['e_rmse_mean']:.2f}",
                             f"{r['e_mag_mean']:.2f}", f"{r['nan_pct']:.0f}",
                             f"{r['cos_mean']:.2f}", f"{r['within30_pct']:.0f} %",
                             f"{r['n_frames']} / {r['n_markers']} / {r['n_orient']}",
                             f"{r['ms']:.0f}"])
        print(f"[{sensor} done]", file=sys.stderr, flush=True)
    header = ["sensor", "setting", "method", "e_rmse mean (px)", "e_mag mean (px)", "NaN %",
              "cos", "within 30 deg", "frames / markers / moved", "ms (busy machine)"]
    if not args.quick:
        srows = speed(models)
        notes_speed = ["", "Speed, one frame with 2 threads (median; real frames, 99 / 48 "
                       "markers):", "", table(["method", "320 x 240", "640 x 480"], srows), ""]
    else:
        notes_speed = []
    omp = os.environ.get("OMP_NUM_THREADS")
    cmd = (f"OMP_NUM_THREADS={omp} " if omp else "") + "python benches/bench_motion_real.py" + \
        (" --quick" if args.quick else "") + (" --slow" if args.slow else "") + \
        (f" --every {args.every}" if args.every > 1 and not args.quick else "") + \
        "".join(f" --model {s}" for s in args.model) + " --update"
    publish(SECTION, notes + notes_speed, header, rows, cmd, args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
