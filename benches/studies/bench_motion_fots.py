"""Markerless motion against REAL marker motion: the two FOTS GelSight Mini frames.

The only real frames at hand whose marker motion is known: two GelSight Mini captures with a
painted marker grid (320 x 240, 9 x 11 markers) from the public FOTS project, each with the
markers' rest centres and their displacement in that frame, hand-tracked by the FOTS authors
(integer px). ``0.png``: a ball press (markers move outward, up to 6 px); ``1.png``: a press with
shear (up to 14 px). There is no no-contact frame of that sensor, so this is the single-frame
setting (the paper's): the markers are removed first (``tacswitch.remove_markers``, the default
pipeline, or the hybrid), then the motion of every marker is predicted from its rest centre on
the markerless result and scored against the FOTS truth.

Caveats, printed with the table: two frames, one sensor; the truth is rounded to whole pixels,
so directions of markers moving 1-2 px are coarse (the cosine is reported over markers moving at
least 1 px and at least 2.5 px); the markerless frame is a removal result, not a markerless
capture. Also reported: the least-squares gain of the mechanics rule on each frame (how far this
gel moves per unit of the rule's output), to compare with the gains measured on taxim's real
presses by grain matching (``bench_press_calibration.py``).

    python benches/studies/bench_motion_fots.py [--data DIR] [--update]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import MOTION_COLUMNS, machine, motion_row, publish

SECTION = "## Markerless motion against real marker motion (FOTS GelSight Mini frames)"
DATA = Path("/work/shared/data/real/fots_gelsight_mini_markers")
#: Markers moving less than this are left out of the cosine (whole-pixel truth).
MIN_PX = (1.0, 2.5)


def load(folder: Path) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """``(name, img, rest, motion)`` per frame: BGR uint8, ``N x 2`` rest centres and motions
    ``(x, y)`` px from the FOTS CSV (``Mx, My, dx, dy``)."""
    import cv2

    out = []
    for p in sorted(folder.glob("*.png")):
        img = cv2.imread(str(p))
        tab = np.loadtxt(p.with_suffix(".csv"), delimiter=",", skiprows=1, ndmin=2)
        out.append((p.stem, img, tab[:, :2].astype(np.float32), tab[:, 2:].astype(np.float32)))
    return out


def load_pair(folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                     np.ndarray] | None:
    """``(im0, im1, rest, d0, d1)`` of the two FOTS frames (press, press + shear) sharing one
    rest grid, or None (with a message on stderr) when ``folder`` does not hold them."""
    frames = load(folder)
    if len(frames) != 2 or not np.array_equal(frames[0][2], frames[1][2]):
        print(f"need the two FOTS frames (same rest grid) under {folder}", file=sys.stderr)
        return None
    (_, im0, rest, d0), (_, im1, _, d1) = frames
    return im0, im1, rest, d0, d1


def methods() -> dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]]:
    """``name -> fn(markerless, rest)``: the single-frame methods compared."""
    from tacswitch.motion.heuristic import outward_motion
    from tacswitch.motion.infer import predict_motion
    from tacswitch.motion.mechanics import mechanics_motion
    from tacswitch.sim.presets import MECHANICS_GAINS

    return {
        "zero": lambda im, c: np.zeros((len(c), 2), np.float32),
        "outward rule": lambda im, c: outward_motion(im, None, c),
        "predict_motion default (ensemble: rule + learned single-frame model)":
            lambda im, c: predict_motion(im, None, c),
        "mechanics rule, default gain 0.25": lambda im, c: mechanics_motion(im, None, c),
        f"mechanics rule, gain=\"gelsight_mini\" ({MECHANICS_GAINS['gelsight_mini']:g})":
            lambda im, c: mechanics_motion(im, None, c, gain=MECHANICS_GAINS["gelsight_mini"]),
        "learned regressor (shipped motion model)": lambda im, c: predict_motion(
            im, None, c, method="model"),
    }


def _score(rows: list[list[str]], data: str, preds: dict[str, np.ndarray], true: np.ndarray,
           frames: int, ms: dict[str, float], min_px: tuple[float, ...] = MIN_PX) -> None:
    from tacswitch.motion.evaluate import motion_metrics

    for meth, pred in preds.items():
        for mp in min_px:
            rows.append(motion_row(data, meth, motion_metrics(pred, true, min_px=mp), mp, frames,
                                   ms.get(meth, float("nan"))))


def _timed(fn, *args):  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    out = fn(*args)
    return out, 1e3 * (time.perf_counter() - t0)


def main() -> int:
    import tacswitch as ts
    from tacswitch import realproxy
    from tacswitch.motion.flow import flow_motion
    from tacswitch.motion.heuristic import outward_motion
    from tacswitch.motion.infer import predict_motion
    from tacswitch.motion.mechanics import mechanics_motion
    from tacswitch.motion.sequence import MarkerlessTracker

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DATA, help="folder of FOTS PNG + CSV pairs")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    pair = load_pair(args.data)
    if pair is None:
        return 1
    im0, im1, rest, d0, d1 = pair
    clean = [ts.remove_markers(im0), ts.remove_markers(im1)]
    hybrid = [ts.remove_markers(im, method="hybrid") for im in (im0, im1)]
    # Ghost check: both frames filled on the union of their marker masks, so the filled holes
    # sit at the same places in both and cannot carry the markers' motion into the flow.
    union = realproxy.default_mask(im0) | realproxy.default_mask(im1)
    same_holes = [ts.remove_markers(im, union) for im in (im0, im1)]

    rows: list[list[str]] = []
    gains = []
    for name, im, true in (("0.png (press)", clean[0], d0), ("1.png (press + shear)", clean[1],
                                                              d1)):
        unit = mechanics_motion(im, None, rest, gain=1.0).astype(np.float64)
        g = float((unit * true).sum()) / max(float((unit * unit).sum()), 1e-12)
        gains.append(f"{name.split()[0]} {g:.3f}")
        preds, ms = {}, {}
        for meth, fn in methods().items():
            preds[meth], ms[meth] = _timed(fn, im, rest)
        _score(rows, f"single frame: {name}", preds, true, 1, ms)
    both, t_ms = _timed(lambda: np.concatenate([predict_motion(h, None, rest) for h in hybrid]))
    _score(rows, "single frame: both, markers removed by the hybrid",
           {"predict_motion default": both}, np.concatenate([d0, d1]), 2,
           {"predict_motion default": t_ms / 2})

    # Part 2: the pair, frame 0 as the reference (the same contact), markers at their frame-0
    # positions; truth d1 - d0.
    at0 = (rest + d0).astype(np.float32)
    for label, (a, b) in (("markers removed", clean), ("holes at the same places", same_holes)):
        preds, ms = {"zero": np.zeros_like(d0)}, {"zero": 0.0}
        preds["outward rule"], ms["outward rule"] = _timed(outward_motion, b, a, at0)
        name = "flow DIS, default preset"
        preds[name], ms[name] = _timed(flow_motion, b, a, at0)
        preds["predict_motion auto"], ms["predict_motion auto"] = _timed(predict_motion, b, a,
                                                                         at0)
        _score(rows, f"pair 0.png -> 1.png (same contact), {label}", preds, d1 - d0, 1, ms,
               (1.0,))

    # Part 3: frame 1 from rest over the two-frame "video" that starts in contact.
    for label, (a, b) in (("markers removed", clean), ("holes at the same places", same_holes)):
        tr = MarkerlessTracker(None, rest)
        tr.update(a)
        seq, t_ms = _timed(tr.update, b)
        single, s_ms = _timed(predict_motion, b, None, rest)
        track = "MarkerlessTracker(None): rule on 0.png + flow 0.png -> 1.png"
        preds = {"zero": np.zeros_like(d1), "predict_motion single frame": single, track: seq}
        _score(rows, f"sequence: 1.png from rest, {label}", preds, d1, 1,
               {"zero": 0.0, "predict_motion single frame": s_ms, track: t_ms})
    print("done", file=sys.stderr, flush=True)
    notes = [
        f"{machine()}.", "",
        "Real data, real truth: the two FOTS GelSight Mini frames (320 x 240, 99 markers each, "
        "marker motion from rest hand-tracked by the FOTS authors in whole pixels; 0.png a ball "
        "press, 1.png the same contact sheared, up to 14 px). Markers removed first (TELEA "
        "default pipeline unless the row says otherwise), then each method predicts the motion "
        "from the markerless result. There is no no-contact frame of this sensor: part 1 is the "
        "single-frame setting (the paper's), part 2 the pair with 0.png as a same-contact "
        "reference (markers at their 0.png positions, truth = the change of their motion), "
        "part 3 the motion from rest of 1.png over the two frames "
        "(`MarkerlessTracker(None, rest)`: the rule on the first frame plus the flow from it). "
        "\"holes at the same places\": both frames filled on the union of their marker masks "
        "(46 % of the frame), so the filled holes cannot carry the markers' motion into the flow "
        "(a pessimistic check). Two frames of one sensor: a check, not a set to tune on; nothing "
        "was chosen on it.", "",
        "Least-squares gain of the mechanics rule on each frame (this gel's motion per unit of "
        "the rule's output): " + ", ".join(gains) + ". taxim's real GelSight measured 0.25-0.30 "
        "and taxim's real Mini 0.036 by grain matching (`bench_press_calibration.py`): this "
        "Mini's gel moves like the GelSight's, so the gain differs between units of one model; "
        "`calibrate_press_gain` measures a unit's own.",
    ]
    publish(SECTION, notes, ["data", *MOTION_COLUMNS], rows,
            "python benches/studies/bench_motion_fots.py " + " ".join(sys.argv[1:]), args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
