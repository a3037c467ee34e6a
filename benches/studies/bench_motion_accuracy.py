"""Accuracy of the motion model against the baselines, simulated and on the real-texture proxy.

    python benches/studies/bench_motion_accuracy.py [--model PATH] [--sim-dir DIR] [--n-sim N]
        [--press-step K] [--update]

Settings (px in each frame's own pixels; metrics of :func:`tacswitch.motion.evaluate.
motion_metrics`: e_rmse = mean per-marker Euclidean error, e_mag, NaN %, mean direction cosine
and share within 30 degrees over markers moving >= 3 px):

- **simulated, held-out** (``gel_test_indenter`` + ``gel_test_depth`` of
  :func:`tacswitch.motion.data.generate_split`, preset ``mixed``, seed 0; unseen indenters and
  unseen depths; random sensor looks, moving gel grain, capture): with the pair's reference (an
  earlier contact frame or the no-contact frame), with the no-contact reference only (the subset
  whose reference is the no-contact frame), and single frame (truth: motion from rest);
- **real-texture proxy** (:mod:`proxies.motion_proxy`: taxim's real GelSight 640 x 480 and Mini
  320 x 240 presses warped by known press / shear / twist / mixed fields, exposure drift, MJPEG or
  H.264): with the real no-contact frame as reference, and single frame.

Methods: zero motion, the outward-from-contact heuristic (``motion.heuristic``), the
contact-mechanics rule (``motion.mechanics``), dense optical flow (``motion.flow``, DIS medium;
needs a reference), the model (pair and single-frame modes). ``bench_motion_single.py`` compares
the single-frame rules on a third data set (real frames with the simulator's field).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import held_out_motion_pairs, machine, publish

from tacswitch.motion.evaluate import motion_metrics
from tacswitch.motion.infer import MotionModel, default_model_path

SECTION = "## Marker motion from markerless frames: model vs baselines (accuracy)"


def _methods(model: MotionModel, with_ref: bool, baselines: bool = True) -> dict[str, Any]:
    from tacswitch.motion.flow import flow_motion
    from tacswitch.motion.heuristic import outward_motion
    from tacswitch.motion.mechanics import mechanics_motion

    def zero(img: Any, ref: Any, c: Any) -> Any:
        return np.zeros((len(c), 2), np.float32)

    out: dict[str, Any] = {"zero": zero}
    if baselines:
        out["outward heuristic"] = lambda i, r, c: outward_motion(i, r, c)
        out["contact-mechanics rule"] = lambda i, r, c: mechanics_motion(i, r, c)
        if with_ref:
            out["flow (DIS medium)"] = lambda i, r, c: flow_motion(i, r, c)
    out["model"] = lambda i, r, c: model(i, r, c)
    return out


def _score(samples: list[tuple[Any, Any, Any, Any]], methods: dict[str, Any]
           ) -> dict[str, dict[str, float]]:
    res = {}
    for name, fn in methods.items():
        preds, trues = [], []
        t0 = time.perf_counter()
        for img, ref, cen, true in samples:
            preds.append(fn(img, ref, cen))
            trues.append(true)
        m = motion_metrics(np.concatenate(preds), np.concatenate(trues))
        m["ms"] = 1e3 * (time.perf_counter() - t0) / max(len(samples), 1)
        res[name] = m
    return res


def sim_settings(root: Path, n: int) -> dict[str, list]:
    d = held_out_motion_pairs(root, n)
    pair, nocontact, single = [], [], []
    for i in range(len(d["image"])):
        sel = d["present"][i]
        cen = d["rest"][i][sel]
        img, ref = d["image"][i], d["reference"][i]
        pair.append((img, ref, cen, d["displacement"][i][sel]))
        single.append((img, None, cen, d["disp_image"][i][sel]))
        if np.abs(d["disp_reference"][i][sel]).max() == 0:
            nocontact.append((img, ref, cen, d["displacement"][i][sel]))
    return {"sim, reference = earlier frame or no-contact": pair,
            "sim, reference = no-contact frame": nocontact, "sim, single frame": single}


def proxy_settings(press_step: int) -> dict[str, list]:
    from proxies import motion_proxy as proxy

    out: dict[str, list] = {}
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor)
        sub = data.subset(slice(None, None, press_step))
        samples = list(proxy.make_proxy(sensor, presses=sub, seed=0))
        for setting, label in (("no_contact", "no-contact reference"),
                               ("press", "unwarped press as reference"),
                               ("single", "single frame")):
            out[f"proxy {sensor}, {label}"] = [(s.img, s.ref(setting), s.rest, s.motion)
                                               for s in samples]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--model", default=None, help="ONNX model (default: the shipped one)")
    ap.add_argument("--sim-dir", default=None, help="folder of gel_test_* shards (made if absent)")
    ap.add_argument("--n-sim", type=int, default=200, help="samples per simulated split")
    ap.add_argument("--press-step", type=int, default=2, help="every K-th real press")
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--no-proxy", action="store_true")
    ap.add_argument("--no-baselines", action="store_true",
                    help="score only zero motion and the model (the baselines do not change)")
    ap.add_argument("--update", action="store_true", help="write BENCHMARKS.md's section")
    args = ap.parse_args()
    model = MotionModel(args.model or default_model_path())
    settings: dict[str, list] = {}
    if not args.no_sim:
        import tempfile

        settings |= sim_settings(Path(args.sim_dir or tempfile.mkdtemp()), args.n_sim)
    if not args.no_proxy:
        settings |= proxy_settings(args.press_step)
    rows = []
    for name, samples in settings.items():
        with_ref = samples[0][1] is not None
        methods = _methods(model, with_ref, not args.no_baselines)
        for meth, m in _score(samples, methods).items():
            rows.append([name, meth, f"{m['e_rmse_mean']:.3f} / {m['e_rmse_median']:.3f}",
                         f"{m['e_mag_mean']:.3f}", f"{m['nan_pct']:.1f}", f"{m['cos_mean']:.3f}",
                         f"{m['within30_pct']:.1f}", f"{len(samples)}", f"{m['ms']:.1f}"])
            print(" | ".join(rows[-1]), flush=True)
    notes = [f"Model: `{Path(model.path).name}` (design {model.design}). {machine()}.",
             "e_rmse / e_mag in px of each frame (640 x 480 for the proxy's GelSight); cosine "
             "and share within 30 deg over markers moving >= 3 px; a zero prediction counts "
             "as cosine 0. Simulated numbers are measured only in simulation."]
    publish(SECTION, notes, ["setting", "method", "e_rmse mean / median", "e_mag mean",
                             "NaN %", "cosine", "within 30 deg %", "samples", "ms / frame"],
            rows, "python benches/studies/bench_motion_accuracy.py " + " ".join(sys.argv[1:]),
            args.update)


if __name__ == "__main__":
    main()
