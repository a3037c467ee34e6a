"""Evaluation of marker-motion predictors with the paper's metrics (numpy; no torch).

Metrics over the markers of every sample (px, in the frames' own pixels):

- ``e_rmse``: per-marker Euclidean error ``|pred - true|``, mean and median (the paper names it
  e_rmse; it is the mean per-marker Euclidean error, not a root mean square);
- ``e_mag``: magnitude error ``| |pred| - |true| |``, mean and median;
- ``nan_pct``: share of markers without a prediction (a tracker's lost markers; 0 for the
  regressor by construction); the errors are over the markers that have one;
- ``orient``: angle between predicted and true motion, degrees, on markers moving >= 3 px;
- ``cos_mean``: mean cosine between predicted and true motion over the same markers (a zero
  prediction counts as cosine 0), and ``within30_pct``: their share within 30 degrees (the
  scale-free figures of issue 15).

Methods compared on the same markers (the painted ones): the regressor, a zero-motion baseline,
and the marker tracker on the true marker images (the upper reference a markerless sensor gives
up). Slip: the paper's rule (:class:`tacswitch.SlipDetector`) fed predicted motion on markerless
grasp sequences vs tracked motion on the marker images: accuracy, false alarms on hold and
vibration sequences, detection delay in frames after the slip onset.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch.slip import SlipDetector
from tacswitch.tracking import MarkerTracker

#: Markers moving at least this much (px) enter the orientation error.
ORIENT_MIN_PX = 3.0


def motion_metrics(pred: NDArray[Any], true: NDArray[Any], *,
                   min_px: float = ORIENT_MIN_PX) -> dict[str, float]:
    """The paper's metrics plus the direction cosine for stacked ``M x 2`` predictions and truths
    (NaN rows = missing); the angle and cosine figures use markers moving at least ``min_px``."""
    pred = np.asarray(pred, np.float64).reshape(-1, 2)
    true = np.asarray(true, np.float64).reshape(-1, 2)
    have = np.isfinite(pred).all(1)
    p, t = pred[have], true[have]
    e = np.linalg.norm(p - t, axis=1)
    mag = np.abs(np.linalg.norm(p, axis=1) - np.linalg.norm(t, axis=1))
    tn = np.linalg.norm(t, axis=1)
    big = tn >= min_px
    pn = np.linalg.norm(p[big], axis=1)
    # A zero prediction has no direction: cosine 0 (90 degrees), not a division by zero.
    cos = np.where(pn > 1e-9, np.sum(p[big] * t[big], 1) / np.maximum(pn * tn[big], 1e-12), 0.0)
    cos = np.clip(cos, -1.0, 1.0)
    ang = np.degrees(np.arccos(cos))

    def stat(x: NDArray[Any], f: Callable[[NDArray[Any]], Any]) -> float:
        return float(f(x)) if x.size else float("nan")

    return {"e_rmse_mean": stat(e, np.mean), "e_rmse_median": stat(e, np.median),
            "e_mag_mean": stat(mag, np.mean), "e_mag_median": stat(mag, np.median),
            "nan_pct": 100.0 * float((~have).mean()) if have.size else 0.0,
            "orient_mean_deg": stat(ang, np.mean), "orient_median_deg": stat(ang, np.median),
            "cos_mean": stat(cos, np.mean),
            "within30_pct": stat(100.0 * (ang <= 30.0), np.mean),
            "n_markers": int(have.size), "n_orient": int(big.sum())}


def track_true_markers(reference_markers: NDArray[np.uint8], image_markers: NDArray[np.uint8],
                       rest: NDArray[np.float32], pitch: float) -> NDArray[np.float32]:
    """Motion of the ``rest`` markers by the tracker on the true marker images (NaN = lost)."""
    tracker = MarkerTracker(reference_markers)
    motion, valid = tracker.update(image_markers)
    ref = tracker.reference
    out = np.full((len(rest), 2), np.nan, np.float32)
    if len(ref) == 0:
        return out
    d = np.linalg.norm(rest[:, None, :] - ref[None, :, :], axis=2)
    j = d.argmin(1)
    ok = (d[np.arange(len(rest)), j] < 0.5 * pitch) & valid[j]
    out[ok] = motion[j[ok]]
    return out


def evaluate_split(data: dict[str, NDArray[Any]], predict: Callable[..., NDArray[np.float32]],
                   *, use_ref: bool = False, pitch: float = 28.5,
                   tracking: bool = True) -> dict[str, dict[str, float]]:
    """Metrics of the regressor (``predict(img, ref, centres)``), the zero baseline and (when the
    data hold marker images) tracking, on the painted markers of every sample."""
    preds, trues, tracks = [], [], []
    t_pred = 0.0
    for i in range(len(data["image"])):
        sel = data["present"][i]
        rest = data["rest"][i]
        t0 = time.perf_counter()
        m = predict(data["image"][i], data["reference"][i] if use_ref else None, rest)
        t_pred += time.perf_counter() - t0
        preds.append(m[sel])
        trues.append(data["displacement"][i][sel])
        if tracking and "image_markers" in data:
            tr = track_true_markers(data["reference_markers"][i], data["image_markers"][i],
                                    rest, pitch)
            tracks.append(tr[sel])
    true = np.concatenate(trues)
    out = {"regressor": motion_metrics(np.concatenate(preds), true),
           "zero": motion_metrics(np.zeros_like(true), true)}
    out["regressor"]["ms_per_frame"] = 1e3 * t_pred / max(len(data["image"]), 1)
    if tracks:
        out["tracking"] = motion_metrics(np.concatenate(tracks), true)
    return out


def evaluate_slip(predict: Callable[..., NDArray[np.float32]], *, preset: str = "gelsight_mini",
                  n_per_kind: int = 6, n_frames: int = 30, seed: int = 100,
                  ref_frame: str = "none", smooth_frames: int = 1) -> dict[str, dict[str, Any]]:
    """Slip detection on rendered grasps (hold / slip / vibration) with the paper's rule alone:
    :func:`slip_on_grasps` for one source, summarised per source (``predicted`` on markerless
    frames, ``tracked`` on marker frames). ``ref_frame``: what ``predict`` gets as ``ref``:
    ``"none"``, ``"no_contact"`` or ``"grasp_start"`` (motion since the grasp start, as the
    slip rule measures it); ``smooth_frames``: the rule's moving average on the predicted
    motion (:class:`tacswitch.SlipDetector`). Returns accuracy, correct / n, false alarms per
    kind, missed slips, the delays (frames after onset) and their mean."""
    res = slip_on_grasps({"predicted": predict}, preset=preset, n_per_kind=n_per_kind,
                         n_frames=n_frames, seed=seed, ref_frame=ref_frame,
                         criteria={"displacement": SLIP_CRITERIA["displacement"]},
                         smooth_frames=smooth_frames)
    out: dict[str, dict[str, Any]] = {}
    for source in ("predicted", "tracked"):
        r = res[(source, "displacement")]
        d = r["delays"]
        out[source] = {"correct": r["correct"], "n": r["n"], "accuracy": r["accuracy"],
                       "false_alarms": {"hold": r["fa_hold"], "vibration": r["fa_vibration"]},
                       "missed": r["n_slip"] - r["slips_found"], "delays": d,
                       "delay_mean": float(np.mean(d)) if d else float("nan")}
    return out


#: Slip criteria compared on markerless motion: SlipDetector options.
SLIP_CRITERIA: dict[str, dict[str, Any]] = {
    "displacement": {},
    "rigid": {"rigid_threshold_px": "auto", "use_displacement": False},
    "both": {"rigid_threshold_px": "auto"},
}


def slip_on_grasps(sources: dict[str, Callable[..., NDArray[np.float32]]], *,
                   preset: str = "gelsight_mini", n_per_kind: int = 6, n_frames: int = 30,
                   seed: int = 100, ref_frame: str = "grasp_start",
                   criteria: dict[str, dict[str, Any]] | None = None,
                   smooth_frames: int = 1, near_contact_only: bool = False
                   ) -> dict[tuple[str, str], dict[str, Any]]:
    """Slip detection on rendered grasps (hold / slip / vibration) from markerless motion.

    Every source ``predict(img, ref, rest)`` gets each markerless frame from the grasp start on
    with ``ref`` = the markerless grasp-start frame (``ref_frame="grasp_start"``), the
    markerless no-contact frame (``"no_contact"``) or none (``"none"``); ``"tracked"`` (the
    marker tracker on the marker images, followed from the first frame) is always added as the
    upper reference. Each
    criterion (:data:`SLIP_CRITERIA`, the paper's threshold scaled to the width) starts at the
    grasp start, as in the paper. ``smooth_frames`` (the rule's moving average,
    :class:`tacswitch.SlipDetector`) applies to the predicted sources; with ``smooth_frames > 1``
    the same motion is also judged without it (``"NAME unsmoothed"``) and tracking with it
    (``"tracked smoothed"``), so each row differs from another by one thing.
    ``near_contact_only``: the predicted sources' rule sees only the markers near the
    grasp-start frame's contact (:func:`tacswitch.motion.reference.near_contact` against the
    no-contact frame), as ``tacswitch slip --markerless`` does.

    Returns per ``(source, criterion)``: ``correct``, ``n``, ``accuracy``, ``slips_found`` /
    ``n_slip``, false alarms on ``hold`` / ``vibration`` (and their counts), the delays (frames
    after the slip onset) of the detections and ``ms`` per predicted frame.
    """
    from tacswitch.motion.reference import near_contact
    from tacswitch.sim.grasp import render_grasp

    if ref_frame not in ("grasp_start", "no_contact", "none"):
        raise ValueError(f"ref_frame: unknown {ref_frame!r}; use 'grasp_start', 'no_contact' "
                         "or 'none'")
    from tacswitch._checks import as_count

    smooth = as_count(smooth_frames, "smooth_frames", 1, 1000)
    crit = SLIP_CRITERIA if criteria is None else criteria
    # (row name, motion source, smooth_frames of its detector)
    rows = [(n, n, smooth) for n in sources] + [("tracked", "tracked", 1)]
    if smooth > 1:
        rows += [(f"{n} unsmoothed", n, 1) for n in sources]
        rows += [("tracked smoothed", "tracked", smooth)]
    names = [r[0] for r in rows]
    res = {(s, c): _new_tally() for s in names for c in crit}
    kinds: tuple[Literal["slip", "hold", "vibration"], ...] = ("slip", "hold", "vibration")
    for kind in kinds:
        for k in range(n_per_kind):
            seq = render_grasp(preset, kind, n_frames=n_frames,
                               seed=np.random.SeedSequence([seed, kinds.index(kind), k]))
            rest = seq.scene.rest
            w = seq.reference.shape[1]
            g0 = seq.grasp_start
            no_contact = (seq.scene.render(np.random.default_rng([seed, 1, k]), depth=0.0).image
                          if ref_frame == "no_contact" or near_contact_only else None)
            ref = (seq.frames[g0].image if ref_frame == "grasp_start" else None
                   if ref_frame == "none" else no_contact)
            valid = (near_contact(seq.frames[g0].image, no_contact, rest)
                     if no_contact is not None and near_contact_only else None)
            onset = int(seq.params["onset"])
            motions: dict[str, list[tuple[NDArray[np.float32], Any]]] = {}
            times: dict[str, float] = {}
            for name, predict in sources.items():
                t0 = time.perf_counter()
                motions[name] = [(predict(seq.frames[t].image, ref, rest), valid)
                                 for t in range(g0, len(seq))]
                times[name] = time.perf_counter() - t0
            tracker = MarkerTracker(seq.reference)
            tracked = []
            pts = tracker.reference
            for t in range(len(seq)):
                m, v = tracker.update(seq.frames[t].image_markers)
                if t >= g0:
                    tracked.append((m, v))
            motions["tracked"] = tracked
            for name, src, n_smooth in rows:
                for cname, opts in crit.items():
                    det = SlipDetector(image_width=w, points=pts if src == "tracked" else rest,
                                          smooth_frames=n_smooth, **opts)
                    _tally(res[(name, cname)], kind, onset, _first_slip(det, motions[src], g0),
                           times.get(src), len(motions[src]))
    return _finish(res)


def _new_tally() -> dict[str, Any]:
    return {"correct": 0, "n": 0, "n_slip": 0, "slips_found": 0, "fa_hold": 0, "n_hold": 0,
            "fa_vibration": 0, "n_vibration": 0, "delays": [], "t": 0.0, "frames": 0}


def _first_slip(det: Any, motions: list[tuple[NDArray[np.float32], Any]], g0: int
                ) -> int | None:
    """The first frame (index from the sequence start; motions start at frame ``g0``) where the
    detector reports slip, or None."""
    for j, (m, v) in enumerate(motions):
        if det.update(m, v).slip:
            return g0 + j
    return None


def _tally(r: dict[str, Any], kind: str, onset: int, first: int | None, seconds: float | None,
           frames: int) -> None:
    """Counts one grasp of ``kind`` whose first detection is ``first`` into ``r``."""
    r["n"] += 1
    if seconds is not None:
        r["t"] += seconds
        r["frames"] += frames
    if kind == "slip":
        r["n_slip"] += 1
        r["slips_found"] += int(first is not None)
        r["correct"] += int(first is not None)
        if first is not None:
            r["delays"].append(first - onset)
    else:
        r[f"n_{kind}"] += 1
        r[f"fa_{kind}"] += int(first is not None)
        r["correct"] += int(first is None)


def _finish(res: dict[tuple[str, str], dict[str, Any]]) -> dict[tuple[str, str], dict[str, Any]]:
    for r in res.values():
        r["accuracy"] = r["correct"] / max(r["n"], 1)
        r["ms"] = 1e3 * r["t"] / r["frames"] if r["frames"] else float("nan")
    return res


def slip_on_videos(sources: dict[str, Callable[..., NDArray[np.float32]]], grasps: Iterable[Any],
                   *, criteria: dict[str, dict[str, Any]] | None = None,
                   smooth_frames: int = 1, near_contact_only: bool = False
                   ) -> dict[tuple[str, str], dict[str, Any]]:
    """Slip detection on grasp videos without marker truth (e.g.
    ``real_grasps`` of ``benches/proxies/slip_proxy.py``: objects with ``frames``, ``rest``,
    ``kind``, ``grasp_start`` and ``onset``): every source ``predict(img, ref, rest)`` gets each
    frame from the grasp start on with ``ref`` = the grasp-start frame; each criterion
    (:data:`SLIP_CRITERIA`) decides on the mean motion of the last ``smooth_frames`` frames.
    ``near_contact_only``: the rule sees only the markers near the grasp-start frame's contact
    (:func:`tacswitch.motion.reference.near_contact`, against frame 0 as the no-contact frame:
    the videos must start before the touch), as ``tacswitch slip --markerless`` does.
    Returns per ``(source, criterion)`` what :func:`slip_on_grasps` returns."""
    from tacswitch._checks import as_count
    from tacswitch.motion.reference import near_contact

    smooth = as_count(smooth_frames, "smooth_frames", 1, 1000)
    crit = SLIP_CRITERIA if criteria is None else criteria
    res = {(s, c): _new_tally() for s in sources for c in crit}
    for i, g in enumerate(grasps):
        n = len(g.frames)
        if g.kind not in ("slip", "hold", "vibration"):
            raise ValueError(f"grasps: item {i}: kind must be 'slip', 'hold' or 'vibration'; "
                             f"got {g.kind!r}")
        g0 = int(g.grasp_start)
        if not 0 <= g0 < n or not 0 <= int(g.onset) < n:
            raise ValueError(f"grasps: item {i}: grasp_start {g0} and onset {g.onset} must be "
                             f"frame indices (0..{n - 1})")
        ref = g.frames[g0]
        valid = near_contact(ref, g.frames[0], g.rest) if near_contact_only else None
        for name, predict in sources.items():
            t0 = time.perf_counter()
            motions = [(predict(g.frames[t], ref, g.rest), valid)
                       for t in range(g0, n)]
            sec = time.perf_counter() - t0
            for cname, opts in crit.items():
                det = SlipDetector(image_width=g.frames.shape[2], points=g.rest,
                                      smooth_frames=smooth, **opts)
                _tally(res[(name, cname)], g.kind, int(g.onset), _first_slip(det, motions, g0),
                       sec, len(motions))
    return _finish(res)
