"""The real gel's outward motion around real presses; the simulator's press law calibrated on it.

1. **Measurement** (:func:`tacswitch.motion.grainmatch.press_profile`): taxim's real GelSight and
   GelSight Mini presses (both captured at 640 x 480; measured there, reported in the working
   size's px: GelSight 640 x 480, Mini 320 x 240), each block-matched against the real
   no-contact frame on high-passed grain patches (48 px, a patch every 16 px), jointly fitted
   by a per-press similarity (shift / zoom / roll between captures) plus a radial profile
   ``g(r / a)`` about the recorded contact shared by the presses (zero from 8 a on). Also the
   raw ring means (nothing removed) for comparison with the DIS flow table.
2. **Estimator check**: the same real presses warped by a known radial bump (2 px at 3 a) plus
   a 1e-3 zoom; the profile's change recovers the bump.
3. **Geometry** (:func:`ball_geometry`): which ball made the presses. The simulator's shading
   (Taxim's tables, :func:`tacswitch.sim.optics.shade_taxim`) of a ball of radius ``R`` pressed
   to each recorded contact radius ``a`` (depth ``R - sqrt(R^2 - a^2)``) against the real
   colour change, both as the median change on rings about the contact; the radius with the
   smallest relative profile error is :data:`proxies.motion_proxy.REAL_BALL_RADIUS_MM`.
4. **Calibration**: the simulator's press law (:func:`tacswitch.sim.motion.contact_displacement`
   via :func:`proxies.motion_proxy.contact_fields`, that ball pressed to the recorded contacts) at
   unit gain for a grid of reaches ``decay_mm``; least-squares gain per reach against the
   even-index presses' profile over 1.5-6 a; the best reach and its gain; the gain range of
   the presses (10th-90th percentile of per-press gains, each press's rings with its own fitted
   similarity removed). Checked on the odd-index presses.

    OMP_NUM_THREADS=1 python benches/studies/bench_press_calibration.py [--update]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, publish, table
from proxies import motion_proxy as proxy

from tacswitch.motion import grainmatch as gm
from tacswitch.motion.calibration import calibrate_press_gain
from tacswitch.sim.presets import get_preset

SECTION = ("## Real presses: the gel's outward motion (grain block matching) and the "
           "calibrated press law")
#: Profile knots, in contact radii (the profile is zero from the last one on).
KNOTS = np.array([1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0])
#: Below this fitted peak (px) the reach is not identifiable: the gel thickness is kept.
MIN_SHAPE_PX = 0.1
#: Reaches (mm) tried for the press law's smoothing (the presets' gel thickness among them).
DECAYS = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0)
#: Ball radii (mm) tried for the presses' geometry (every one above every recorded contact).
BALL_RADII = (2.0, 2.25, 2.5, 3.0, 4.0, 6.0)
#: Rings (contact radii) of the geometry's change profile.
GEOMETRY_RINGS = np.array([0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0])


def native(sensor: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """taxim's frames at capture size: ``f0, imgs, centres, radii`` and the factor capture px
    per working px."""
    from tacswitch.realproxy import _taxim_pack

    pack = _taxim_pack(sensor)
    k = pack["f0"].shape[1] / proxy.SENSORS[sensor][0]
    return (pack["f0"], pack["imgs"], pack["touch_center"].astype(np.float64),
            pack["touch_radius"].astype(np.float64), k)


def raw_rings(f0: np.ndarray, imgs: np.ndarray, centres: np.ndarray, radii: np.ndarray,
              qs: np.ndarray, sims: np.ndarray | None = None) -> np.ndarray:
    """Per press, the mean radial block-matched motion on rings ``q a`` (capture px); with
    ``sims`` each press's fitted similarity removed first."""
    h, w = f0.shape[:2]
    about = ((w - 1) / 2, (h - 1) / 2)
    hp0 = gm.highpass(f0)
    out = np.full((len(imgs), len(qs)), np.nan)
    for i in range(len(imgs)):
        out[i], _ = gm.radial_rings(hp0, gm.highpass(imgs[i]), tuple(centres[i]),
                                    qs * radii[i], background=None if sims is None else sims[i],
                                    about=about)
    return out


