"""Marker motion from rest over markerless sequences that start at the no-contact frame:
:class:`tacswitch.motion.sequence.MarkerlessTracker` against the per-frame pair methods.

Data:

1. **real frames + calibrated press field, as sequences** (``proxy.make_contact_proxy``): per
   real press (taxim's GelSight 640 x 480 / GelSight Mini 320 x 240, every ``--every``-th), the
   captured no-contact frame, then the captured press (truth: the simulator's press field of its
   recorded contact, law measured on real presses), then that press sheared / twisted / both
   (the frame warped by a stuck field of the contact; truth: press + that field). Scored on the
   last frame. Real texture and imprint, modelled motion.
2. **the same as one recording of a press, then a shear** (``proxy.make_ramp_proxy``, GelSight):
   the press built up over three frames, then sheared over four; scored on every frame, on the
   sheared frames, and on the motion since the full press (each method's own; there the truth
   is the warp alone, exactly known).
3. **simulated grasps** (``sim.grasp.render_grasp``, held-out seed 300, random sensor looks,
   GelSight and GelSight Mini presets): the markerless no-contact frame, then 30 frames of
   press, shear ramp, then hold / slip / vibration; every frame scored against the gel's true
   motion from rest, per phase (measured only in simulation).

Methods, each given only the no-contact frame as reference: zero, the outward rule, flow from
the no-contact frame, ``predict_motion(frame, no_contact)`` (auto: with a reference, the flow
from it; the ensemble before 2026-11-27), the mechanics rule alone against it, and the tracker
(which also sees the earlier frames), with its default ``anchor="contact"`` and with
``anchor="rest"``.

    python benches/bench_motion_sequence.py [--every N] [--grasps N] [--update]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))  # benches/: harness, proxies
from harness import machine, publish
from proxies import motion_proxy as proxy

from tacswitch.motion.evaluate import motion_metrics
from tacswitch.motion.flow import flow_motion
from tacswitch.motion.heuristic import outward_motion
from tacswitch.motion.infer import predict_motion
from tacswitch.motion.mechanics import mechanics_motion
from tacswitch.motion.sequence import MarkerlessTracker

SECTION = "## Markerless motion over a sequence (from the no-contact frame)"
#: ``fn(frames, no_contact, centres, sensor) -> motions``: every frame's motion from rest.
Method = Callable[[list[np.ndarray], np.ndarray, np.ndarray, str], list[np.ndarray]]


def _per_frame(fn: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]) -> Method:
    return lambda frames, f0, c, s: [fn(f, f0, c) for f in frames]


def _tracker(gain_by_sensor: bool, anchor: str = "contact") -> Method:
    def run(frames: list[np.ndarray], f0: np.ndarray, c: np.ndarray, s: str) -> list[np.ndarray]:
        tr = MarkerlessTracker(f0, c, gain=s if gain_by_sensor else None, anchor=anchor)
        return [tr.update(f) for f in frames]
    return run


METHODS: dict[str, Method] = {
    "zero": lambda frames, f0, c, s: [np.zeros((len(c), 2), np.float32) for _ in frames],
    "outward rule": _per_frame(outward_motion),
    "flow from the no-contact frame": _per_frame(flow_motion),
    "predict_motion pair (auto: the flow, with a reference)": _per_frame(
        lambda f, f0, c: predict_motion(f, f0, c)),
    "mechanics rule pair": _per_frame(lambda f, f0, c: mechanics_motion(f, f0, c)),
    "MarkerlessTracker": _tracker(False),
    "MarkerlessTracker, anchor='rest'": _tracker(False, "rest"),
}


def real_sequences(every: int) -> dict[str, list[tuple[list, np.ndarray, np.ndarray, list, str]]]:
    """``{setting: [(frames, no_contact, centres, truths, sensor)]}``; truths per frame (None:
    not scored)."""
    out: dict[str, list] = {}
    for sensor in ("gelsight", "gelsight_mini"):
        data = proxy.load_real_presses(sensor).subset(slice(None, None, every))
        by_press: dict[int, dict[str, object]] = {}
        for smp in proxy.make_contact_proxy(sensor, presses=data, seed=0):
            by_press.setdefault(smp.press, {})[smp.kind] = smp
        seqs = []
        for kinds in by_press.values():
            press = kinds["press"]
            f0 = press.ref("no_contact")  # type: ignore[attr-defined]
            for kind, smp in kinds.items():
                if kind == "press":
                    continue
                seqs.append(([press.img, smp.img], f0, smp.rest,  # type: ignore[attr-defined]
                             [None, smp.motion], sensor))  # type: ignore[attr-defined]
        out[f"real frames + calibrated field, {sensor}: no-contact -> press -> sheared"] = seqs
    return out


def ramp_sequences(every: int) -> dict[str, list[proxy.RampSequence]]:
    """``{setting: [RampSequence]}``: press then shear as one recording, per real GelSight
    press (every ``every``-th; ``proxy.make_ramp_proxy``)."""
    data = proxy.load_real_presses("gelsight").subset(slice(None, None, every))
    return {"real frames + calibrated field, gelsight: press ramp -> shear ramp, one recording":
            list(proxy.make_ramp_proxy("gelsight", presses=data, seed=0))}


def score_ramp(seqs: list[proxy.RampSequence], rows: list[list[str]], name: str) -> None:
    """Rows for every frame, the sheared frames, and the motion since the full press (the
    exactly known warp: each method's motion minus its own at the full press)."""
    for meth, fn in METHODS.items():
        t0 = time.perf_counter()
        got: dict[str, tuple[list, list]] = {k: ([], []) for k in (
            "every frame", "sheared frames", "sheared frames, motion since the full press")}
        for sq in seqs:
            ms = fn(sq.frames, sq.no_contact, sq.rest, "gelsight")
            base_p, base_t = ms[sq.pressed], sq.truths[sq.pressed]
            for j, (m, t) in enumerate(zip(ms, sq.truths, strict=True)):
                got["every frame"][0].append(m)
                got["every frame"][1].append(t)
                if j > sq.pressed:
                    got["sheared frames"][0].append(m)
                    got["sheared frames"][1].append(t)
                    got["sheared frames, motion since the full press"][0].append(m - base_p)
                    got["sheared frames, motion since the full press"][1].append(t - base_t)
        ms_per = 1e3 * (time.perf_counter() - t0) / sum(len(sq.frames) for sq in seqs)
        for part, (p, t) in got.items():
            m = motion_metrics(np.concatenate(p), np.concatenate(t), min_px=0.1)
            rows.append([name, part, meth, f"{m['e_rmse_mean']:.3f}", f"{m['cos_mean']:.2f}",
                         f"{m['within30_pct']:.0f}", f"{len(seqs)} / {m['n_orient']}",
                         f"{ms_per:.0f}"])


def sim_sequences(n: int) -> dict[str, list]:
    from tacswitch.sim.grasp import render_grasp

    out: dict[str, list] = {}
    for preset in ("gelsight_mini", "gelsight"):
        seqs = []
        for k in range(n):
            for kind in ("hold", "slip", "vibration"):
                seq = render_grasp(preset, kind, seed=[300, k], appearance="random")
                f0 = seq.scene.render(np.random.default_rng([300, 1, k]), depth=0.0).image
                seqs.append(([f.image for f in seq.frames], f0, seq.scene.rest.astype(np.float32),
                             [f.displacement.astype(np.float32) for f in seq.frames], preset,
                             list(seq.phase), kind))
        out[f"simulated grasps, {preset}"] = seqs
    return out


def score_real(seqs: list, rows: list[list[str]], name: str) -> None:
    for meth, fn in METHODS.items():
        t0 = time.perf_counter()
        pred, true = [], []
        for frames, f0, c, truths, sensor in seqs:
            ms = fn(frames, f0, c, sensor)
            for m, t in zip(ms, truths, strict=True):
                if t is not None:
                    pred.append(m)
                    true.append(t)
        ms_per = 1e3 * (time.perf_counter() - t0) / sum(len(s[0]) for s in seqs)
        m = motion_metrics(np.concatenate(pred), np.concatenate(true), min_px=0.1)
        rows.append([name, "last frame", meth, f"{m['e_rmse_mean']:.3f}", f"{m['cos_mean']:.2f}",
                     f"{m['within30_pct']:.0f}", f"{len(seqs)} / {m['n_orient']}",
                     f"{ms_per:.0f}"])


def score_sim(seqs: list, rows: list[list[str]], name: str) -> None:
    for meth, fn in METHODS.items():
        t0 = time.perf_counter()
        got = {ph: ([], []) for ph in ("all", "press", "shear", "hold", "slip", "vibration")}
        for frames, f0, c, truths, preset, phases, kind in seqs:
            sensor = "gelsight_mini" if preset == "gelsight_mini" else "gelsight"
            ms = fn(frames, f0, c, sensor)
            for m, t, ph in zip(ms, truths, phases, strict=True):
                key = ph if ph in ("press", "shear") else kind
                for k in ("all", key):
                    got[k][0].append(m)
                    got[k][1].append(t)
        ms_per = 1e3 * (time.perf_counter() - t0) / sum(len(s[0]) for s in seqs)
        for ph, (p, t) in got.items():
            m = motion_metrics(np.concatenate(p), np.concatenate(t), min_px=0.5)
            rows.append([name, ph, meth, f"{m['e_rmse_mean']:.3f}", f"{m['cos_mean']:.2f}",
                         f"{m['within30_pct']:.0f}", f"{len(seqs)} / {m['n_orient']}",
                         f"{ms_per:.0f}"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=int, default=2, help="use every N-th real press")
    ap.add_argument("--grasps", type=int, default=3, help="simulated grasps per kind and preset")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    rows: list[list[str]] = []
    for name, seqs in real_sequences(max(1, args.every)).items():
        score_real(seqs, rows, name)
        print(f"done {name}", file=sys.stderr, flush=True)
    for name, ramps in ramp_sequences(max(1, args.every)).items():
        score_ramp(ramps, rows, name)
        print(f"done {name}", file=sys.stderr, flush=True)
    for name, seqs in sim_sequences(args.grasps).items():
        score_sim(seqs, rows, name)
        print(f"done {name}", file=sys.stderr, flush=True)
    notes = [
        "Data: **real texture, modelled motion** (rows `real frames + calibrated field`) and "
        "**simulated** (rows `simulated grasps`).", "",
        f"{machine()}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}.", "",
        "Every method gets only the markerless no-contact frame as reference. "
        "`MarkerlessTracker` (`tacswitch.motion.sequence`): by default (`anchor='contact'`) the "
        "flow from the no-contact frame (imprint suppressed) while a contact appears or grows, "
        "then, while it stays, the motion at the frame where it settled plus the flow from that "
        "frame; `anchor='rest'` the flow from the no-contact frame throughout. The pair methods "
        "see one frame and the no-contact frame. Real rows: taxim's "
        "real presses, sequence no-contact -> press -> the press sheared / twisted / both "
        "(`proxy.make_contact_proxy`'s cases; truth modelled: the calibrated press field plus "
        "the stuck field), scored on the last frame, cosine over markers moving >= 0.1 px; "
        "and the same presses as one recording, the press built up over three frames, then "
        "sheared over four (`proxy.make_ramp_proxy`). "
        "Simulated rows (measured only in simulation): held-out grasps (seed 300, random sensor "
        "looks), every frame, cosine over markers moving >= 0.5 px. Nothing here was tuned on "
        "these data (the tracker has no parameter of its own).",
    ]
    cmd = "OMP_NUM_THREADS=1 python benches/bench_motion_sequence.py " + " ".join(sys.argv[1:])
    publish(SECTION, notes, ["data", "frames scored", "method", "e_rmse mean (px)", "cos",
                             "within 30 deg %", "sequences / moved", "ms / frame (busy)"],
            rows, cmd.strip(), args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
