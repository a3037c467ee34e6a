"""``tacswitch demo``: everything the install can do, on a generated scene, in one report."""

from __future__ import annotations

import argparse
import time

import numpy as np

#: Frames per rendered grasp: the slip rule needs a few after the grasp start, and every frame
#: of both grasps is held in memory (about 1 MB each at 640x480), so the count is bounded.
MIN_FRAMES, MAX_FRAMES = 8, 2000


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="generate a grasp, track markers, detect slip, remove markers, predict motion",
        description="Renders synthetic contacts and grasps (no data or download needed), runs "
        "marker extraction, tracking and the slip rule, removes the markers (TELEA and the "
        "TacDiff diffusion model), predicts marker motion from markerless frames, and writes "
        "a PNG report.",
    )
    p.add_argument("-o", "--out", default="tacswitch-demo",
                   help="output folder (default: %(default)s)")
    p.add_argument("--preset", default="gelsight", help="sensor preset (default: %(default)s)")
    p.add_argument("--frames", type=int, default=40,
                   help=f"frames per grasp, {MIN_FRAMES}-{MAX_FRAMES} (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only the report path")
    p.set_defaults(run=run)


def _track(seq, detector_factory):
    """Tracks a sequence, feeding the slip detector from the established grasp on."""
    import tacswitch as ts

    tracker = ts.MarkerTracker(seq.reference)
    detector = detector_factory()
    states, motions, valids = [], [], []
    start = time.perf_counter()
    for t, frame in enumerate(seq.frames):
        motion, valid = tracker.update(frame)
        if t == seq.grasp_start:
            detector.reset()
        states.append(detector.update(motion, valid) if t >= seq.grasp_start else None)
        motions.append(motion)
        valids.append(valid)
    elapsed = time.perf_counter() - start
    return tracker, states, motions, valids, elapsed


def _row(panels: list[tuple[np.ndarray, str]], width: int, title: str = "") -> np.ndarray:
    """Panels side by side, ``width`` px in all, each captioned *after* scaling (captions stay
    readable however much a panel shrinks), under an optional ``title`` bar for the row."""
    import cv2

    from tacswitch import viz

    each = width // len(panels)
    out = []
    for img, caption in panels:
        small = cv2.resize(img, (each, round(img.shape[0] * each / img.shape[1])),
                           interpolation=cv2.INTER_AREA)
        # Caption lines pad at the bottom of the bar, so every caption starts at the top.
        bar = viz.label(np.zeros((0, each, 3), np.uint8), caption)
        out.append((bar, np.asarray(small)))
    tallest = max(bar.shape[0] for bar, _ in out)
    cols = [np.vstack([bar, np.full((tallest - bar.shape[0], each, 3), 40, np.uint8), img])
            for bar, img in out]
    row = np.hstack(cols)
    if row.shape[1] < width:  # integer division left a few columns
        row = np.hstack([row, np.full((row.shape[0], width - row.shape[1], 3), 40, np.uint8)])
    if title:
        head = viz.label(np.zeros((0, width, 3), np.uint8), title, scale=1.2 * viz.TEXT_SCALE)
        row = np.vstack([head, row])
    return row


def _marker_removal_panel(preset: str, seed: int, width: int) -> tuple[np.ndarray, list[str]]:
    """Markers removed from a physically simulated contact by TELEA and by TacDiff (hybrid:
    the diffusion model near the contact only), with the error against the true markerless
    image."""
    import tacswitch as ts
    from tacswitch import metrics
    from tacswitch.sim.scene import render_sample

    sample = render_sample(preset, seed)
    mask = ts.dilate_mask(sample.marker_mask)
    contact = mask & sample.contact_mask
    start = time.perf_counter()
    telea = ts.remove_markers(sample.image_markers)
    ms_telea = 1e3 * (time.perf_counter() - start)
    ts.remove_markers(sample.image_markers, method="hybrid", ref=sample.reference)  # warm-up
    start = time.perf_counter()
    hybrid = ts.remove_markers(sample.image_markers, method="hybrid", ref=sample.reference)
    ms_hybrid = 1e3 * (time.perf_counter() - start)
    lines = []
    for name, img, ms in (("TELEA", telea, ms_telea), ("TacDiff hybrid", hybrid, ms_hybrid)):
        mae = metrics.masked_mae(img, sample.image, mask)
        mae_c = metrics.masked_mae(img, sample.image, contact) if contact.any() else float("nan")
        lines.append(f"marker removal ({name}) on a simulated {sample.label} contact: {ms:.0f} ms, "
                     f"error under the markers {mae:.2f} grey levels, in contact {mae_c:.2f}")
    panels = [(sample.image_markers, "input (with markers)"),
              (telea, f"TELEA, {ms_telea:.0f} ms"),
              (hybrid, f"TacDiff hybrid, {ms_hybrid:.0f} ms"),
              _error_panel(hybrid, sample.image, "TacDiff")]
    title = f"Marker removal on a simulated contact ({sample.label})"
    return _row(panels, width, title), lines