def ball_geometry(sensor: str, every: int = 3) -> dict[str, np.ndarray]:
    """Median colour change (grey levels, distance over BGR of frames blurred at 2 px) on rings
    ``GEOMETRY_RINGS`` ``x a`` about the recorded contacts of every ``every``-th press: the real
    press against the real no-contact frame (``"real"``) and the simulator's shading of a ball of
    each radius in :data:`BALL_RADII` pressed to the same contact radius (``"R=..."``; NaN
    where the ball is smaller than a contact), at capture size. Medians over the presses."""
    import cv2

    from tacswitch.sim.motion import pressed_ball
    from tacswitch.sim.optics import load_calibration, shade_taxim

    f0, imgs, cen, rad, _ = native(sensor)
    cal = load_calibration(sensor)
    h, w = f0.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    b0 = cv2.GaussianBlur(f0.astype(np.float32), (0, 0), 2)
    out: dict[str, list[list[float]]] = {"real": []} | {f"R={r:g}": [] for r in BALL_RADII}
    for i in range(0, len(imgs), every):
        (cx, cy), a = cen[i], float(rad[i])
        r = np.hypot(xx - cx, yy - cy) / a
        rings = [(r > q - 0.125) & (r <= q + 0.125) for q in GEOMETRY_RINGS]
        real = np.linalg.norm(cv2.GaussianBlur(imgs[i].astype(np.float32), (0, 0), 2) - b0,
                              axis=2)
        out["real"].append([float(np.median(real[m])) for m in rings])
        for big_r in BALL_RADII:
            if big_r <= a * cal.pixmm:
                out[f"R={big_r:g}"].append([np.nan] * len(rings))
                continue
            gel, _, _ = pressed_ball(h, w, cal.pixmm, (cx, cy), a, big_r)
            sim = np.linalg.norm(shade_taxim(gel, cal.pixmm, cal), axis=2)
            out[f"R={big_r:g}"].append([float(np.median(sim[m])) for m in rings])
    return {k: np.nanmedian(np.array(v), 0) for k, v in out.items()}


def sim_rings(sensor: str, centres: np.ndarray, radii: np.ndarray, qs: np.ndarray,
              decay_mm: float | None, dilation: float | None) -> np.ndarray:
    """The simulator's press law (unit gain unless ``dilation``) at the same contacts (working
    px), mean radial motion on rings ``q a`` inside the frame, per press."""
    p = get_preset(sensor)
    ang = np.arange(32) * 2 * np.pi / 32
    unit = np.stack([np.cos(ang), np.sin(ang)], 1)
    out = np.full((len(centres), len(qs)), np.nan)
    for i, (c, a) in enumerate(zip(centres, radii, strict=True)):
        rng = np.random.default_rng([11, i])
        press, _, st, _ = proxy.contact_fields(sensor, (float(c[0]), float(c[1])), float(a),
                                               "press", rng, dilation=dilation,
                                               decay_mm=decay_mm,
                                               ball_radius_mm=proxy.REAL_BALL_RADIUS_MM[sensor])
        for j, q in enumerate(qs):
            pts = c + q * a * unit
            ok = ((pts >= 2) & (pts < np.array([p.width - 2, p.height - 2]))).all(1)
            if ok.sum() >= 6:
                v = proxy._sample_coarse(press, st, pts[ok].astype(np.float32))
                out[i, j] = float((v * unit[ok]).sum(1).mean())
    return out


