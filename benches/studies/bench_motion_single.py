"""Marker motion from ONE markerless frame (the paper's setting) and from a no-contact reference:
zero motion, the outward rule, the shipped model and the contact-mechanics rule, on three data.

1. **real frames, modelled field** (:func:`proxies.motion_proxy.make_contact_proxy`): taxim's
   real presses (GelSight 640 x 480, 48; GelSight Mini 320 x 240, 24) keep their real imprint;
   the truth is the simulator's field of a ball press at the recorded contact (``press``), plus
   a stuck shear / twist of it (the frame warped by that field) for the other cases. The truth
   is MODELLED: real texture and imprint, simulated motion.
2. **real frames, warped by fields unrelated to the imprint** (:func:`proxies.motion_proxy.
   make_proxy`, the real-texture proxy of ``bench_motion_real.py``): from a single frame most of
   its motion is unpredictable in principle.
3. **simulated, held-out** (the ``gel_test_indenter`` + ``gel_test_depth`` splits of
   :mod:`tacswitch.motion.data`, mixed presets, unseen indenters / depths): single frame (truth:
   motion from rest) and the pairs whose reference is the no-contact frame.

Metrics (:func:`tacswitch.motion.evaluate.motion_metrics`, px in each frame's pixels): e_rmse
(mean per-marker Euclidean error), e_mag, NaN %, and over the markers whose true motion is at
least ``min px`` the mean direction cosine and the share within 30 degrees.

    python benches/studies/bench_motion_single.py [--every N] [--sim-dir DIR] [--n-sim N] [--update]
    python benches/studies/bench_motion_single.py --calibrate     # the mechanics rule's gains (sim only)
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import (
    MOTION_COLUMNS,
    held_out_motion_pairs,
    machine,
    motion_row,
    publish,
    pure_press_gains,
)
from proxies import motion_proxy as proxy

from tacswitch.motion.ensemble import ensemble_motion
from tacswitch.motion.evaluate import motion_metrics
from tacswitch.motion.heuristic import outward_motion
from tacswitch.motion.infer import MotionModel
from tacswitch.motion.mechanics import MECHANICS_GAIN, mechanics_motion
from tacswitch.sim.presets import MECHANICS_GAINS, OUTWARD_GAINS, PRESETS

SECTION = "## Marker motion from a single frame: contact-mechanics rule vs outward rule and model"
#: ``fn(img, ref, centres, sensor)``: ``sensor`` names the frame's press gains
#: (``sim.presets.MECHANICS_GAINS`` / ``OUTWARD_GAINS``).
Predict = Callable[[np.ndarray, Any, np.ndarray, str], np.ndarray]
MECH_DEFAULT = f"mechanics rule, default gain {MECHANICS_GAIN:g}"
#: Rules whose scale-fitted diagnostic row is shown too.
SCALED = ("outward rule", MECH_DEFAULT)


def methods(with_ref: bool) -> dict[str, Predict]:
    model = MotionModel(threads=2)
    out: dict[str, Predict] = {
        "zero": lambda i, r, c, s: np.zeros((len(c), 2), np.float32),
        "outward rule": lambda i, r, c, s: outward_motion(i, r, c),
        "outward rule, per-sensor gain": lambda i, r, c, s: outward_motion(
            i, r, c, gain=OUTWARD_GAINS[s]),
        "model (shipped)": lambda i, r, c, s: model(i, ref=r, centres=c),
        "mechanics rule, old gain 1.02": lambda i, r, c, s: mechanics_motion(i, r, c, gain=1.02),
        MECH_DEFAULT: lambda i, r, c, s: mechanics_motion(i, r, c),
        "mechanics rule, per-sensor gain": lambda i, r, c, s: mechanics_motion(
            i, r, c, gain=MECHANICS_GAINS[s]),
        # What predict_motion runs without a reference, and against a reference it takes for a
        # no-contact frame (``"auto"``; it runs flow on the others).
        'ensemble (rule + single-frame model; method="ensemble")':
            lambda i, r, c, s: ensemble_motion(i, r, c),
        "ensemble, per-sensor gain": lambda i, r, c, s: ensemble_motion(
            i, r, c, gain=MECHANICS_GAINS[s]),
    }
    if with_ref:
        from tacswitch.motion.flow import DEFAULT_PRESET, flow_motion

        out[f"flow DIS {DEFAULT_PRESET} (default)"] = lambda i, r, c, s: flow_motion(i, r, c)
    return out


def score(samples: list[tuple[Any, Any, Any, Any, str]], min_px: float
          ) -> dict[str, dict[str, float]]:
    """Metrics per method over ``(img, ref, centres, true, sensor)`` samples."""
    res = {}
    true = np.concatenate([smp[3] for smp in samples])
    for name, fn in methods(samples[0][1] is not None).items():
        t0 = time.perf_counter()
        pred = np.concatenate([fn(i, r, c, s) for i, r, c, _, s in samples])
        m = motion_metrics(pred, true, min_px=min_px)
        m["ms"] = 1e3 * (time.perf_counter() - t0) / len(samples)
        res[name] = m
        if name in SCALED:
            # Diagnostic, not a method: the rule with its scale fitted by least squares on the
            # very data it is scored on (its direction unchanged): what a perfect magnitude prior
            # would give. The shipped gains come from simulated presses only.
            # A negative best scale (the rule points the wrong way on average) is clamped to
            # 0; the direction figures stay the rule's own (a positive scale does not change
            # them).
            k = max(0.0, float((pred * true).sum() / max(float((pred * pred).sum()), 1e-12)))
            o = motion_metrics(pred * k, true, min_px=min_px)
            o |= {"cos_mean": m["cos_mean"], "within30_pct": m["within30_pct"], "ms": m["ms"]}
            res[f"{name}, scale x{k:.2f} fitted here (upper bound)"] = o
    return res


def contact_settings(every: int) -> dict[str, tuple[list, float]]:
    out: dict[str, tuple[list, float]] = {}
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor)
        sub = data.subset(slice(None, None, every))
        samples = list(proxy.make_contact_proxy(sensor, presses=sub, seed=0))
        for setting in ("single", "no_contact"):
            for subset, kinds in (("press only", ("press",)), ("all cases", proxy.CONTACT_KINDS)):
                out[f"real frames + modelled field, {sensor}, {setting}, {subset}"] = (
                    [(s.img, s.ref(setting), s.rest, s.motion, sensor) for s in samples
                     if s.kind in kinds], 0.1)
    return out


def warp_settings(every: int) -> dict[str, tuple[list, float]]:
    out: dict[str, tuple[list, float]] = {}
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor)
        sub = data.subset(slice(None, None, every))
        samples = list(proxy.make_proxy(sensor, presses=sub, seed=0))
        min_px = 0.1 * proxy.MAX_AMPLITUDE_MM / proxy.MM_PER_PX[sensor]
        for setting in ("single", "no_contact"):
            out[f"real warp proxy, {sensor}, {setting}"] = (
                [(s.img, s.ref(setting), s.rest, s.motion, sensor) for s in samples], min_px)
    return out


def sim_sensors(n: int) -> tuple[list[str], list[str]]:
    """Which press law each simulated held-out sample has (``"gelsight_mini"`` or
    ``"gelsight"``: the ``mixed`` preset's GelSight at the Mini's size), in
    :func:`harness.held_out_motion_pairs` order: replays the draws of
    :func:`tacswitch.motion.data.render_gel_pair_sample` (label, then the preset) and checks the
    label against the data's."""
    from tacswitch.motion import data as mdata

    out = []
    for split in ("gel_test_indenter", "gel_test_depth"):
        base = split.removeprefix("gel_")
        classes, _ = mdata.split_spec(base)
        sid = mdata.SPLITS.index(base) + 200
        for i in range(n):
            rng = np.random.default_rng(np.random.SeedSequence([0, sid, i]))
            label = classes[int(rng.integers(len(classes)))]
            out.append((label, "gelsight_mini" if rng.random() < 0.5 else "gelsight"))
    return [s for _, s in out], [lab for lab, _ in out]


