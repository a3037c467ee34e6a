"""Markerless motion from a reference frame: flow, the mechanics rule, the ensemble, and
``method="auto"``,
which picks one by the reference (:mod:`tacswitch.motion.reference`: does ``ref`` lack ``img``'s
contact?).

Parts:

1. **the test's statistic** (:func:`tacswitch.motion.reference.contact_energy_ratio`) on pairs
   whose kind is known: taxim's real no-contact frame against each real press; real presses
   warped by known fields against the unwarped press (same contact) and against the no-contact
   frame; simulated held-out pairs (no-contact reference / the same contact at another depth
   and load).
2. **accuracy with a reference** (e_rmse, e_mag, NaN %, cosine, share within 30 deg; px of each
   frame): real frames + the calibrated press field (``proxy.make_contact_proxy``, no-contact
   reference, all cases), the real warp proxy (``proxy.make_proxy``, no-contact and
   unwarped-press references), the real presses' own grain-matched motion (odd presses,
   markers >= 2 contact radii, no-contact reference; the capture's shift between the two
   frames included: it is in the image), and simulated held-out pairs (measured only in
   simulation).
3. **speed** of ``predict_motion(img, ref)`` (auto) against ``method="flow"`` on real frames at
   320 x 240 and 640 x 480, interleaved, medians.

    python benches/studies/bench_motion_reference.py [--every N] [--sim-dir DIR] [--n-sim N] [--update]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import (
    MOTION_COLUMNS,
    held_out_motion_pairs,
    interleaved,
    machine,
    motion_row,
    publish,
    table,
)
from proxies import motion_proxy as proxy

from tacswitch.motion.evaluate import motion_metrics
from tacswitch.motion.flow import flow_motion
from tacswitch.motion.heuristic import outward_motion
from tacswitch.motion.infer import predict_motion
from tacswitch.motion.mechanics import mechanics_motion
from tacswitch.motion.reference import NEW_CONTACT_RATIO, contact_energy_ratio
from tacswitch.sim.presets import MECHANICS_GAINS

SECTION = "## Markerless motion: which reference (flow, mechanics rule, auto)"
#: ``fn(img, ref, centres, sensor)``.
Predict = Callable[[np.ndarray, np.ndarray, np.ndarray, str], np.ndarray]
Sample = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, str]


def methods() -> dict[str, Predict]:
    return {
        "zero": lambda i, r, c, s: np.zeros((len(c), 2), np.float32),
        "outward rule": lambda i, r, c, s: outward_motion(i, r, c),
        "flow DIS balanced": lambda i, r, c, s: flow_motion(i, r, c),
        "mechanics rule, default gain": lambda i, r, c, s: mechanics_motion(i, r, c),
        "mechanics rule, sensor gain": lambda i, r, c, s: mechanics_motion(
            i, r, c, gain=MECHANICS_GAINS[s]),
        "ensemble (rule + learned model)": lambda i, r, c, s: predict_motion(
            i, r, c, method="ensemble"),
        "auto (shipped default)": lambda i, r, c, s: predict_motion(i, r, c),
        "auto, sensor gain": lambda i, r, c, s: predict_motion(i, r, c, gain=s),
    }


def real_sets(every: int) -> tuple[dict[str, tuple[list[Sample], float]],
                                    dict[str, list[float]]]:
    """Accuracy settings and the statistic's values on the real frames."""
    sets: dict[str, tuple[list[Sample], float]] = {}
    ratios: dict[str, list[float]] = {}
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor)
        ratios[f"real {sensor}: no-contact frame vs each press (all)"] = [
            contact_energy_ratio(im, data.f0) for im in data.imgs]
        sub = data.subset(slice(None, None, every))
        contact = list(proxy.make_contact_proxy(sensor, presses=sub, seed=0))
        sets[f"real frames + calibrated press field, {sensor}, no-contact ref"] = (
            [(s.img, s.ref("no_contact"), s.rest, s.motion, sensor) for s in contact], 0.1)
        ratios[f"real frames + calibrated press field, {sensor}, no-contact ref"] = [
            contact_energy_ratio(s.img, s.ref("no_contact")) for s in contact]
        warp = list(proxy.make_proxy(sensor, presses=sub, seed=0))
        min_px = 0.1 * proxy.MAX_AMPLITUDE_MM / proxy.MM_PER_PX[sensor]
        for setting, label in (("no_contact", "no-contact ref"), ("press", "same-contact ref")):
            sets[f"real warp proxy, {sensor}, {label}"] = (
                [(s.img, s.ref(setting), s.rest, s.motion, sensor) for s in warp], min_px)
            ratios[f"real warp proxy, {sensor}, {label}"] = [
                contact_energy_ratio(s.img, s.ref(setting)) for s in warp]
        sets[f"real presses, grain-matched motion >= 2 a, {sensor}, no-contact ref"] = (
            grain_truth(sensor), 0.5)
    return sets, ratios