def check_estimator(sensor: str, amp: float = 2.0, zoom: float = 1e-3) -> tuple[np.ndarray,
                                                                                  np.ndarray,
                                                                                  float]:
    """Every 3rd press warped by ``amp * exp(-((r / a - 3) / 1.2)^2)`` outward plus ``zoom``
    about the image centre: recovered profile change (capture px), the truth, zoom change."""
    f0, imgs, cen, rad, _ = native(sensor)
    sel = slice(0, None, 3)
    imgs, cen, rad = imgs[sel], cen[sel], rad[sel]
    h, w = f0.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    cc = ((w - 1) / 2, (h - 1) / 2)
    warped = []
    for im, c, a in zip(imgs, cen, rad, strict=True):
        rx, ry = xs - c[0], ys - c[1]
        r = np.hypot(rx, ry) + 1e-6
        m = amp * np.exp(-((r / a - 3.0) / 1.2) ** 2)
        v = np.stack([m * rx / r + zoom * (xs - cc[0]), m * ry / r + zoom * (ys - cc[1])], -1)
        warped.append(proxy.warp_dense(im, v.astype(np.float32)))
    g0, s0 = gm.press_profile(f0, imgs, cen, rad, KNOTS)
    g1, s1 = gm.press_profile(f0, np.stack(warped), cen, rad, KNOTS)
    truth = amp * np.exp(-((KNOTS[:-1] - 3.0) / 1.2) ** 2)
    return g1 - g0, truth, float(np.median(s1[:, 2] - s0[:, 2]))


def calibrate(sensor: str) -> dict:
    """Measurement, calibration on even presses and check on odd ones for one sensor."""
    f0, imgs, cen, rad, k = native(sensor)
    qs = KNOTS[:-1]
    halves = {"even": slice(0, None, 2), "odd": slice(1, None, 2)}
    prof, sims = {}, {}
    for name, sel in halves.items():
        g, s = gm.press_profile(f0, imgs[sel], cen[sel], rad[sel], KNOTS)
        prof[name], sims[name] = g / k, s
    raw = raw_rings(f0, imgs, cen, rad, qs) / k
    # Working-size contacts (pixel centres at integers) for the simulator.
    wc, wr = (cen + 0.5) / k - 0.5, rad / k
    ev = halves["even"]
    fit = qs <= 6.0
    fits = {}
    for dm in DECAYS:
        unit = np.nanmean(sim_rings(sensor, wc[ev], wr[ev], qs, dm, 1.0), 0)
        gain = max(0.0, float((unit[fit] * prof["even"][fit]).sum() / (unit[fit] ** 2).sum()))
        err = float(np.sqrt(((gain * unit[fit] - prof["even"][fit]) ** 2).mean()))
        fits[dm] = (dm, gain, err, unit)
    dm, gain, err, unit = min(fits.values(), key=lambda f: f[2])
    identifiable = float(np.abs(gain * unit[fit]).max()) >= MIN_SHAPE_PX
    if not identifiable:
        # A field this small has no measurable shape: keep the reach at the gel thickness and
        # fit the gain only.
        dm, gain, err, unit = fits[get_preset(sensor).gel_thickness_mm]
    # Per-press gains: each even press's rings with its own fitted similarity removed.
    per = raw_rings(f0, imgs[ev], cen[ev], rad[ev], qs, sims["even"]) / k
    unit_each = sim_rings(sensor, wc[ev], wr[ev], qs, dm, 1.0)
    gains = []
    for i in range(len(per)):
        ok = fit & np.isfinite(per[i]) & np.isfinite(unit_each[i])
        den = float((unit_each[i, ok] ** 2).sum())
        if den > 0:
            gains.append(max(0.0, float((unit_each[i, ok] * per[i, ok]).sum()) / den))
    od = halves["odd"]
    p = get_preset(sensor)
    old = np.nanmean(sim_rings(sensor, wc[od], wr[od], qs, p.gel_thickness_mm,
                               float(np.mean((0.15, 0.4)))), 0) \
        if p.press_decay_mm is not None or p.press_dilation != (0.15, 0.4) else None
    now = np.nanmean(sim_rings(sensor, wc[od], wr[od], qs, p.press_decay_mm,
                               float(np.mean(p.press_dilation))), 0)
    return {"profile": prof, "raw": np.nanmedian(raw, 0), "decay_mm": dm, "gain": gain,
            "sims": sims,
            "identifiable": identifiable,
            "rmse": err, "fit": gain * unit, "gain_range": np.percentile(gains, [10, 50, 90]),
            "zoom": {n: float(np.median(s[:, 2])) for n, s in sims.items()},
            "old_odd": old, "preset_odd": now}