def sim_settings(root: Path, n: int) -> dict[str, tuple[list, float]]:
    d = held_out_motion_pairs(root, n)
    sensors, labels = sim_sensors(n)
    if list(d["label"]) != labels:
        raise SystemExit("sim_sensors: replayed labels differ from the data's (the generator "
                         "changed); cannot tell each sample's preset")
    single, nocontact = [], []
    for i in range(len(d["image"])):
        sel = d["present"][i]
        cen = d["rest"][i][sel]
        single.append((d["image"][i], None, cen, d["disp_image"][i][sel], sensors[i]))
        if np.abs(d["disp_reference"][i][sel]).max() == 0:
            nocontact.append((d["image"][i], d["reference"][i], cen, d["displacement"][i][sel],
                              sensors[i]))
    return split_by_gel({"simulated held-out, single": (single, 0.5),
                         "simulated held-out, no_contact": (nocontact, 0.5)})


#: The two halves of the simulated ``mixed`` preset, by the press law of their gel (each
#: sample's fifth field, :func:`sim_sensors`).
GEL_HALVES = (("gelsight", "GelSight half"),
              ("gelsight_mini", "Mini half (its gel does not move under a press)"))


def split_by_gel(sets: dict[str, tuple[list, float]]) -> dict[str, tuple[list, float]]:
    """``sets`` plus, for each, its samples of each gel (:data:`GEL_HALVES`): on the Mini half
    (taxim's Mini: no measurable press motion) the only motion is the stuck shear, which one
    frame does not show, so no single-frame method can beat zero there."""
    out = dict(sets)
    for key, (samples, min_px) in sets.items():
        for sensor, label in GEL_HALVES:
            half = [x for x in samples if x[4] == sensor]
            if half:  # a small --n-sim can leave a half empty
                out[f"{key}, {label}"] = (half, min_px)
    return out


