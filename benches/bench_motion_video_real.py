"""Markerless motion on REAL GelSight Mini videos: markers tracked for the truth, then removed.

Data: ``gsmini_slip_train`` (real GelSight Mini grasp-and-lift videos with a painted marker grid,
320 x 240, 25 fps, MPEG-4; BSD-2 licence, see the data folder). One clip per object, a fixed list
(:data:`CLIPS`: every one of the set's 29 objects in name order, its first experiment in
``labels.csv``, camera 0 and camera 2 alternating; nylon_thread's camera 2 shows no markers at
its first frame, so its camera 0), so the figures come from 29 objects, not from many clips of a
few. The development objects (even positions) were used to compare design options (flow
settings, chaining, anchoring); the tracker's direct flow (2026-11-27) also looked at the
all-object rows of the frames with a new contact, so those rows are not held out. Its contact
anchor (2026-11-30) was chosen on real GelSight texture with modelled motion, not on these
videos, where it costs those frames (BENCHMARKS.md). Nothing is fitted. The paper's own recipe:

1. truth: :class:`tacswitch.MarkerTracker` on the frames *with* markers, from the clip's first
   settled frame (the no-contact frame: the gripper is open) on every frame; its reference
   centres are the marker centres handed to the markerless methods. Settled: the camera's
   first frames are skipped as ``tacswitch slip`` skips them
   (:func:`tacswitch.tracking.settled_index`: 11 of the 29 clips start with under-exposed
   frames or frames left in the camera's buffer, a deformed gel before a jump; from frame 0,
   the truth of such a clip was cut at the jump and scored only the replayed frames, and every
   method measured motion from a frame that was not the gel at rest). A tracker is not perfect
   on sudden slips (markers smear and jump by more than half a pitch between two frames), so a
   clip is scored only up to the first frame where a tracked marker moves more than
   :data:`MAX_STEP_PITCH` of the pitch between consecutive frames, and only markers the
   tracker holds;
2. input: the markers removed, ``tacswitch.remove_markers(frame)`` (TELEA, the default mask);
   and removed as the markerless-motion guide recommends for a marker sensor's videos,
   ``remove_markers(frame, dilate=MOTION_DILATE, radius=MOTION_RADIUS)`` (a wider mask, a short
   fill: no seam of a dot's fill left for the flow to read);
3. control (**ghost control**): a removal leaves faint traces that move with the gel, which flow
   can follow. The control removes the markers with the mask grown by :data:`CONTROL_DILATE_PX`
   px (``extract_markers(...).mask`` dilated, ``tacswitch.inpaint_telea`` at radius
   :data:`CONTROL_RADIUS`), so no trace of a dot's darkness is left;
   **static-mask control**: the fills of the ghost control still sit where the dots are, so
   their places move with the gel and a method can follow them. This one fills every frame of a
   clip on one mask, the union of all its frames' marker masks grown the same way
   (:func:`static_removal`): the holes stay put and only the gel between them shows the motion
   (large motions leave less gel to see: shaken clips sweep the dots over much of the frame);
4. every ``--score-every``-th fed frame is scored (the video is fed at every ``--stride``-th
   frame: the sequence method sees 25 / stride frames per second).

Scores (pooled over scored frames and tracked markers): e_rmse = mean per-marker Euclidean error
(px), against zero motion (the mean truth magnitude); cos = mean direction cosine over markers
that moved >= 2 px; RMS error / RMS truth; magnitude ratio = mean predicted / mean true magnitude
over markers that moved >= 2 px (1 = right size); worse-than-zero = clips whose e_rmse exceeds
zero motion's. Rows for the held-out objects (odd positions in :data:`CLIPS`) and all objects;
nothing in tacswitch was fitted on these videos.

Results are cached per clip and method under ``bench-results/motion_video_real/`` (gitignored);
``--fresh`` recomputes.

    python benches/bench_motion_video_real.py [--stride 2] [--score-every 2] [--clips N]
        [--methods NAME ...] [--fresh] [--update]
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, publish

SECTION = "## Markerless motion on real GelSight Mini videos (markers tracked, then removed)"
DATA = Path("/work/shared/data/real/gsmini_slip_train")
CACHE = Path(__file__).resolve().parents[1] / "bench-results" / "motion_video_real"
LABEL = "real pseudo-markerless (markers removed), GelSight Mini"
#: A clip is scored up to the first frame where a tracked marker steps farther than this
#: fraction of the marker pitch between consecutive frames (the tracker's truth is unsure there).
MAX_STEP_PITCH = 0.45
#: Markers that moved at least this (px) count in the cosine and the magnitude ratio.
MIN_PX = 2.0
#: Ghost control: the marker mask grown by this many px before the fill, and the TELEA radius.
CONTROL_DILATE_PX = 4
CONTROL_RADIUS = 5
#: Removal for motion, what a user calls: ``remove_markers(frame, dilate=MOTION_DILATE,
#: radius=MOTION_RADIUS)`` (3x3-cross dilations of the extracted mask; chosen on the
#: development objects among dilate 4-5 and radius 5-12, docs/markerless-motion.md).
MOTION_DILATE = 5
MOTION_RADIUS = 5

#: ``(object, experiment, camera)``: every object, its first experiment in labels.csv, cameras
#: alternating (fixed, so runs compare; nylon_thread: camera 0, its camera 2 shows no
#: markers). Odd positions are the held-out objects.
CLIPS = [
    ("artificial_strawberry", "exp_num_1", 0), ("avocado_real", "exp_num_1", 2),
    ("bag_of_peanuts", "exp_num_1", 0), ("bag_straws", "exp_num_1", 2),
    ("ball_white_thread", "exp_num_1", 0), ("baseball", "exp_num_1", 2),
    ("blue_box", "exp_num_1", 0), ("blue_mug", "exp_num_1", 2),
    ("cellotape", "exp_num_1", 0), ("cheese_tube", "exp_num_1", 2),
    ("glass_box", "exp_num_1", 0), ("green_rope", "exp_num_1", 2),
    ("jute_basket", "exp_num_1", 0), ("lemon", "exp_num_1", 2),
    ("marker_pen", "exp_num_1", 0), ("nylon_thread", "exp_num_1", 0),
    ("pattern_cotton_cloth", "exp_num_1", 0), ("plastic_cup", "exp_num_1", 2),
    ("plug_3D", "exp_num_1", 0), ("red_sticker_tape", "exp_num_1", 2),
    ("rubber_hand", "exp_num_1", 0), ("rubber_pear", "exp_num_1", 2),
    ("rubber_salmon_fillet", "exp_num_1", 0), ("screw_driver_blue_gray", "exp_num_1", 2),
    ("screw_driver_red", "exp_num_1", 0), ("silicone_salmon_fillet", "exp_num_1", 2),
    ("tennis_ball", "exp_num_1", 0), ("wallet", "exp_num_1", 2),
    ("wooden_statue", "exp_num_1", 0),
]

#: ``fn(frames, no_contact, centres) -> motions``: every fed frame's motion from the first.
Method = Callable[[list[np.ndarray], np.ndarray, np.ndarray], list[np.ndarray]]


def _pairwise(**kw: object) -> Method:
    from tacswitch.motion.infer import predict_motion

    return lambda frames, f0, c: [predict_motion(f, f0, c, **kw) for f in frames]


def _single(frames: list[np.ndarray], f0: np.ndarray, c: np.ndarray) -> list[np.ndarray]:
    from tacswitch.motion.infer import predict_motion

    return [predict_motion(f, None, c) for f in frames]


def _tracker(**kw: object) -> Method:
    def run(frames: list[np.ndarray], f0: np.ndarray, c: np.ndarray) -> list[np.ndarray]:
        from tacswitch.motion.sequence import MarkerlessTracker

        tr = MarkerlessTracker(f0, c, **kw)
        return [tr.update(f) for f in frames]
    return run


#: ``--model``: a motion model (``tacswitch train motion --videos``) scored beside the defaults.
MODEL: Path | None = None


def _model_methods() -> dict[str, tuple[Method, bool]]:
    if MODEL is None:
        return {}
    tag = hashlib.sha1(MODEL.read_bytes()).hexdigest()[:8]
    return {f"pairwise from the first frame, model {tag}": (
                _pairwise(method="model", model=str(MODEL)), False),
            f"single frame, model {tag}": (
                lambda frames, f0, c: [_single_model(f, c) for f in frames], False)}


def _single_model(frame: np.ndarray, c: np.ndarray) -> np.ndarray:
    from tacswitch.motion.infer import predict_motion

    return predict_motion(frame, None, c, method="model", model=str(MODEL))


def methods() -> dict[str, tuple[Method, bool]]:
    """``name -> (fn, sequential)``; a sequential method sees every fed frame, the others only
    the scored ones."""
    return {
        "zero": (lambda frames, f0, c: [np.zeros((len(c), 2), np.float32) for _ in frames],
                 False),
        "MarkerlessTracker (default)": (_tracker(), True),
        "MarkerlessTracker, rest_frames=16": (_tracker(rest_frames=16), True),
        "MarkerlessTracker, anchor='rest'": (_tracker(anchor="rest"), True),
        "MarkerlessTracker, frame_to_frame=0.8": (_tracker(frame_to_frame=0.8), True),
        "MarkerlessTracker, anchor='rest', suppress_imprint=False": (
            _tracker(anchor="rest", suppress_imprint=False), True),
        "pairwise from the first frame, auto": (_pairwise(), False),
        "pairwise from the first frame, flow, suppress_imprint": (
            _pairwise(method="flow", suppress_imprint=True), False),
        # The same flow as MarkerlessTracker(anchor="rest", preset="accurate"), which reads each
        # frame from the first alone: scored frames only (DeepFlow is ~30x slower).
        "pairwise from the first frame, flow, suppress_imprint, preset='accurate'": (
            _pairwise(method="flow", suppress_imprint=True, preset="accurate"), False),
        "single frame (ensemble)": (_single, False),
        **_model_methods(),
    }


def read_video(path: Path) -> list[np.ndarray]:
    import cv2

    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    return frames


def control_removal(frame: np.ndarray) -> np.ndarray:
    """The ghost control: markers removed with the mask grown by :data:`CONTROL_DILATE_PX`."""
    from tacswitch.motion.real_pairs import markerless

    return markerless(frame, CONTROL_DILATE_PX, CONTROL_RADIUS)


def static_removal(frames: list[np.ndarray]) -> list[np.ndarray]:
    """The static-mask control: every frame filled on one mask, the union of all the clip's
    marker masks grown by :data:`CONTROL_DILATE_PX`, so the holes do not move: a method that
    reads where the fills are (they follow the dots) learns nothing from them here; only the gel
    between the holes shows the motion."""
    from tacswitch.motion.real_pairs import markerless, union_mask

    union = union_mask(frames)
    return [markerless(f, CONTROL_DILATE_PX, CONTROL_RADIUS, mask=union) for f in frames]


def truth(frames: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, int]:
    """``(centres N x 2, motions T x N x 2 with NaN = not tracked, frames trusted)``."""
    import tacswitch as ts

    tr = ts.MarkerTracker(frames[0])
    c = tr.reference.astype(np.float32)
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    np.fill_diagonal(d, np.inf)
    pitch = float(np.median(d.min(1))) if len(c) > 1 else np.inf
    out = np.full((len(frames), len(c), 2), np.nan, np.float32)
    trusted = len(frames)
    for t, f in enumerate(frames):
        m, v = tr.update(f)
        out[t, v] = m[v]
        if t > 0 and trusted == len(frames):
            step = np.linalg.norm(out[t] - out[t - 1], axis=1)
            if np.nanmax(step, initial=0.0) > MAX_STEP_PITCH * pitch:
                trusted = t
    return c, out, trusted


def clip_key(clip: tuple[str, str, int]) -> str:
    return f"{clip[0]}__{clip[1]}__cam{clip[2]}"


def run_clip(clip: tuple[str, str, int], names: list[str], stride: int, score_every: int,
             fresh: bool, tag: str = "") -> tuple[dict[str, dict[str, object]], bool]:
    """Per input kind (``removed`` / ``motion`` / ``control`` / ``static``) and method:
    predictions, truths, time; and whether the clip was cut short (see :data:`MAX_STEP_PITCH`)."""
    import tacswitch as ts
    from tacswitch.tracking import REST_LOOK_AHEAD, rest_thumbnail, settled_index

    obj, exp, cam = clip
    path = DATA / obj / exp / f"camera_{cam}.avi"
    CACHE.mkdir(parents=True, exist_ok=True)
    raw = read_video(path)
    start = settled_index([rest_thumbnail(f) for f in raw[:REST_LOOK_AHEAD]])
    raw = raw[start:]
    c, tr_all, trusted = truth(raw)
    trusted = max(trusted, 1)
    fed_idx = list(range(0, trusted, stride))
    scored_pos = list(range(0, len(fed_idx), score_every))
    gt = tr_all[[fed_idx[i] for i in scored_pos]]
    inputs = {"removed": [ts.remove_markers(raw[i]) for i in fed_idx],
              "motion": [ts.remove_markers(raw[i], dilate=MOTION_DILATE, radius=MOTION_RADIUS)
                         for i in fed_idx],
              "control": [control_removal(raw[i]) for i in fed_idx],
              "static": static_removal([raw[i] for i in fed_idx])}
    from tacswitch.motion.reference import is_new_contact

    out: dict[str, dict[str, object]] = {}
    table_ = methods()
    for kind, frames in inputs.items():
        # Scored frames showing a contact the first frame lacks (where "auto" ran the ensemble
        # before this release).
        new = np.array([is_new_contact(frames[i], frames[0]) for i in scored_pos], bool)
        for name in names:
            fn, sequential = table_[name]
            key = hashlib.sha1(f"{tag}|{name}|{kind}|{stride}|{score_every}|{start}".encode())
            cache = CACHE / f"{clip_key(clip)}__{key.hexdigest()[:10]}.npz"
            if cache.exists() and not fresh:
                z = np.load(cache)
                pred, ms = z["pred"], float(z["ms"])
            else:
                feed = frames if sequential else [frames[i] for i in scored_pos]
                t0 = time.perf_counter()
                res = fn(feed, frames[0], c)
                ms = 1e3 * (time.perf_counter() - t0) / max(len(feed), 1)
                if sequential:
                    res = [res[i] for i in scored_pos]
                pred = np.stack(res).astype(np.float32)
                np.savez(cache, pred=pred, ms=ms)
            out[f"{kind}|{name}"] = {"pred": pred, "true": gt, "ms": ms, "new": new}
    return out, trusted < len(raw)


def scores(pred: np.ndarray, true: np.ndarray) -> dict[str, float]:
    p = pred.reshape(-1, 2).astype(np.float64)
    t = true.reshape(-1, 2).astype(np.float64)
    ok = np.isfinite(t).all(1) & np.isfinite(p).all(1)
    p, t = p[ok], t[ok]
    e = np.linalg.norm(p - t, axis=1)
    tn = np.linalg.norm(t, axis=1)
    pn = np.linalg.norm(p, axis=1)
    big = tn >= MIN_PX
    cos = np.where(pn[big] > 1e-9, np.sum(p[big] * t[big], 1)
                   / np.maximum(pn[big] * tn[big], 1e-12), 0.0)
    return {"e": float(e.mean()) if e.size else np.nan,
            "zero": float(tn.mean()) if tn.size else np.nan,
            "cos": float(cos.mean()) if cos.size else np.nan,
            "rms": float(np.sqrt((e ** 2).mean() / max((tn ** 2).mean(), 1e-12))),
            "mag": float(pn[big].sum() / max(tn[big].sum(), 1e-12)) if big.any() else np.nan,
            "n": float(ok.sum()), "moved": float(big.sum())}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stride", type=int, default=2, help="feed every N-th video frame")
    ap.add_argument("--score-every", type=int, default=3, help="score every N-th fed frame")
    ap.add_argument("--clips", type=int, default=len(CLIPS), help="use the first N clips")
    ap.add_argument("--methods", nargs="*", default=None, help="method names (default: all)")
    ap.add_argument("--fresh", action="store_true", help="ignore the cache")
    ap.add_argument("--tag", default="", help="cache namespace (e.g. one per code version)")
    ap.add_argument("--per-clip", action="store_true", help="print per-clip e_rmse too")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    ap.add_argument("--model", type=Path, default=None,
                    help="also score this motion model (pairwise from the first frame and "
                         "single frame), e.g. from `tacswitch train motion --videos`")
    args = ap.parse_args()
    global MODEL
    MODEL = args.model
    if not DATA.is_dir():
        print(f"no data at {DATA}", file=sys.stderr)
        return 1
    names = list(methods()) if not args.methods else ["zero", *[m for m in args.methods
                                                                 if m != "zero"]]
    unknown = [n for n in names if n not in methods()]
    if unknown:
        ap.error(f"unknown methods {unknown}; choose from {list(methods())}")
    clips = CLIPS[:args.clips]
    per_clip: dict[tuple[str, str], list[dict[str, object]]] = {}
    truncated = 0
    t_start = time.perf_counter()
    for i, clip in enumerate(clips):
        res, cut = run_clip(clip, names, args.stride, args.score_every, args.fresh,
                              args.tag)
        n_scored = len(next(iter(res.values()))["true"])  # type: ignore[arg-type]
        truncated += int(cut)
        for key, r in res.items():
            kind, name = key.split("|", 1)
            per_clip.setdefault((kind, name), []).append({"clip": clip, "held": i % 2 == 1, **r})
        print(f"[{time.perf_counter() - t_start:5.0f} s] {clip_key(clip)}: {n_scored} frames "
              "scored", file=sys.stderr)
    header = ["data", "input", "objects", "method", "e_rmse px", "x zero", "cos (>= 2 px)",
              "RMS err / RMS truth", "magnitude ratio", "clips worse than zero", "ms / frame"]
    rows: list[list[str]] = []
    new_rows: list[list[str]] = []
    for kind, kind_label in (("removed", "markers removed (default mask)"),
                             ("motion", f"markers removed for motion (dilate={MOTION_DILATE}, "
                                        f"radius={MOTION_RADIUS})"),
                             ("control", f"ghost control (mask +{CONTROL_DILATE_PX} px)"),
                             ("static", "static-mask control (one mask per clip)")):
        for subset in ("held-out", "all"):
            zero_e = {}
            for name in names:
                recs = [r for r in per_clip[(kind, name)] if subset == "all" or r["held"]]
                pred = np.concatenate([np.asarray(r["pred"]).reshape(-1, 2) for r in recs])
                true = np.concatenate([np.asarray(r["true"]).reshape(-1, 2) for r in recs])
                s = scores(pred, true)
                clip_e = [scores(np.asarray(r["pred"]), np.asarray(r["true"])) for r in recs]
                if name == "zero":
                    zero_e = {clip_key(r["clip"]): ce["zero"]  # type: ignore[arg-type]
                              for r, ce in zip(recs, clip_e, strict=True)}
                worse = sum(ce["e"] > zero_e[clip_key(r["clip"])] + 1e-9
                            for r, ce in zip(recs, clip_e, strict=True))
                ms = float(np.mean([float(r["ms"]) for r in recs]))  # type: ignore[arg-type]
                rows.append([LABEL, kind_label, f"{subset} ({len(recs)})", name,
                             f"{s['e']:.2f}", f"{s['e'] / s['zero']:.2f}", f"{s['cos']:.2f}",
                             f"{s['rms']:.2f}", f"{s['mag']:.2f}",
                             "-" if name == "zero" else f"{worse}/{len(recs)}",
                             "-" if name == "zero" else f"{ms:.1f}"])
                if subset == "all" and not name.startswith("single frame"):
                    sel = [np.asarray(r["new"], bool) for r in recs]
                    pn = np.concatenate([np.asarray(r["pred"])[m].reshape(-1, 2)
                                         for r, m in zip(recs, sel, strict=True)])
                    tn = np.concatenate([np.asarray(r["true"])[m].reshape(-1, 2)
                                         for r, m in zip(recs, sel, strict=True)])
                    sn = scores(pn, tn)
                    n_new = sum(int(m.sum()) for m in sel)
                    new_rows.append([LABEL, kind_label, f"all, the {n_new} frames with a "
                                     "contact the first frame lacks", name,
                                     f"{sn['e']:.2f}", f"{sn['e'] / sn['zero']:.2f}",
                                     f"{sn['cos']:.2f}", f"{sn['rms']:.2f}", f"{sn['mag']:.2f}",
                                     "-", "-"])
                if args.per_clip and subset == "all" and name != "zero":
                    print(kind, name, " ".join(
                        f"{clip_key(r['clip'])[:14]}:{ce['e']:.1f}/{zero_e[clip_key(r['clip'])]:.1f}"  # type: ignore[arg-type]
                        for r, ce in zip(recs, clip_e, strict=True)), file=sys.stderr)
    notes = [f"Data: {LABEL} — {len(clips)} clips of `gsmini_slip_train`, one per object "
             f"(held-out = odd positions of the fixed list), fed every {args.stride}-th video "
             f"frame, every {args.score_every}-th fed frame scored; truth = MarkerTracker on the "
             f"frames with markers ({truncated} clips cut at a sudden slip the tracker cannot "
             "follow). x zero = e_rmse / zero motion's; magnitude ratio = mean |predicted| / "
             "mean |true| over markers that moved >= 2 px.",
             f"Machine: {machine()}"]
    command = "python benches/bench_motion_video_real.py" + (
        f" --stride {args.stride}" if args.stride != 2 else "") + (
        f" --score-every {args.score_every}" if args.score_every != 3 else "")
    publish(SECTION, notes, header, rows + new_rows, command, args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