def grain_truth(sensor: str, sims: dict[str, np.ndarray]) -> dict[str, list]:
    """Per press (even-index presses first, then odd): the real frame (``img``, working size),
    the sensor's marker grid (``rest``), the grain-matched real motion there (``true``: each
    press's fitted similarity removed; working px), the markers where it counts (``ok``: >= 2 a
    from the contact, NCC peak >= 0.08) and whether the press is odd (held out)."""
    f0, imgs, _, _, k = native(sensor)
    data = proxy.load_real_presses(sensor)
    rest, _ = proxy.marker_grid(sensor)
    h, w = f0.shape[:2]
    about = ((w - 1) / 2, (h - 1) / 2)
    hp0 = gm.highpass(f0)
    order = list(range(0, len(imgs), 2)) + list(range(1, len(imgs), 2))
    sim_all = np.concatenate([sims["even"], sims["odd"]])
    out: dict[str, list] = {"img": [], "rest": [], "ok": [], "true": [], "odd": []}
    for j, i in enumerate(order):
        pts = (rest.astype(np.float64) + 0.5) * k - 0.5
        found, pk = gm.match_patches(hp0, gm.highpass(imgs[i]), pts)
        d = (found - gm.similarity_at(sim_all[j], pts, about)) / k
        far = np.linalg.norm(rest - data.centres[i], axis=1) >= 2 * data.radii[i]
        out["img"].append(data.imgs[i])
        out["rest"].append(rest)
        out["ok"].append(far & np.isfinite(d).all(1) & (pk >= 0.08))
        out["true"].append(d.astype(np.float32))
        out["odd"].append(i % 2 == 1)
    return out


def truth_and_rules(sensor: str, sims: dict[str, np.ndarray]) -> dict[str, list[np.ndarray]]:
    """Per press (even-index presses first, then odd): the grain-matched real motion at the
    sensor's marker grid (:func:`grain_truth`, where it counts) and the single-frame rules at
    unit gain there (both rules are linear in their gain). The real measurement as a (noisy)
    truth."""
    from tacswitch.motion.heuristic import outward_motion
    from tacswitch.motion.mechanics import mechanics_motion

    g = grain_truth(sensor, sims)
    out: dict[str, list[np.ndarray]] = {"true": [], "outward": [], "mechanics": [], "odd": []}
    for img, rest, ok, true, odd in zip(g["img"], g["rest"], g["ok"], g["true"], g["odd"],
                                        strict=True):
        out["true"].append(true[ok])
        out["outward"].append(outward_motion(img, None, rest, gain=1.0)[ok])
        out["mechanics"].append(mechanics_motion(img, None, rest, gain=1.0)[ok])
        out["odd"].append(np.array(odd))
    return out


def ls_scale(pred: list[np.ndarray], true: list[np.ndarray]) -> float:
    """Least-squares scale of ``pred`` against ``true``, clamped at 0."""
    p, t = np.concatenate(pred), np.concatenate(true)
    return max(0.0, float((p * t).sum() / max(float((p * p).sum()), 1e-12)))


def rule_gains(data: dict[str, dict[str, list[np.ndarray]]]) -> dict[str, float]:
    """The rules' gains fitted on the even presses: per sensor and pooled over both sensors
    (each in its working px)."""
    out = {}
    for rule in ("mechanics", "outward"):
        pp, tt = [], []
        for sensor, d in data.items():
            ev = [j for j, o in enumerate(d["odd"]) if not o]
            p, t = [d[rule][j] for j in ev], [d["true"][j] for j in ev]
            out[f"{rule}/{sensor}"] = ls_scale(p, t)
            pp += p
            tt += t
        out[f"{rule}/pooled"] = ls_scale(pp, tt)
    return out