def grain_truth(sensor: str) -> list[Sample]:
    """The odd real presses against the no-contact frame, truth = the coating grain's
    block-matched motion (:func:`tacswitch.motion.grainmatch.match_patches`, NCC peak >= 0.08)
    at the sensor's marker grid >= 2 contact radii from the contact (where the grain is not
    under the imprint), in working px; the capture's own shift is part of it."""
    from bench_press_calibration import native

    from tacswitch.motion import grainmatch as gm

    f0, imgs, _, _, k = native(sensor)
    data = proxy.load_real_presses(sensor)
    rest, _ = proxy.marker_grid(sensor)
    hp0 = gm.highpass(f0)
    out: list[Sample] = []
    pts = (rest.astype(np.float64) + 0.5) * k - 0.5
    for i in range(1, len(imgs), 2):
        found, pk = gm.match_patches(hp0, gm.highpass(imgs[i]), pts)
        far = np.linalg.norm(rest - data.centres[i], axis=1) >= 2 * data.radii[i]
        ok = far & np.isfinite(found).all(1) & (pk >= 0.08)
        out.append((data.imgs[i], data.f0, rest[ok], (found[ok] / k).astype(np.float32), sensor))
    return out


def sim_sets(root: Path, n: int) -> tuple[dict[str, tuple[list[Sample], float]],
                                          dict[str, list[float]]]:
    from bench_motion_single import sim_sensors, split_by_gel

    d = held_out_motion_pairs(root, n)
    sensors, _ = sim_sensors(n)
    nc: list[Sample] = []
    same: list[Sample] = []
    for i in range(len(d["image"])):
        sel = d["present"][i]
        smp = (d["image"][i], d["reference"][i], d["rest"][i][sel], d["displacement"][i][sel],
               sensors[i])
        (nc if np.abs(d["disp_reference"][i][sel]).max() == 0 else same).append(smp)
    sets = split_by_gel({"simulated held-out, no-contact ref": (nc, 0.5),
                         "simulated held-out, same-contact ref": (same, 0.5)})
    ratios = {k: [contact_energy_ratio(s[0], s[1]) for s in v] for k, (v, _) in sets.items()}
    return sets, ratios


def _timings(img: np.ndarray, f0: np.ndarray, same: np.ndarray, grid: np.ndarray,
             rounds: int) -> dict[str, float]:
    """Median ms per call of ``predict_motion`` with ``method="flow"`` and ``"auto"`` (the same
    validation), with a no-contact and a same-contact reference, and of the test alone."""
    fns = {"method='flow', no-contact ref": lambda: predict_motion(img, f0, grid, method="flow"),
           "auto, no-contact ref (runs the ensemble)": lambda: predict_motion(img, f0, grid),
           "method='flow', same-contact ref": lambda: predict_motion(same, img, grid,
                                                                    method="flow"),
           "auto, same-contact ref (runs flow)": lambda: predict_motion(same, img, grid),
           "the reference test alone": lambda: contact_energy_ratio(img, f0)}
    return {k: 1e3 * t.median for k, t in interleaved(fns, rounds=rounds, repeat=10).items()}


