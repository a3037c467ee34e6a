"""``tacswitch slip``: the live slip loop on a video, an image folder or a camera."""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from pathlib import Path

import numpy as np

from tacswitch.cli.sources import frame_count, frames


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "slip",
        help="run the slip loop on a video, an image folder or a camera",
        description="Tracks markers frame by frame (the first frame is the no-contact "
        "reference and the start of the grasp) and applies the slip rule. A CSV log is "
        "written and flushed every frame, so an interruption never loses it.",
    )
    p.add_argument("source", help="video file, folder of images, or camera index (0, 1, ...)")
    p.add_argument("--log", default="slip-log.csv", help="CSV log (default: %(default)s)")
    p.add_argument("--threshold-px", type=float, default=None,
                   help="displacement threshold (default: 3.25 px scaled to the frame width)")
    p.add_argument("--rigid-threshold-px", type=_px_or_auto, default=None, metavar="PX|auto",
                   help="also flag deviation from a rigid contact motion above this (pixels, or "
                   "'auto': half the displacement threshold)")
    p.add_argument("--rigid-only", action="store_true",
                   help="use only the rigid criterion (ignores rigid vibration; needs "
                   "--rigid-threshold-px)")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    p.add_argument("--show", action="store_true", help="show an overlay window (needs a display)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(run=run)


def _px_or_auto(text: str) -> float | str:
    if text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected pixels or 'auto', got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    import tacswitch as ts
    from tacswitch.cli.progress import progress

    show = args.show and (sys.platform == "win32" or bool(os.environ.get("DISPLAY")))
    detector: ts.SlipDetector | None = None
    n = skipped = slips = 0
    t0 = time.perf_counter()
    log_path = Path(args.log)
    log_path.parent.mkdir(parents=True, exist_ok=True)
    status = 0
    total = frame_count(args.source, args.max_frames)
    # The window shows the state; the bar (frames/s) is for runs without it.
    with open(log_path, "w", newline="") as fh, \
            progress(total=total, desc="slip", unit="frame", quiet=args.quiet or show) as bar:
        writer = csv.writer(fh)
        writer.writerow(["frame", "slip", "criterion", "max_displacement_px", "marker",
                         "rigid_residual_px", "valid_markers", "time_s"])
        try:
            for frame in frames(args.source):
                if args.max_frames is not None and n >= args.max_frames:
                    break
                bar.update()
                if frame is None or frame.ndim != 3:
                    skipped += 1
                    continue
                if detector is None:
                    detector = ts.SlipDetector(args.threshold_px,
                                               rigid_threshold_px=args.rigid_threshold_px,
                                               use_displacement=not args.rigid_only)
                    shape = frame.shape
                elif frame.shape != shape:
                    skipped += 1
                    continue
                state = detector.update(frame)
                if state.slip and not slips:
                    bar.set_postfix_str(f"slip at frame {n}", refresh=False)
                slips += state.slip
                writer.writerow([n, int(state.slip), state.criterion or "",
                                 f"{state.max_displacement:.3f}", state.marker,
                                 f"{state.rigid_residual:.3f}", state.n_compared,
                                 f"{time.perf_counter() - t0:.4f}"])
                fh.flush()
                n += 1
                if show:
                    _show(frame, detector, state)
        except ConnectionError as exc:
            print(f"tacswitch slip: {exc}; log kept at {log_path}", file=sys.stderr)
            status = 1
    elapsed = time.perf_counter() - t0
    if n == 0:
        raise ValueError(f"source: no readable frames in {args.source!r}")
    if not args.quiet:
        print(f"{n} frames ({skipped} skipped), {slips} with slip, {n / elapsed:.0f} frames/s; "
              f"log: {log_path}")
    return status


def _show(frame: np.ndarray, detector, state) -> None:
    import cv2

    from tacswitch import viz

    tracker = detector.tracker
    motion = tracker.positions - tracker.reference
    vis = viz.draw_motion(frame, tracker.reference, motion, scale=2.0)
    text = f"SLIP ({state.criterion})" if state.slip else f"max {state.max_displacement:.1f} px"
    cv2.putText(vis, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7,
                (0, 0, 255) if state.slip else (0, 200, 0), 2, cv2.LINE_AA)
    cv2.imshow("tacswitch slip", vis)
    cv2.waitKey(1)