def truth_rows(sensor: str, d: dict[str, list[np.ndarray]], fitted: dict[str, float],
               selfcal: float) -> list[list[str]]:
    """Single-frame methods on the held-out (odd) presses against the real measurement."""
    from tacswitch.motion.evaluate import motion_metrics
    from tacswitch.motion.heuristic import OUTWARD_GAIN
    from tacswitch.motion.mechanics import MECHANICS_GAIN
    from tacswitch.sim.presets import MECHANICS_GAINS, OUTWARD_GAINS

    od = [j for j, o in enumerate(d["odd"]) if o]
    true = np.concatenate([d["true"][j] for j in od])
    mech = np.concatenate([d["mechanics"][j] for j in od])
    outw = np.concatenate([d["outward"][j] for j in od])
    preds = {
        "zero": (np.zeros_like(true), "-"),
        f"outward rule, default gain {OUTWARD_GAIN:g}": (OUTWARD_GAIN * outw, "-"),
        f"outward rule, {sensor} gain {OUTWARD_GAINS[sensor]:g}":
            (OUTWARD_GAINS[sensor] * outw, f"{fitted['outward/' + sensor]:.3f}"),
        "mechanics rule, old gain 1.02": (1.02 * mech, "-"),
        f"mechanics rule, default gain {MECHANICS_GAIN:g}":
            (MECHANICS_GAIN * mech, f"{fitted['mechanics/pooled']:.3f} (pooled)"),
        f"mechanics rule, {sensor} gain {MECHANICS_GAINS[sensor]:g}":
            (MECHANICS_GAINS[sensor] * mech, f"{fitted['mechanics/' + sensor]:.3f}"),
        f"mechanics rule, self-calibrated {selfcal:.3f}": (selfcal * mech, "-"),
    }
    rows = []
    for n, (pred, fit) in preds.items():
        m = motion_metrics(pred, true, min_px=0.5)
        rows.append([sensor, n, fit, f"{m['e_rmse_mean']:.3f}", f"{m['cos_mean']:.2f}",
                     f"{m['within30_pct']:.0f}", f"{len(od)} / {len(true)} / {m['n_orient']}"])
    rows.append([sensor, "(truth: mean length)", "-", f"{np.linalg.norm(true, axis=1).mean():.3f}",
                 "-", "-", "-"])
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    ap.add_argument("--no-check", action="store_true", help="skip the estimator check")
    args = ap.parse_args()
    qs = KNOTS[:-1]
    rows, notes_fit, check, rule_rows, geo_rows = [], [], [], [], []
    geo_warn: list[str] = []
    tdata: dict[str, dict[str, list[np.ndarray]]] = {}
    selfcal: dict[str, Any] = {}
    for sensor in ("gelsight", "gelsight_mini"):
        geo = ball_geometry(sensor)
        real = geo.pop("real")
        errs = {k: float(np.sqrt(np.nanmean(((v - real) / real) ** 2))) for k, v in geo.items()}
        best = min(errs, key=lambda k: errs[k] if np.isfinite(errs[k]) else np.inf)
        geo_rows.append([sensor, "real", *(f"{x:.1f}" for x in real), "-"])
        for k, v in geo.items():
            mark = " (best)" if k == best else ""
            geo_rows.append([sensor, f"simulated, ball {k} mm{mark}", *(f"{x:.1f}" for x in v),
                             f"{errs[k]:.2f}"])
        print(*(" | ".join(x) for x in geo_rows[-len(geo) - 1:]), sep="\n", flush=True)
        if best != f"R={proxy.REAL_BALL_RADIUS_MM[sensor]:g}":
            geo_warn.append(f"**{sensor}: the best radius here ({best} mm) is not "
                            f"`REAL_BALL_RADIUS_MM` ({proxy.REAL_BALL_RADIUS_MM[sensor]:g} mm), "
                            "which the calibration below used.**")
            print(geo_warn[-1], flush=True)
        r = calibrate(sensor)
        p = get_preset(sensor)
        for j, q in enumerate(qs):
            rows.append([sensor, f"{q:g} a", f"{r['raw'][j]:+.2f}",
                         f"{r['profile']['even'][j]:+.2f}", f"{r['profile']['odd'][j]:+.2f}",
                         f"{r['fit'][j]:+.2f}",
                         "-" if r["old_odd"] is None else f"{r['old_odd'][j]:+.3f}",
                         f"{r['preset_odd'][j]:+.3f}"])
            print(" | ".join(rows[-1]), flush=True)
        lo, med, hi = r["gain_range"]
        notes_fit.append(
            f"- {sensor}: reach `decay_mm` = {r['decay_mm']:g} mm ("
            + ("best of the grid" if r["identifiable"] else
               f"gel thickness: the best fit's peak is under {MIN_SHAPE_PX} px, no measurable "
               "shape") + f"; grid {DECAYS}), "
            f"gain {r['gain']:.3f} (fit rmse {r['rmse']:.3f} px over 1.5-6 a, even presses); "
            f"per-press gains 10/50/90 % {lo:.3f} / {med:.3f} / {hi:.3f} (draw range: "
            f"({lo:.2f}, {2 * r['gain'] - lo if r['gain'] > 0 else hi:.2f})); fitted zoom between "
            f"captures (median, even / odd) {r['zoom']['even'] * 1e3:+.2f}e-3 / "
            f"{r['zoom']['odd'] * 1e3:+.2f}e-3. Preset now: `press_dilation` = "
            f"{p.press_dilation}, `press_decay_mm` = {p.press_decay_mm}.")
        print(notes_fit[-1], flush=True)
        tdata[sensor] = truth_and_rules(sensor, r["sims"])
        f0, imgs, *_ = native(sensor)
        selfcal[sensor] = (calibrate_press_gain(f0, imgs[0::2]),
                           calibrate_press_gain(f0, imgs[1::2]))
        print(sensor, "self-calibrated (even, odd):", *selfcal[sensor], flush=True)
        if not args.no_check:
            got, truth, dz = check_estimator(sensor)
            check.append(f"- {sensor} (every 3rd press, capture px): recovered "
                         f"{np.array2string(got, precision=2, separator=', ')} vs truth "
                         f"{np.array2string(truth, precision=2, separator=', ')} at "
                         f"{', '.join(f'{q:g}' for q in qs)} a; zoom change {dz * 1e3:.2f}e-3 "
                         "(truth 1.00e-3).")
            print(check[-1], flush=True)
    fitted = rule_gains(tdata)
    print("fitted on even presses:", fitted, flush=True)
    for sensor, d in tdata.items():
        rule_rows += truth_rows(sensor, d, fitted, selfcal[sensor][0].gain)
        print(*(" | ".join(x) for x in rule_rows[-8:]), sep="\n", flush=True)
    gain_notes = []
    for sensor, (ev, od) in selfcal.items():
        gain_notes.append(
            f"- {sensor}: least-squares scale on the even presses: mechanics rule "
            f"{fitted['mechanics/' + sensor]:.3f}, outward rule {fitted['outward/' + sensor]:.3f} "
            f"(fraction of the pitch); `calibrate_press_gain` on the even / odd presses: "
            f"{ev.gain:.3f} +- {ev.stderr:.3f} / {od.gain:.3f} +- {od.stderr:.3f} "
            f"({ev.n_patches} / {od.n_patches} patches, explained {ev.explained:.2f} / "
            f"{od.explained:.2f}, median NCC peak {ev.peak:.2f}).")
    gain_notes.append(f"- pooled over both sensors (even presses, each in its working px): "
                      f"mechanics {fitted['mechanics/pooled']:.3f}, outward "
                      f"{fitted['outward/pooled']:.3f}.")
    notes = [
        f"{machine()}.", "",
        "Radial motion (px of the working size, + = outward) of the real gel around taxim's real "
        "presses, from block matching of the high-passed grain (48 px patches every 16 px, NCC "
        "peak >= 0.08, `motion.grainmatch`) between the real no-contact frame and each press, "
        "both at capture size (640 x 480). `raw`: mean over a ring of patches at r = q a "
        "(median over all presses; nothing removed: a zoom between captures stays in). "
        "`profile`: the shared radial profile of a joint robust fit with a per-press similarity "
        "(shift / zoom / roll about the image centre), zero from 8 a on "
        "(`grainmatch.press_profile`), on the even- and the odd-index presses separately. "
        "`calibrated law`: the simulator's press law fitted to the even presses "
        "(`sim.motion.contact_displacement`, ball presses at the recorded contacts); "
        "`simulator, odd presses`: the law at the old draw (dilation 0.15-0.4 mid, reach = gel "
        "thickness) and at the preset's calibrated mid gain and reach, at the held-out "
        "(odd) contacts. Measured on real frames; the grain is weak (NCC peaks ~0.2-0.3), "
        "so the per-press rings are noisy; the profile pools 24 (GelSight) / 12 (Mini) presses.",
        "", "Geometry: which ball made the presses (median colour change, grey levels, on rings "
        "about the recorded contact, every 3rd press at capture size; the simulator's shading of "
        "a ball of radius R pressed to the same contact radius, depth R - sqrt(R^2 - a^2); "
        "`rel. error`: rms of the relative difference to the real profile). "
        f"`proxy.REAL_BALL_RADIUS_MM` = {proxy.REAL_BALL_RADIUS_MM} "
        + ("(the best radius here for both sensors)" if not geo_warn else "(see the warning "
           "below the table)")
        + " is used by the calibration below and by the real frames + modelled field proxy "
        "(`make_contact_proxy`); GelSight's 2 mm is the smallest radius its largest recorded "
        "contact allows, and the real change exceeds the render at every ring. Before "
        "this, the radius was drawn U(max(2, 1.2 a), 6) mm as for the simulator's spheres, "
        "i.e. presses 0.3-0.5 mm deep where the imprints show 1.0-1.7 mm, and the GelSight's "
        "fitted gain was 14.554 (draw range 10.0-19.1): 3-4x the gel's motion per pressed "
        "volume.", "",
        table(["sensor", "profile", *(f"{q:g} a" for q in GEOMETRY_RINGS), "rel. error"],
              geo_rows), *geo_warn,
        "", "Calibration (even presses):", *notes_fit]
    if check:
        notes += ["", "Estimator check: the same real presses warped by a known outward bump "
                  "`2 exp(-((r/a - 3) / 1.2)^2)` px plus a 1e-3 zoom about the image centre; "
                  "change of the fitted profile:", *check]
    notes += ["", "The rules' press gains on real frames (single frame; the grain-matched motion "
              "at the sensor's marker grid, each press's fitted similarity removed, markers "
              ">= 2 a from the contact; least-squares scale of the rule at unit gain, clamped "
              ">= 0; shipped as `sim.presets.MECHANICS_GAINS` / `OUTWARD_GAINS`, the default "
              "`MECHANICS_GAIN` the pooled value) and the self-calibration "
              "(`motion.calibration.calibrate_press_gain`: no marker grid, no recorded contacts; "
              "its own joint fit of the gain and a per-frame similarity on a 16 px patch grid "
              "away from the imprint; stderr optimistic: patches overlap):", *gain_notes, "",
              "Single-frame methods scored on the held-out (odd) presses against this real "
              "measurement (cosine over truths >= 0.5 px; `fit (even)`: the least-squares "
              "scale fitted on the even presses that the shipped gain rounds; the per-marker "
              "truth is noisy, ~0.2-0.4 px; on the Mini it is noise only):", "",
              table(["sensor", "method (single frame)", "fit (even)", "e_rmse mean (px)", "cos",
                     "within 30 deg %", "presses / markers / moved"], rule_rows),
              "", "Ring table:"]
    cmd = "OMP_NUM_THREADS=1 python benches/studies/bench_press_calibration.py " + " ".join(sys.argv[1:])
    publish(SECTION, notes, ["sensor", "ring", "raw (all presses)", "profile, even",
                             "profile, odd (held out)", "calibrated law (even fit)",
                             "simulator old, odd presses", "simulator now (preset), odd presses"],
            rows, cmd.strip(), args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