def speed(rounds: int) -> list[list[str]]:
    rows = []
    for sensor in ("gelsight_mini", "gelsight"):
        data = proxy.load_real_presses(sensor)
        grid = proxy.marker_grid(sensor)[0]
        i = len(data.imgs) // 2
        img = data.imgs[i]
        same = proxy.warp(img, proxy.random_field(
            "shear", tuple(data.centres[i]), float(data.radii[i]), 10.0,
            np.random.default_rng(0), shape=img.shape[:2]))
        h, w = img.shape[:2]
        for name, ms in _timings(img, data.f0, same, grid, rounds).items():
            rows.append([f"{w} x {h}", name, f"{ms:.2f} ms ({1e3 / ms:.0f} Hz)"])
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=int, default=2, help="use every N-th real press (proxies)")
    ap.add_argument("--sim-dir", default=None, help="folder of gel_test_* shards (made if absent)")
    ap.add_argument("--n-sim", type=int, default=40, help="samples per simulated split")
    ap.add_argument("--rounds", type=int, default=15, help="speed: interleaved rounds")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    sets, ratios = real_sets(max(1, args.every))
    s2, r2 = sim_sets(Path(args.sim_dir or tempfile.mkdtemp()), args.n_sim)
    sets |= s2
    ratios |= r2
    ratio_rows = []
    for name, v in ratios.items():
        a = np.asarray(v)
        q = np.percentile(a, [0, 10, 50, 90, 100])
        ratio_rows.append([name, str(len(a)), " / ".join(f"{x:.2f}" for x in q),
                           f"{100 * float((a < NEW_CONTACT_RATIO).mean()):.0f}"])
    rows = []
    meths = methods()
    for name, (samples, min_px) in sets.items():
        true = np.concatenate([s[3] for s in samples])
        for meth, fn in meths.items():
            t0 = time.perf_counter()
            pred = np.concatenate([fn(*s[:3], s[4]) for s in samples])
            ms = 1e3 * (time.perf_counter() - t0) / len(samples)
            m = motion_metrics(pred, true, min_px=min_px)
            rows.append(motion_row(name, meth, m, min_px, len(samples), ms))
        print(f"done {name}", file=sys.stderr, flush=True)
    speed_rows = speed(args.rounds)
    notes = [
        f"{machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}.", "",
        "`predict_motion(img, ref)` (method `auto`) runs the ensemble (the mean of the "
        "contact-mechanics rule against `ref` and the learned single-frame model; before "
        "this release the rule alone) when `ref` "
        "lacks the contact `img` shows (a no-contact reference: the imprint appears, and optical "
        "flow turns its shading into false motion) and DIS flow otherwise (a reference of the "
        "same contact, or no contact in either frame); without `ref` the ensemble on the "
        "single frame. The test (`tacswitch.motion.reference`): shading-gradient energy of `ref` "
        f"over `img` where the frames differ, new contact below {NEW_CONTACT_RATIO:g}. "
        "Threshold set in the gap between taxim's real no-contact and same-contact pairs (part "
        "1); no accuracy figure below was used to choose it.", "",
        "Part 1, the test's statistic (min / p10 / median / p90 / max; share called a new "
        "contact):", "",
        table(["pairs", "n", "ratio", "new contact %"], ratio_rows), "",
        "Part 3, speed (`predict_motion` end to end, one frame, median of 15 interleaved rounds "
        "x 10 calls, real frames, OpenCV on both cores; compare within the table):", "",
        table(["frame", "call", "median"], speed_rows), "",
        "Part 2, accuracy (px of each frame; `sensor gain`: `MECHANICS_GAINS` of the frame's "
        "sensor, as `gain=\"gelsight\"` gives; cosine over markers moving >= min px). Data: real "
        "frames + calibrated press field = taxim's real presses with their real imprint, truth "
        "the simulator's press field (law measured on real presses) plus a stuck shear / twist "
        "the frame is warped by; real warp proxy = the same real presses warped by press / "
        "shear / twist / mixed fields unrelated to the imprint (large: up to one Mini pitch, "
        "1.68 mm); real presses, grain-matched = real motion, no model; simulated = measured "
        "only in simulation.",
    ]
    cmd = "OMP_NUM_THREADS=1 python benches/studies/bench_motion_reference.py " + " ".join(sys.argv[1:])
    publish(SECTION, notes, ["data, reference", *MOTION_COLUMNS], rows, cmd.strip(),
            args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