def _error_panel(result: np.ndarray, truth: np.ndarray, name: str) -> tuple[np.ndarray, str]:
    """The removal error as a visible panel and its caption: errors of a few grey levels under
    the markers, amplified (the caption says how much) over the dimmed truth."""
    from tacswitch import viz

    panel, gain = viz.difference_panel(result, truth)
    return panel, f"|{name} - truth| x{gain:.0f} over the dimmed truth"


#: Markers moving at least this far (px) enter the demo's direction cosine (the GelSight Mini
#: preset's shear moves its gel ~1 px).
MOTION_COS_MIN_PX = 0.5


def _motion_panel(preset: str, seed: int, width: int) -> tuple[np.ndarray, list[str]]:
    """Marker motion predicted from markerless frames of a rendered grasp while its contact is
    stuck (the shear ramp, from the end of the press to the grasp start: the gel moves with
    the object, so its texture and imprint move as the markers do), against the true motion
    of the markers. The slip that follows is reported apart: there the object's imprint slides
    over the gel while the gel relaxes, and flow follows the imprint, not the gel."""
    import tacswitch as ts
    from tacswitch import viz
    from tacswitch.motion.evaluate import motion_metrics
    from tacswitch.sim.grasp import render_grasp

    seq = render_grasp(preset, "slip", n_frames=12, seed=seed)
    rest = seq.scene.rest
    pressed = next(t for t, p in enumerate(seq.phase) if p != "press") - 1
    a, b = seq.frames[pressed], seq.frames[seq.grasp_start - 1]
    centres = rest + a.displacement
    truth = b.displacement - a.displacement
    t0 = time.perf_counter()
    pred = ts.predict_motion(b.image, ref=a.image, centres=centres)
    ms = 1e3 * (time.perf_counter() - t0)
    m = motion_metrics(pred, truth, min_px=MOTION_COS_MIN_PX)
    zero = float(np.hypot(*truth.T).mean())
    last = seq.frames[-1]
    slip_truth = last.displacement - b.displacement
    slip = motion_metrics(ts.predict_motion(last.image, ref=b.image, centres=rest + b.displacement),
                          slip_truth, min_px=MOTION_COS_MIN_PX)
    scale = max(3.0, round(10.0 / max(float(np.hypot(*truth.T).max()), 1e-6)))
    ones = np.ones(len(rest), bool)
    panels = [(viz.draw_motion(b.image, centres, truth, ones, scale=scale),
               f"true motion (arrows x{scale:g})"),
              (viz.draw_motion(b.image, centres, pred, ones, scale=scale),
               f"optical flow between the markerless frames, {ms:.0f} ms: cosine "
               f"{m['cos_mean']:.2f}, error {m['e_rmse_mean']:.2f} px (zero motion {zero:.2f})")]
    title = ("Marker motion from markerless frames while the contact is stuck (the shear, from "
             "the end of the press to the grasp start)")
    lines = [f"motion from markerless frames (optical flow; stuck shear of a simulated grasp, "
             f"end of the press -> grasp start): {ms:.1f} ms, direction cosine "
             f"{m['cos_mean']:.2f}, error mean {m['e_rmse_mean']:.2f} px against "
             f"{zero:.2f} px for zero motion (largest true motion "
             f"{np.hypot(*truth.T).max():.1f} px)",
             f"  (during the slip that follows, the object's imprint slides over the gel while "
             f"the gel relaxes: flow follows the imprint, cosine {slip['cos_mean']:.2f}, error "
             f"{slip['e_rmse_mean']:.2f} px against {np.hypot(*slip_truth.T).mean():.2f} px "
             "for zero motion)"]
    return _row(panels, width, title), lines