def calibrate(n: int = 40) -> int:
    """Least-squares gains of the mechanics rule (unit gain output vs true motion) on the
    simulator's pure presses (no shear; 40 per preset, seeds [7, k] as the outward rule's
    calibration), with the no-contact reference and single-frame; per preset and pooled (the
    shipped ``MECHANICS_GAIN`` is the pooled value of both presets and both settings)."""
    for key, gain in pure_press_gains(mechanics_motion, n).items():
        print(f"{key[0]:14s} {key[1]:6s} least-squares gain {gain:.4f}")
    return 0


PRESS_SECTION = "## Real presses: radial texture motion (flow) vs the simulator's press field"


def press_flow(every: int) -> list[list[str]]:
    """Radial motion around taxim's real presses, measured by DIS flow (default preset) from the
    real no-contact frame to the press (the real grain moves with the gel), at rings of radius
    ``k a`` about the recorded contact (24 points each, inside the frame), minus the flow's mean
    over a ring near the frame border (a capture-to-capture shift); beside it the simulator's
    press field (:func:`proxies.motion_proxy.contact_fields`, ball press at the same
    contact). Medians over presses of each ring's median; also the border ring's radial flow
    about the image centre (a zoom between the captures would show there; the contacts lie near
    the image centre, so a zoom and a long-range outward flow cannot be told apart)."""
    from tacswitch.motion.flow import flow_motion

    rows = []
    ks = (1.0, 1.5, 2.0, 3.0, 4.0)
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor)
        h, w = data.f0.shape[:2]
        cc = np.array([(w - 1) / 2, (h - 1) / 2])
        ang = np.arange(24) * 2 * np.pi / 24
        unit = np.stack([np.cos(ang), np.sin(ang)], 1)
        border = (cc + np.stack([0.42 * w * np.cos(ang), 0.42 * h * np.sin(ang)], 1)
                  ).astype(np.float32)
        real: dict[float, list[float]] = {k: [] for k in ks}
        sim: dict[float, list[float]] = {k: [] for k in ks}
        zoom = []
        rng = np.random.default_rng(0)
        for i in range(0, len(data.imgs), every):
            c, a = data.centres[i], float(data.radii[i])
            fb = flow_motion(data.imgs[i], data.f0, border)
            shift = fb.mean(0)
            ub = (border - cc) / np.linalg.norm(border - cc, axis=1, keepdims=True)
            zoom.append(float(np.median(((fb - shift) * ub).sum(1))))
            press, _, st, _ = proxy.contact_fields(
                sensor, (float(c[0]), float(c[1])), a, "press", rng,
                ball_radius_mm=proxy.REAL_BALL_RADIUS_MM[sensor])
            for k in ks:
                pts = c + k * a * unit
                ok = ((pts >= 5) & (pts < np.array([w - 5, h - 5]))).all(1)
                if ok.sum() < 6:
                    continue
                p = pts[ok].astype(np.float32)
                f = flow_motion(data.imgs[i], data.f0, p) - shift
                real[k].append(float(np.median((f * unit[ok]).sum(1))))
                sm = proxy._sample_coarse(press, st, p)
                sim[k].append(float(np.median((sm * unit[ok]).sum(1))))
        for k in ks:
            r = np.asarray(real[k])
            rows.append([sensor, f"{k:g} a", f"{np.median(r):+.2f} [{np.percentile(r, 25):+.2f}, "
                         f"{np.percentile(r, 75):+.2f}]", f"{np.median(sim[k]):+.3f}",
                         f"{len(r)}"])
        rows.append([sensor, "border ring, about the image centre",
                     f"{np.median(zoom):+.2f} [{np.percentile(zoom, 25):+.2f}, "
                     f"{np.percentile(zoom, 75):+.2f}]", "-", f"{len(zoom)}"])
    return rows


