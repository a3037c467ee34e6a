"""``tacswitch slip``: the live slip loop on a video, an image folder or a camera."""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tacswitch.cli.rest_frame import choose_rest_frame
from tacswitch.cli.sources import SkipCount, check_source, frame_count, frames


def add_parser(sub: argparse._SubParsersAction) -> None:
    from tacswitch.cli.options import positive, px_or_auto

    p = sub.add_parser(
        "slip",
        help="run the slip loop on a video, an image folder or a camera",
        description="Tracks markers frame by frame (the first frame after the camera settled "
        "is the no-contact reference of the markers' rest positions) and follows each grasp "
        "from the marker motion (contact onset: the markers leave their rest positions; "
        "established: they stop moving; release: they return). The learned rule (default) "
        "scores every frame from the onset to the release; --rule paper applies the paper's "
        "displacement rule from the established contact, or from --start FRAME. Frames "
        "outside a contact are never flagged. The start is printed and logged. A CSV log (frame, "
        "phase, grasp, grasp_start, slip, ...) is written and flushed every frame, so an "
        "interruption never loses it.",
        epilog="A recording that starts in contact has no onset to detect: pass --start 0 "
        "(or the frame where the grasp is established). The reference skips the frames "
        "before the camera settled (exposure still changing, or stale frames ended by a jump "
        "of the whole image) and, with markers, a first frame that shows no markers or fewer "
        "than half as many as a frame of the first 30 (said on stderr); the frames before it "
        "have no log rows, and frame numbers stay the source's.",
    )
    p.add_argument("source", help="video file, folder of images, camera index (0, 1, ...), or "
                                  "ROS bag (with --topic)")
    p.add_argument("--log", default="slip-log.csv",
                   help="CSV log, a .csv file name (default: %(default)s)")
    p.add_argument("--rule", choices=RULES, default=None,
                   help="'learned' (default): a classifier of how the marker field moves over "
                        "time, trained on real lifted and shaken grasps, run from the contact "
                        "onset to the release; 'paper': the paper's displacement rule from the "
                        "grasp start (implied by --threshold-px, --rigid-threshold-px, "
                        "--rigid-only, --smooth-frames, --method and --all-markers)")
    p.add_argument("--slip-model", default=None, metavar="ONNX",
                   help="scorer for --rule learned (default: the shipped one, for markers or "
                        "with --markerless for predicted motion; make your own with "
                        "`tacswitch train slip`)")
    p.add_argument("--score-threshold", type=float, default=None, metavar="LOGIT",
                   help="--rule learned: a committee member fires on a frame whose score "
                        "exceeds this (default: the model's, 0); higher: fewer false alarms, "
                        "later and fewer detections")
    p.add_argument("--votes", type=int, default=None, metavar="K",
                   help="--rule learned: flag a grasp once K members of the scorer's committee "
                        f"have fired in it (default: the model's, {_shipped_votes()}; the "
                        "marker model's second vote, 5/8 of its members trained with rendered "
                        "grasps, stays); fewer: "
                        "earlier and "
                        "more detections, more false alarms")
    p.add_argument("--threshold-px", type=positive, default=None,
                   help="--rule paper: displacement threshold (default: 3.25 px scaled to the "
                        "frame width)")
    p.add_argument("--rigid-threshold-px", type=px_or_auto, default=None, metavar="PX|auto",
                   help="also flag deviation from a rigid contact motion above this (pixels, or "
                   "'auto': half the displacement threshold)")
    p.add_argument("--rigid-only", action="store_true",
                   help="use only the rigid criterion (ignores rigid vibration; needs "
                   "--rigid-threshold-px)")
    p.add_argument("--start", type=int, default=None, metavar="FRAME",
                   help="the grasp starts at this frame (0-based; default: detected from the "
                        "contact onset)")
    p.add_argument("--fps", type=float, default=None, metavar="HZ",
                   help="--rule learned: the source's frame rate, frames/s (default: what a "
                        "video file states, or a bag's header stamps; a camera or folder is "
                        "taken to be at the scorer's rate, 25). A source faster than 31.25 "
                        "frames/s is resampled to 25, where the scorer's cues (velocities, "
                        "frame windows) were learned; a slower one is read frame by frame. "
                        "The log keeps one row per source frame")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    p.add_argument("--smooth-frames", type=int, default=None, metavar="N",
                   help="the slip rule sees the mean motion of the last N frames of the grasp "
                        "(default: 1 with markers, the paper's rule; 2 with --markerless, whose "
                        "predicted motion carries camera noise that changes every frame)")
    m = p.add_argument_group("markerless sensor (motion predicted instead of tracked)")
    m.add_argument("--markerless", action="store_true",
                   help="the frames have no markers: predict each frame's marker motion from "
                        "the reference frame (the learned rule: tacswitch.MarkerlessTracker and "
                        "the shipped markerless scorer; --rule paper: tacswitch.predict_motion)")
    m.add_argument("--ref", default=None, metavar="IMG",
                   help="markerless no-contact reference frame; every frame is measured "
                        "from it (default: the first frame after the camera settled)")
    m.add_argument("--centres", default=None, metavar="CSV",
                   help="marker rest centres, a CSV with x,y columns (e.g. `tacswitch markers` "
                        "on a frame with markers); default: the motion model's grid scaled to "
                        "the frame")
    m.add_argument("--method", choices=("flow", "model", "outward"), default=None,
                   help="--rule paper: how motion is predicted (default: flow, dense optical "
                        "flow from the reference; the learned rule reads MarkerlessTracker's "
                        "motion)")
    m.add_argument("--model", default=None, help="ONNX motion model for --method model")
    from tacswitch.cli.options import add_device_option

    add_device_option(m, "--method model's network (the slip scorer always runs on the CPU)")
    m.add_argument("--all-markers", action="store_true",
                   help="judge slip on every marker (default: only the markers near the "
                        "grasp-start frame's contact, where the gel moves most; far from it a "
                        "compressed video's drifting texture reads as motion)")
    p.add_argument("--show", action="store_true",
                   help="show an overlay window (needs a display and an OpenCV build with a "
                        "GUI: opencv-contrib-python instead of the -headless package)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    from tacswitch.cli.bagio import add_bag_options

    add_bag_options(p, "<topic>/slip (diagnostic_msgs/DiagnosticArray: level 1 while "
                       "slipping) and <topic>/marker_motion (sensor_msgs/PointCloud2)")
    p.set_defaults(run=run)


RULES = ("learned", "paper")
#: Options of the paper rule only: giving one selects it when --rule is not given.
PAPER_OPTIONS = ("threshold_px", "rigid_threshold_px", "smooth_frames", "method")


def _window_problem() -> str | None:
    """Why ``--show`` cannot open a window here (None: it can): the headless OpenCV build
    tacswitch depends on has no GUI (``cv2.imshow`` raises "not implemented"), and on Linux a
    window needs a display."""
    import re

    import cv2

    gui = re.search(r"^\s*GUI:\s*(\S+)", cv2.getBuildInformation(), re.MULTILINE)
    if gui is not None and gui.group(1).upper() == "NONE":
        return ("this OpenCV build has no GUI (opencv-contrib-python-headless); for a window "
                "pip install opencv-contrib-python in place of the -headless package, or drop "
                "--show")
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        return "no display to open a window on ($DISPLAY is not set); drop --show"
    return None


LOG_COLUMNS = ["frame", "phase", "grasp", "grasp_start", "slip", "criterion",
               "max_displacement_px", "marker", "rigid_residual_px", "score", "votes",
               "valid_markers",
               "time_s"]


def _check(args: argparse.Namespace) -> None:
    """Option values that cannot work: one line naming the flag."""
    from tacswitch.cli.options import UsageError

    if args.max_frames is not None and args.max_frames < 1:
        raise UsageError(f"--max-frames: must be >= 1; got {args.max_frames}")
    if args.start is not None and args.start < 0:
        raise UsageError(f"--start: must be >= 0; got {args.start}")
    if args.start is not None and args.max_frames is not None and args.start >= args.max_frames:
        raise UsageError(f"--start: frame {args.start} is past --max-frames {args.max_frames}")
    if args.smooth_frames is not None and not 1 <= args.smooth_frames <= 1000:
        raise UsageError(f"--smooth-frames: must be in [1, 1000]; got {args.smooth_frames}")
    if args.fps is not None:
        from tacswitch.grasp.timebase import check_fps

        try:
            check_fps(args.fps, "--fps")
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    if args.markerless:
        from tacswitch.cli.options import device_option

        device_option(args.device)
    if not args.markerless:
        for flag, value in (("--device", None if args.device == "auto" else args.device),
                            ("--ref", args.ref), ("--centres", args.centres),
                            ("--model", args.model), ("--all-markers", args.all_markers or None)):
            if value is not None:
                raise UsageError(f"{flag}: applies to --markerless only")
    paper_given = [o for o in PAPER_OPTIONS if getattr(args, o) is not None] + (
        ["rigid_only"] if args.rigid_only else []) + (["all_markers"] if args.all_markers else [])
    if args.rule is None:
        args.rule = "paper" if paper_given else "learned"
    if args.rule == "learned" and paper_given:
        raise UsageError(f"--{paper_given[0].replace('_', '-')}: applies to --rule paper only")
    if args.rule == "paper":
        for flag, value in (("--slip-model", args.slip_model),
                            ("--score-threshold", args.score_threshold),
                            ("--votes", args.votes), ("--fps", args.fps)):
            if value is not None:
                raise UsageError(f"{flag}: applies to --rule learned only")
    if args.score_threshold is not None and not np.isfinite(args.score_threshold):
        raise UsageError(f"--score-threshold: must be finite; got {args.score_threshold}")
    if args.rigid_only and args.rigid_threshold_px is None:
        raise UsageError("--rigid-only: needs --rigid-threshold-px (pixels or 'auto'), or "
                         "nothing is checked")
    if args.show:
        problem = _window_problem()
        if problem is not None:
            raise UsageError(f"--show: {problem}")


def run(args: argparse.Namespace) -> int:
    import tacswitch as ts
    from tacswitch.cli.options import StreamingCsv, csv_output, input_file
    from tacswitch.cli.progress import progress, warn

    _check(args)
    from tacswitch.cli.bagio import bag_sink, bag_source, motion_fields

    bag = bag_source(args.source, args)
    if args.markerless and bag is None:
        _warn_inter_frame_codec(args.source)
    rule: _PaperLoop | _LearnedLoop = (_LearnedLoop(args, _source_fps(args, bag), bag)
                                       if args.rule == "learned" else _PaperLoop(args))
    show = args.show  # _check refused it where no window can open
    n = slips = 0
    skipped = SkipCount()
    starts: list[int] = []
    t0 = time.perf_counter()
    log_path = csv_output(args.log, "--log")
    if bag is None:  # before the log is opened: a run that cannot start leaves no log
        check_source(args.source)
    if args.ref:  # a --ref that is not there: said before any warning about the run
        input_file(args.ref, "--ref")
    if args.markerless and args.rule == "learned" and not args.centres:
        warn("slip", "--centres not given: motion is predicted on the motion model's grid; the "
             "markerless scorer learned from a sensor's own marker centres, so pass --centres "
             "from a frame with markers (`tacswitch markers VIDEO --frame N -o DIR`) where you "
             "have one")
    status = 0
    total = (frame_count(args.source, args.max_frames) if bag is None else
             min(len(bag), args.max_frames or len(bag)) or None)
    k = -1  # index in the stream (bag frames are looked up by it)
    # The window shows the state; the bar (frames/s) is for runs without it.
    # The log is opened at its first row: a source that cannot be read leaves an existing
    # log alone (one that fails later keeps the rows so far).
    with StreamingCsv(log_path, LOG_COLUMNS) as log, bag_sink(bag, args) as sink, \
            progress(total=total, desc="slip", unit="frame", quiet=args.quiet or show) as bar:
        try:
            stream = frames(args.source) if bag is None else iter(bag)
            # Predicted motion needs no markers on the rest frame, only a settled camera.
            rest, stream = choose_rest_frame(
                stream, None if args.markerless else lambda f: ts.extract_markers(f).centres,
                source=args.source, max_frames=args.max_frames)
            if args.markerless and args.ref:
                # The user chose the reference: every frame is measured from it (as `motion
                # --sequence --ref`). The look-ahead still ran: a bag's rate is read from the
                # stamps of the frames it read.
                rest = None
            if rest is not None and rest.index > 0:
                warn("slip", rest.message())
            for frame in stream:
                if args.max_frames is not None and n >= args.max_frames:
                    break
                k += 1
                bar.update()
                if frame is None or frame.ndim != 3:
                    skipped.undecodable()
                    continue
                skipped.decoded()
                if rule.tracker is None:
                    if rest is not None and n < rest.index:  # before the rest frame: no row
                        n += 1
                        continue
                    rule.begin(frame, n)
                elif frame.shape[:2] != rule.tracker.reference_shape:
                    skipped.unusable()
                    continue
                row, slip, started, state = rule.step(frame, n, time.perf_counter() - t0)
                if started:
                    starts.append(n)
                    bar.set_postfix_str(f"grasp start at frame {n}", refresh=False)
                if slip and not slips:
                    bar.set_postfix_str(f"slip at frame {n}", refresh=False)
                slips += slip
                log.writerow(row)
                if sink is not None:
                    at = bag.frames[k]
                    sink.slip(at, bool(slip), str(row[1]),
                              float(row[9]) if row[9] != "" else float("nan"))
                    tr = rule.tracker
                    sink.points(at, motion_fields(tr.reference, tr.positions - tr.reference))
                n += 1
                if show:
                    _show(frame, rule.tracker, state)
        except ConnectionError as exc:
            kept = f"log kept at {log_path}" if log.opened else "no frame logged"
            print(f"tacswitch slip: {exc}; {kept}", file=sys.stderr)
            status = 1
    elapsed = time.perf_counter() - t0
    if n == 0:
        raise ValueError(f"source: no readable frames in {args.source!r}")
    if not args.quiet:
        found = _starts_text(starts, args, rule.segmenter, rule.offset)
        print(f"{n} frames ({skipped}), {found}, "
              f"{slips} with slip{rule.label}, {n / elapsed:.0f} frames/s; log: {log_path}")
    return status


def _source_fps(args: argparse.Namespace, bag: Any) -> float | None:
    """The source's frame rate: ``--fps``, else what a video file states, else None (the
    scorer's rate is assumed; a bag's is read from its stamps once the rest frame is
    chosen: :meth:`_LearnedLoop.begin`)."""
    from tacswitch.cli.sources import VIDEO_SUFFIXES, stated_fps

    if args.fps is not None:
        return float(args.fps)
    path = Path(args.source)
    if bag is None and path.suffix.lower() in VIDEO_SUFFIXES and path.is_file():
        try:
            return stated_fps(path)
        except ValueError:
            return None  # the decode error comes where the frames are read
    return None


def checked_scorer(model: str, markerless: bool, *, command: str = "slip",
                   flag: str = "--slip-model") -> Any:
    """The slip scorer ``model`` (a path or a shipped name), loaded before any frame is read:
    a file that cannot be used is an error naming ``flag``, and one line on stderr says when it
    learned from the other kind of motion than this run feeds it (a marker scorer reads
    predicted motion as nearly still: 3 of 65 real slips caught, BENCHMARKS.md)."""
    from tacswitch.cli.progress import warn
    from tacswitch.grasp.detector import load_scorer

    try:
        scorer = load_scorer(model)
    except (ValueError, FileNotFoundError) as exc:
        raise ValueError(str(exc).replace("model:", f"{flag}:", 1)) from None
    fed = "markerless" if markerless else "markers"
    learned_from = scorer.motion
    if learned_from is None or learned_from == fed:
        return scorer
    other = ("tracked markers" if learned_from == "markers"
             else "motion predicted on a markerless sensor")
    hint = "with --markerless" if markerless else "without --markerless"
    warn(command, f"{flag}: learned from {other}, and this run "
         f"{'predicts motion (--markerless)' if markerless else 'tracks markers'}; its "
         f"decisions are not measured on such motion (train one {hint}: `tacswitch train "
         "slip`)")
    return scorer


def _first_tracker(frame: np.ndarray, args: argparse.Namespace,
                   markerless: Callable[[np.ndarray, argparse.Namespace], Any]) -> Any:
    """The marker tracker (or its markerless stand-in, ``markerless(frame, args)``) from the
    rest frame (one with markers: :func:`tacswitch.cli.rest_frame.choose_rest_frame`)."""
    import tacswitch as ts

    return markerless(frame, args) if args.markerless else ts.MarkerTracker(frame)


def _shipped_votes() -> str:
    """The recipe's votes for the help text: ``"13 of 32"`` (and the markerless recipe's when
    it differs)."""
    from tacswitch.grasp.train import COMMITTEE, MARKERLESS_COMMITTEE, default_votes

    text = f"{default_votes(COMMITTEE)} of {COMMITTEE}"
    if MARKERLESS_COMMITTEE != COMMITTEE:
        text += (f", with --markerless {default_votes(MARKERLESS_COMMITTEE)} of "
                 f"{MARKERLESS_COMMITTEE}")
    return text


def _start_after(args: argparse.Namespace, offset: int) -> int | None:
    """``--start`` counted from the rest frame ``offset`` (the rules count frames from it); a
    start before the rest frame is the rest frame."""
    return None if args.start is None else max(args.start - offset, 0)


class _PaperLoop:
    """The paper's rule from each detected grasp start (``--rule paper``)."""

    label = ""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.tracker: Any = None
        self.detector: Any = None
        self.segmenter: Any = None
        self.offset = 0  # the rest frame: the segmenter counts frames from it

    def begin(self, frame: np.ndarray, offset: int) -> None:
        """Starts on the rest frame, frame ``offset`` of the source."""
        import tacswitch as ts
        from tacswitch.grasp.phases import GraspSegmenter

        args = self.args
        self.offset = offset
        self.tracker = _first_tracker(frame, args, MarkerlessMotion)
        self.detector = ts.SlipDetector(args.threshold_px,
                                        rigid_threshold_px=args.rigid_threshold_px,
                                        use_displacement=not args.rigid_only,
                                        points=self.tracker.reference,
                                        image_width=frame.shape[1],
                                        smooth_frames=_smooth_frames(args))
        self.segmenter = GraspSegmenter(_epsilon(args, frame.shape[1]),
                                        start=_start_after(args, offset),
                                        first_frame_rest=args.ref is None)

    def step(self, frame: np.ndarray, n: int, t: float) -> tuple[list, bool, bool, Any]:
        from tacswitch.grasp.phases import GRASP

        motion, valid = self.tracker.update(frame)
        step = self.segmenter.update(motion, valid)
        state = None
        if step.starts:
            self.detector.reset()
        if step.phase == GRASP:
            if isinstance(self.tracker, MarkerlessMotion):
                # Slip is measured from the grasp start: predict from that frame.
                motion, valid = self.tracker.since_grasp(frame, restart=step.starts)
            state = self.detector.update(motion, valid)
        slip = bool(state is not None and state.slip)
        return (_row(n, step, state, int(valid.sum()), t, self.offset), slip, step.starts,
                state)


class _LearnedLoop:
    """The learned rule (default): every frame's field since the first frame goes to
    :class:`tacswitch.GraspSlipDetector`, which follows the grasp phases itself."""

    def __init__(self, args: argparse.Namespace, fps: float | None = None,
                 bag: Any = None) -> None:
        from tacswitch.cli.options import input_file

        self.args = args
        self.fps = fps
        self.bag = bag
        self.label = " (learned rule)"
        self.model = (str(input_file(args.slip_model, "--slip-model")) if args.slip_model
                      else "markerless" if args.markerless else "markers")
        if args.votes is not None or args.slip_model:
            # Checked now, against the scorer: a usage error or a warning before any frame.
            from tacswitch.cli.options import UsageError
            from tacswitch.grasp.detector import check_votes

            scorer = checked_scorer(self.model, args.markerless)
            if args.votes is not None:
                try:
                    check_votes(args.votes, scorer.committee)
                except ValueError as exc:
                    raise UsageError(f"--{exc}") from None
        self.tracker: Any = None
        self.detector: Any = None
        self.offset = 0  # the rest frame: the detector counts frames from it

    @property
    def segmenter(self) -> Any:
        return None if self.detector is None else self.detector.segmenter

    def _markerless_sequence(self, frame: np.ndarray, args: argparse.Namespace
                             ) -> MarkerlessSequence:
        """The markerless motion of the kind the scorer learned from (its file says)."""
        from tacswitch.grasp.detector import scorer_frame_to_frame

        return MarkerlessSequence(frame, args, frame_to_frame=scorer_frame_to_frame(self.model))

    def begin(self, frame: np.ndarray, offset: int) -> None:
        """Starts on the rest frame, frame ``offset`` of the source."""
        from tacswitch.grasp.detector import GraspSlipDetector

        self.offset = offset
        self.tracker = _first_tracker(frame, self.args, self._markerless_sequence)
        if self.fps is None and self.bag is not None:
            from tacswitch.grasp.timebase import fps_from_stamps

            # The header stamps of the frames read so far (up to the rest frame's look-ahead).
            self.fps = fps_from_stamps([f.stamp_ns for f in self.bag.frames])
        try:
            self.detector = GraspSlipDetector(
                self.tracker.reference, image_width=frame.shape[1], model=self.model,
                threshold=self.args.score_threshold, votes=self.args.votes,
                start=_start_after(self.args, offset), fps=self.fps,
                # Tracked from this frame unless --ref gave the no-contact frame.
                first_frame_rest=self.args.ref is None)
        except (ValueError, FileNotFoundError) as exc:
            raise ValueError(str(exc).replace("model:", "--slip-model:", 1)) from None
        tb = self.detector.timebase
        if tb is not None:
            self.label = (f" (learned rule; {self.fps:g} frames/s resampled to the scorer's "
                          f"{self.detector.model_fps:g})")

    def step(self, frame: np.ndarray, n: int, t: float) -> tuple[list, bool, bool, Any]:
        st = self.detector.update(*self.tracker.update(frame))
        return (_learned_row(n, st, t, self.offset), st.slip, st.grasp_start == st.frame,
                st)


def _learned_row(n: int, st, t: float, offset: int) -> list:  # type: ignore[no-untyped-def]
    """One log row of the learned rule (its score; the paper rule's columns stay empty);
    ``offset``: the rest frame, where the detector's frame numbers start."""
    score = "" if st.score != st.score else f"{st.score:.3f}"  # NaN: the scorer did not run
    return [n, st.phase, st.grasp or "",
            "" if st.grasp_start is None else st.grasp_start + offset,
            int(st.slip), st.criterion or "", "", "", "", score, st.votes if score else "",
            st.n_valid, f"{t:.4f}"]


class MarkerlessSequence:
    """Stands in for the marker tracker on a markerless sensor for the learned rule: every
    frame's marker motion since the first frame from :class:`tacswitch.MarkerlessTracker`
    (``--ref``: the no-contact frame, default none: the first frame is the anchor) at
    ``--centres`` or the motion model's grid; no marker is ever lost. ``frame_to_frame``: the
    tracker's frame-to-frame weight, the one the scorer's motion was tracked with."""

    def __init__(self, first: np.ndarray, args: argparse.Namespace, *,
                 frame_to_frame: float = 0.0) -> None:
        import tacswitch as ts
        from tacswitch._io import read_image
        from tacswitch.cli.motion import _read_centres
        from tacswitch.cli.options import input_file, load_model_option
        from tacswitch.grasp.detector import SCORER_FLOW_PRESET
        from tacswitch.motion.infer import load_model

        ref = (read_image(input_file(args.ref, "--ref"), "--ref", quiet=True) if args.ref
               else None)
        if ref is not None and ref.shape != first.shape:
            raise ValueError(f"--ref: shape {ref.shape} does not match the frames "
                             f"{first.shape}")
        self.reference_shape = first.shape[:2]
        self.reference = (_read_centres(str(input_file(args.centres, "--centres")))
                          if args.centres else
                          load_model_option(load_model, args.model).centres_for(
                              *first.shape[:2]))
        self.positions = self.reference.copy()
        # The plain flow from rest, of the preset the markerless scorer was trained on
        # (MarkerlessTracker's doc).
        self._tracker = ts.MarkerlessTracker(ref, self.reference, suppress_imprint=False,
                                             preset=SCORER_FLOW_PRESET, anchor="rest",
                                             frame_to_frame=frame_to_frame)

    def __len__(self) -> int:
        return len(self.reference)

    def update(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        motion = np.asarray(self._tracker.update(frame), np.float32)
        self.positions = self.reference + motion
        return motion, np.ones(len(motion), bool)


class MarkerlessMotion:
    """Stands in for the marker tracker on a markerless sensor: each frame's marker motion from
    the reference frame by :func:`tacswitch.predict_motion` (``--method``), at fixed rest centres
    (``--centres`` or the model's grid); no marker is ever lost. The contact onset is found from
    the motion since the no-contact reference; during a grasp the slip rule gets the motion since
    the grasp-start frame (:meth:`since_grasp`): against the no-contact frame the imprint
    appears, which optical flow cannot follow (on simulated grasps its error is 2-3 px there,
    0.4 px from the grasp start). Unless ``--all-markers``, only the markers near the
    grasp-start frame's contact are valid during a grasp
    (:func:`tacswitch.motion.reference.near_contact` against the reference): the gel moves
    most near the contact, while the texture of a compressed video drifts all over the gel
    (real-texture H.264 grasp videos of a GelSight Mini, CRF 23: 8 of 18 grasps right over all
    markers, 16 near the contact; ``benches/studies/bench_slip_real_texture.py``)."""

    def __init__(self, first: np.ndarray, args: argparse.Namespace) -> None:
        from tacswitch._io import read_image
        from tacswitch.cli.motion import _read_centres
        from tacswitch.cli.options import input_file, load_model_option
        from tacswitch.motion.infer import load_model

        self.ref = (read_image(input_file(args.ref, "--ref"), "--ref", quiet=True) if args.ref
                    else first)
        if self.ref.shape != first.shape:
            raise ValueError(f"--ref: shape {self.ref.shape} does not match the frames "
                             f"{first.shape}")
        self.reference_shape = first.shape[:2]
        self.method, self.model = args.method or "flow", args.model
        self.reference = (_read_centres(str(input_file(args.centres, "--centres")))
                          if args.centres else
                          load_model_option(load_model, args.model).centres_for(
                              *first.shape[:2]))
        self.positions = self.reference.copy()
        self.grasp_ref: np.ndarray | None = None
        self.all_markers = bool(args.all_markers)
        self.device = args.device
        self.ref_given = args.ref is not None
        # The markers near the grasp-start frame's contact (None: all of them are judged).
        self.grasp_near: np.ndarray | None = None
        self.warned = False

    def __len__(self) -> int:
        return len(self.reference)

    def update(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(motion N x 2, valid N)`` of this frame."""
        from tacswitch.motion.infer import predict_motion

        motion = predict_motion(frame, self.ref, self.reference, method=self.method,
                                model=self.model, device=self.device)
        self.positions = self.reference + motion
        return motion, np.ones(len(motion), bool)

    def since_grasp(self, frame: np.ndarray, restart: bool) -> tuple[np.ndarray, np.ndarray]:
        """``(motion, valid)`` of this frame since the grasp start (``restart``: this frame is
        the start; its motion is exactly zero); valid: the markers near the grasp-start
        frame's contact (every marker with ``--all-markers`` or when the start frame shows no
        contact against ``--ref``)."""
        from tacswitch.motion.infer import predict_motion
        from tacswitch.motion.reference import near_contact

        if restart or self.grasp_ref is None:
            self.grasp_ref = frame.copy()
            near = None if self.all_markers else near_contact(frame, self.ref, self.reference,
                                                              fallback=False)
            if near is None and not self.all_markers and not self.warned:
                # With --ref given, asking for one would argue with the user: say what it
                # means instead.
                hint = ("is --ref a no-contact frame of this sensor and recording?"
                        if self.ref_given else "pass --ref NO_CONTACT.png when the video "
                        "starts in contact (the first frame is the reference without it)")
                print("tacswitch slip: warning: --ref: the grasp-start frame shows no contact "
                      f"against the reference frame, so every marker is judged; {hint}",
                      file=sys.stderr)
                self.warned = True
            self.grasp_near = near
        motion = predict_motion(frame, self.grasp_ref, self.reference, method=self.method,
                                model=self.model, device=self.device)
        if self.grasp_near is None:
            return motion, np.ones(len(motion), bool)
        return motion, self.grasp_near.copy()


def _warn_inter_frame_codec(source: str) -> None:
    """One line on stderr when a markerless slip run reads a video whose codec predicts frames
    from earlier ones (H.264 and the like): flow reads its drifting texture as motion."""
    from pathlib import Path

    from tacswitch.cli.sources import INTER_FRAME_CODECS, video_codec

    if source.isdigit() or not Path(source).is_file():
        return
    codec = video_codec(source)
    if codec in INTER_FRAME_CODECS:
        print(f"tacswitch slip: warning: source: {codec!r} video; on inter-frame codecs the "
              "gel's texture drifts between frames and raises false slip alarms (real-texture "
              "H.264 grasps with noisy frames: GelSight 24-29 of 36 right, 36 lossless or "
              "MJPEG); record lossless or MJPEG for --markerless (from tacswitch "
              "remove-markers: --codec ffv1 or --frames, not its default mp4v)",
              file=sys.stderr)


def _smooth_frames(args: argparse.Namespace) -> int:
    """The rule's moving average: given, else 2 frames on a markerless sensor, 1 with markers."""
    from tacswitch.slip import MARKERLESS_SMOOTH_FRAMES

    if args.smooth_frames is not None:
        return int(args.smooth_frames)
    return MARKERLESS_SMOOTH_FRAMES if args.markerless else 1


def _epsilon(args: argparse.Namespace, width: int) -> float:
    """The displacement threshold in force, px (given, or the paper's scaled to the width)."""
    from tacswitch.slip import scaled_threshold

    return float(args.threshold_px) if args.threshold_px is not None else scaled_threshold(width)


def _row(n: int, step, state, n_valid: int, t: float,  # type: ignore[no-untyped-def]
         offset: int) -> list:
    """One log row; the rule's columns are empty outside a grasp (the rule did not run);
    ``offset``: the rest frame, where the segmenter's frame numbers start."""
    head = [n, step.phase, step.grasp or "", "" if step.start is None else step.start + offset]
    if state is None:
        return [*head, 0, "", "", "", "", "", "", n_valid, f"{t:.4f}"]
    return [*head, int(state.slip), state.criterion or "", f"{state.max_displacement:.3f}",
            state.marker, f"{state.rigid_residual:.3f}", "", "", state.n_compared, f"{t:.4f}"]


def _starts_text(starts: list[int], args: argparse.Namespace, segmenter,  # type: ignore[no-untyped-def]
                 offset: int) -> str:
    """How the grasp start(s) were found, for the summary line (``offset``: the rest frame,
    where the segmenter's frame numbers start)."""
    if args.start is not None:
        if starts and starts[0] != args.start:
            why = ("before the rest frame" if args.start < offset else
                   "the first frame on the scorer's time base at or after it")
            return f"grasp start: frame {starts[0]} (--start {args.start}, {why})"
        return (f"grasp start: frame {args.start} (--start)" if starts else
                f"grasp start --start {args.start} not reached")
    if not starts:
        where = ("contact onset at frame " + str(segmenter.onset + offset) + " never settled"
                 if segmenter is not None and segmenter.onset is not None else "no contact onset")
        return f"no grasp detected ({where}; pass --start FRAME)"
    shown = ", ".join(str(s) for s in starts[:10]) + (" ..." if len(starts) > 10 else "")
    plural = "s" if len(starts) > 1 else ""
    return f"grasp start{plural}: frame{plural} {shown} (contact onset detected)"


def _show(frame: np.ndarray, tracker, state) -> None:  # type: ignore[no-untyped-def]
    import cv2

    from tacswitch import viz

    motion = tracker.positions - tracker.reference
    vis = viz.draw_motion(frame, tracker.reference, motion, scale=2.0)
    if state is None:
        text = "no grasp"
    elif state.slip:
        text = f"SLIP ({state.criterion})"
    elif hasattr(state, "score"):  # the learned rule: its score, or the phase when it is off
        text = f"score {state.score:.2f}" if state.score == state.score else state.phase
    else:
        text = f"max {state.max_displacement:.1f} px"
    cv2.putText(vis, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7,
                (0, 0, 255) if state is not None and state.slip else (0, 200, 0), 2, cv2.LINE_AA)
    cv2.imshow("tacswitch slip", vis)
    cv2.waitKey(1)