def run(args: argparse.Namespace) -> int:
    import tacswitch as ts
    from tacswitch import sim, viz
    from tacswitch._io import write_image
    from tacswitch.cli.options import UsageError, output_dir, preset_option

    if not MIN_FRAMES <= args.frames <= MAX_FRAMES:
        raise UsageError(f"--frames: must be in [{MIN_FRAMES}, {MAX_FRAMES}]; got {args.frames}")
    if args.seed < 0:
        raise UsageError(f"--seed: must be >= 0; got {args.seed}")
    preset = sim.get_preset(preset_option(args.preset))
    say = (lambda *a: None) if args.quiet else print
    # Checked before rendering: a bad folder fails at once, not after the whole demo.
    out = output_dir(args.out, "-o/--out")

    def factory() -> ts.SlipDetector:
        return ts.SlipDetector(image_width=preset.width)

    results = {}
    for kind in ("slip", "hold"):
        seq = sim.grasp_sequence(preset, kind, n_frames=args.frames, seed=args.seed)
        results[kind] = (seq, *_track(seq, factory))

    seq, tracker, states, motions, valids, elapsed = results["slip"]
    _, ok, idx = ts.match_markers(seq.rest, tracker.reference, return_index=True)
    order = np.argsort(idx[ok])
    truth = seq.motions[-1][ok][order]
    err = np.hypot(*(motions[-1][idx[ok]][order] - truth).T)
    fps = len(seq.frames) / elapsed
    onset = seq.slip.index(True)
    first = next((t for t, s in enumerate(states) if s is not None and s.slip), None)
    hold_first = next((t for t, s in enumerate(results["hold"][2]) if s is not None and s.slip),
                      None)

    top = _row([
        (viz.draw_markers(seq.reference, tracker.reference),
         f"no-contact reference: {len(tracker.reference)} markers found"),
        (viz.draw_motion(seq.frames[-1], tracker.reference, motions[-1], valids[-1], scale=1.0),
         "last frame of the slip grasp: tracked motion"),
    ], 2 * seq.reference.shape[1], f"Marker tracking on a simulated {preset.name} grasp")
    disp = {k: [np.nan if s is None else s.max_displacement for s in results[k][2]]
            for k in ("slip", "hold")}
    events = [(first, f"slip detected: frame {first}", 0)] if first is not None else []
    if hold_first is not None:
        events.append((hold_first, f"hold: false alarm at frame {hold_first}", 1))
    threshold = factory().threshold_px
    plot = viz.line_plot(
        {"slip grasp": np.array(disp["slip"]), "hold grasp": np.array(disp["hold"])},
        size=(380, top.shape[1]), hline=threshold,
        hline_label=f"slip threshold {threshold:.2f} px", marks=np.array(seq.slip),
        marks_label="true slip (slip grasp)",
        spans=[(0, seq.grasp_start - 1, "loading: the press, then the shear ramp. The rule "
                "is not run before the grasp start (the established contact), where "
                "displacements are measured from")],
        events=events, xlabel="frame", ylabel="largest marker displacement since the grasp "
        "start, px", title="Slip rule on two simulated grasps: one slips, one holds",
    )
    removal, removal_lines = _marker_removal_panel(preset.name, args.seed, top.shape[1])
    motion_row, motion_lines = _motion_panel(preset.name, args.seed, top.shape[1])
    report = np.vstack([top, plot, removal, motion_row])
    path = write_image(out / "report.png", report)

    say(f"preset {preset.name}: {preset.width}x{preset.height}, {len(seq.rest)} markers")
    say(f"markers tracked: {int(valids[-1].sum())}/{len(tracker.reference)}, "
        f"error vs ground truth: median {np.median(err):.3f} px, max {err.max():.3f} px "
        f"(largest motion {np.hypot(*truth.T).max():.1f} px)")
    say(f"slip grasp: slip detected at frame {first} (true onset {onset}); "
        f"hold grasp: {'no slip' if hold_first is None else f'false alarm at {hold_first}'}")
    say(f"slip loop (extract + track + rule, Python API): {fps:.0f} frames/s")
    for line in removal_lines:
        say(line)
    for line in motion_lines:
        say(line)
    print(path)
    return 0