def flow_measured(every: int) -> list[list[str]]:
    """Single-frame methods scored against the flow-measured motion of the real presses (the
    flow of :func:`press_flow`, border shift removed) at the sensor's marker grid, on markers at
    least 2 contact radii from the contact (beyond the imprint's shading change); cosine over
    markers the flow moved >= 0.5 px."""
    from tacswitch.motion.flow import flow_motion

    model = MotionModel(threads=2)
    fns: dict[str, Predict] = {
        "zero": lambda i, r, c, s: np.zeros((len(c), 2), np.float32),
        "outward rule": lambda i, r, c, s: outward_motion(i, r, c),
        "model (shipped)": lambda i, r, c, s: model(i, ref=r, centres=c),
        MECH_DEFAULT: lambda i, r, c, s: mechanics_motion(i, r, c),
        "mechanics rule, per-sensor gain": lambda i, r, c, s: mechanics_motion(
            i, r, c, gain=MECHANICS_GAINS[s]),
    }
    rows = []
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor)
        rest, _ = proxy.marker_grid(sensor)
        h, w = data.f0.shape[:2]
        cc = np.array([(w - 1) / 2, (h - 1) / 2])
        ang = np.arange(24) * 2 * np.pi / 24
        border = (cc + np.stack([0.42 * w * np.cos(ang), 0.42 * h * np.sin(ang)], 1)
                  ).astype(np.float32)
        preds: dict[str, list[np.ndarray]] = {k: [] for k in fns}
        trues = []
        for i in range(0, len(data.imgs), every):
            far = np.linalg.norm(rest - data.centres[i], axis=1) >= 2 * data.radii[i]
            shift = flow_motion(data.imgs[i], data.f0, border).mean(0)
            trues.append((flow_motion(data.imgs[i], data.f0, rest) - shift)[far])
            for k, fn in fns.items():
                preds[k].append(fn(data.imgs[i], None, rest, sensor)[far])
        true = np.concatenate(trues)
        for k in fns:
            m = motion_metrics(np.concatenate(preds[k]), true, min_px=0.5)
            rows.append([sensor, k, f"{m['e_rmse_mean']:.3f}", f"{m['cos_mean']:.2f}",
                         f"{m['within30_pct']:.0f}", f"{len(trues)} / {m['n_orient']}"])
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=int, default=1, help="use every N-th real press")
    ap.add_argument("--sim-dir", default=None, help="folder of gel_test_* shards (made if absent)")
    ap.add_argument("--n-sim", type=int, default=200, help="samples per simulated split")
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--no-warp", action="store_true")
    ap.add_argument("--calibrate", action="store_true")
    ap.add_argument("--press-flow", action="store_true",
                    help="only the real presses' radial texture motion vs the simulator's")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    if args.calibrate:
        return calibrate()
    if args.press_flow:
        rows = press_flow(max(1, args.every))
        notes = [f"{machine()}.", "",
                 "Radial component (px, + = outward) of DIS flow (the default preset, "
                 "`balanced`) from taxim's real no-contact frame to each real press, at rings "
                 "of radius k x the recorded contact radius a (median over the ring, then "
                 "median [IQR] over presses; the mean flow of a ring near the frame border "
                 "subtracted). The real grain moves "
                 "with the gel, so this is the real gel's outward motion, with caveats: at "
                 "r <= 1.5 a the imprint's shading change also moves the flow; the border ring "
                 "itself expands about the image centre (a zoom between captures or a long-range "
                 "outward flow: the contacts lie near the image centre, the two cannot be told "
                 "apart). Beside it: the simulator's press field at the same contact "
                 "(`proxy.contact_fields`, taxim's ball `proxy.REAL_BALL_RADIUS_MM`, the "
                 "preset's press law). Measured on "
                 "real frames; not a ground truth. The grain block matching of "
                 "`benches/studies/bench_press_calibration.py` (local, no coarse-to-fine propagation) "
                 "confirms the GelSight rings but finds the Mini's gel still (within +-0.15 px): "
                 "the Mini's flow rings here are the imprint's shading leaking outward."]
        from harness import table

        notes2 = ["", "The same flow as a (weak, real) truth for single-frame methods: each real "
                  "press alone, markers of the sensor's grid >= 2 a from the contact, cosine "
                  "over markers the flow moved >= 0.5 px (e_rmse mostly measures the magnitude "
                  "prior; the zoom caveat applies):", "",
                  table(["sensor", "method (single frame)", "e_rmse mean (px)", "cos",
                         "within 30 deg %", "presses / moved"], flow_measured(max(1, args.every))),
                  "", "Ring table:"]
        cmd = "OMP_NUM_THREADS=1 python benches/studies/bench_motion_single.py " + " ".join(sys.argv[1:])
        publish(PRESS_SECTION, notes + notes2, ["sensor", "ring", "real flow, radial px",
                                                "simulator press field, radial px", "presses"],
                rows, cmd.strip(), args.update)
        return 0
    settings = contact_settings(max(1, args.every))
    if not args.no_warp:
        settings |= warp_settings(max(1, args.every))
    if not args.no_sim:
        settings |= sim_settings(Path(args.sim_dir or tempfile.mkdtemp()), args.n_sim)
    rows = []
    for name, (samples, min_px) in settings.items():
        for meth, m in score(samples, min_px).items():
            rows.append(motion_row(name, meth, m, min_px, len(samples), m["ms"]))
            print(" | ".join(rows[-1]), flush=True)
    notes = [f"{machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', '-')}.", "",
             "**Real frames + modelled field**: taxim's real presses (GelSight 640 x 480, Mini "
             "320 x 240) with their real imprint; truth = the simulator's field "
             "(`sim.motion.contact_displacement`) of taxim's ball pressed to the recorded touch "
             "centre / radius (ball radius `proxy.REAL_BALL_RADIUS_MM`, measured from the real "
             "imprints: GelSight 2 mm, Mini 3 mm; the preset's press law calibrated on the same "
             f"presses for that ball: GelSight dilation U{PRESETS['gelsight'].press_dilation} "
             "with a 5 mm reach, Mini U(0, 0.05), as the simulator draws them; "
             "`bench_press_calibration.py`), plus for `shear` / "
             "`twist` / `shear_twist` cases a stuck "
             "shear (pitch x U(0, 0.9)^1.5) / twist (U(-0.08, 0.08) rad) of the same contact, "
             "the frame warped by that field; exposure drift + MJPEG / H.264. The truth is "
             "modelled (GelSight: up to ~3 px, as the real GelSight's grain moves; Mini: under "
             "0.05 px, as the real Mini's): cosines there are over markers moving >= 0.1 px. "
             "`press only`: the "
             "case a single frame can predict; `all cases`: with the shear / twist cases, whose "
             "shear part a symmetric imprint does not show. **Real warp proxy**: the fields of "
             "`bench_motion_real.py` (unrelated to the imprint). **Simulated held-out**: "
             "`gel_test_indenter` + `gel_test_depth` (measured only in simulation). `single`: no "
             "reference; `no_contact`: the real (or simulated) no-contact frame as reference.",
             f"Press gains: `default gain {MECHANICS_GAIN:g}` is the mechanics rule's shipped "
             "default (the least-squares gain pooled over real GelSight and Mini presses, "
             "`bench_press_calibration.py`); `old gain 1.02` its former default (least squares "
             "on the simulator's pure presses, `--calibrate`); `per-sensor gain`: each frame's "
             "sensor's gain fitted on real presses (`sim.presets.MECHANICS_GAINS` "
             f"{MECHANICS_GAINS}, `OUTWARD_GAINS` {OUTWARD_GAINS}; simulated samples: the "
             "`mixed` preset's "
             "GelSight-optics half gets the GelSight gain, the Mini half the Mini's, i.e. what a "
             "user who selected the sensor would get). No gain is fitted on these data. Rows "
             "`scale xK fitted here (upper bound)` are diagnostics, not methods: the rule "
             "rescaled by least squares on the "
             "data it is scored on (scale clamped at >= 0; cosine and within-30 are the rule's "
             "own), i.e. what a perfect magnitude prior would give."]
    cmd = "OMP_NUM_THREADS=1 python benches/studies/bench_motion_single.py " + " ".join(sys.argv[1:])
    publish(SECTION, notes, ["data, setting", *MOTION_COLUMNS], rows, cmd.strip(), args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
