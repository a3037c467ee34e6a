"""``tacswitch motion``: marker motion predicted from markerless frames (arrows overlay + CSV)."""

from __future__ import annotations

import argparse
import csv
import io
from pathlib import Path

#: Methods whose learned part --model names (elsewhere it gives only the default centres).
LEARNED_PART = ("ensemble",)


#: Largest --scale: arrows longer than a few frame widths show nothing more.
MAX_SCALE = 1000.0


def add_parser(sub: argparse._SubParsersAction) -> None:
    from tacswitch.cli.options import bounded

    p = sub.add_parser("motion", help="predict marker motion from markerless images",
                       description="Predicts the (dx, dy) each marker would have had from "
                                   "markerless frames; writes a CSV and an arrow overlay per "
                                   "image. A video is one sequence (as --sequence): every "
                                   "frame's motion from rest by tacswitch.MarkerlessTracker "
                                   "(with --method model: by the model), from the no-contact "
                                   "frame --ref or else the video's first frame after the "
                                   "camera settled (the frames before get no rows; see "
                                   "--starts-in-contact), one CSV per video (frame, x, y, dx, "
                                   "dy) and the overlay of its last frame. Unreadable images "
                                   "are skipped, counted and named in a warning on stderr.")
    p.add_argument("inputs", nargs="+",
                   help="markerless image files, videos (.mp4, .avi, .mov, .mkv, .webm, .m4v) "
                        "or folders of them")
    p.add_argument("--ref", default=None,
                   help="markerless no-contact frame (needed by models trained with it)")
    p.add_argument("--centres", default=None,
                   help="CSV with x,y columns of your sensor's marker rest centres (e.g. from "
                        "`tacswitch markers` on a frame with markers); default: the GelSight "
                        "Mini's 9 x 11 grid (pitch 28.5 px at 320 x 240) scaled to the frame")
    p.add_argument("--model", default=None, help="ONNX model (default: the shipped one)")
    p.add_argument("--method", choices=("auto", "ensemble", "model", "flow", "outward",
                                        "mechanics"),
                   default="auto",
                   help="auto (default): ensemble without --ref, flow with a --ref (the "
                        "no-contact frame or a frame of the same contact); ensemble: the mean "
                        "of the mechanics rule and the learned "
                        "single-frame model (--model: its learned part, default the shipped "
                        "'single'); model: the ONNX "
                        "model; flow: dense optical flow from --ref (training-free, needs "
                        "--ref); outward: the no-learning baseline (markers move outward from "
                        "the contact); mechanics: the simulator's elastic press law applied to "
                        "the imprint (no learning; with or without --ref)")
    p.add_argument("--gain", default=None, metavar="SENSOR|G",
                   help="mechanics / ensemble / outward / auto (when it runs the ensemble; "
                        "a sequence: with --starts-in-contact, the rule on its first frame): "
                        "how far a press moves your gel: a sensor name (gelsight, "
                        "gelsight_mini: fitted on real presses) or a number in [0, 1000], e.g. "
                        "from tacswitch.motion.calibration.calibrate_press_gain (default: the "
                        "rule's own)")
    from tacswitch.motion.flow import DEFAULT_PRESET, FLOW_PRESETS

    p.add_argument("--flow-preset", choices=FLOW_PRESETS, default=None,
                   help="the optical flow's preset wherever flow runs (--method flow, auto "
                        f"with --ref, videos, bags, --sequence); default {DEFAULT_PRESET} "
                        "(camera rate; lower error on real frames than balanced, which is "
                        "~15 %% faster and follows large motions from a frame of the same "
                        "contact further); medium is ~2x slower; accurate (DeepFlow, 10-30x "
                        "slower, 5 frames/s) is for recordings: fewer clips worse than zero "
                        "motion, less false motion on a still gel")
    p.add_argument("--sequence", action="store_true",
                   help="the inputs are the frames of one video, in name order: each frame's "
                        "motion from rest by tacswitch.MarkerlessTracker from the no-contact "
                        "frame (--ref, else the first frame; see --starts-in-contact); method "
                        "auto only. Videos are always read so")
    from tacswitch.motion.sequence import ANCHORS

    p.add_argument("--starts-in-contact", action="store_true",
                   help="a video or --sequence without --ref that starts in contact: its first "
                        "(settled) frame is the anchor, the mechanics rule on it, then the flow "
                        "from it. Without this, the first settled frame is the no-contact frame")
    p.add_argument("--anchor", choices=ANCHORS, default=None,
                   help="over a video, a bag or --sequence from the no-contact frame (--ref, "
                        "or the first frame; of a video, the first after the camera settled): "
                        "contact (default) reads a "
                        "steady contact's motion from the frame where it settled (the flow "
                        "follows the imprint with the gel; on a contact that slides over the "
                        "gel it follows the object), rest the flow from the no-contact frame "
                        "on every frame (docs/markerless-motion.md)")
    from tacswitch.cli.options import positive_count

    p.add_argument("--rest-frames", type=positive_count, default=None, metavar="N",
                   help="over a video, a bag or --sequence from the no-contact frame: average "
                        "it with the still frames after it, up to N in all, until anything "
                        "changes, to average a noisy camera's noise out of every motion (e.g. "
                        "16; default 1: the frame as given; docs/markerless-motion.md)")
    from tacswitch.cli.options import add_device_option

    add_device_option(p, "the learned model (--method model, ensemble, auto without --ref)")
    p.add_argument("-o", "--out", default="motion-out", help="output folder (default: %(default)s)")
    p.add_argument("--scale", type=bounded(0.0, MAX_SCALE), default=3.0, metavar="S",
                   help="overlay arrow length per px of motion, in (0, "
                        f"{MAX_SCALE:g}] (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or messages")
    from tacswitch.cli.bagio import add_bag_options

    add_bag_options(p, "<topic>/marker_motion (sensor_msgs/PointCloud2: x, y, dx, dy, valid "
                       "per marker); a bag is one sequence, as a video")
    p.set_defaults(run=run)


def _read_centres(path: str):  # type: ignore[no-untyped-def]
    """Marker centres ``N x 2`` float32 (x, y) px from a CSV with ``x`` and ``y`` columns;
    :class:`UsageError` naming ``--centres`` for a file that is not one."""
    import numpy as np

    from tacswitch.cli.options import UsageError

    try:
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except UnicodeDecodeError:
        raise UsageError(f"--centres: {path!r} is not a text CSV file") from None
    if not rows or "x" not in rows[0] or "y" not in rows[0]:
        raise UsageError(f"--centres: {path!r} needs a header with x and y columns")
    try:
        centres = np.array([[float(r["x"]), float(r["y"])] for r in rows], np.float32)
    except (TypeError, ValueError):
        raise UsageError(f"--centres: {path!r} has a row whose x or y is not a number") from None
    if not np.isfinite(centres).all():
        raise UsageError(f"--centres: {path!r} has a row whose x or y is not finite")
    return centres


def _gain_option(text: str | None, method: str) -> float | str | None:
    """``--gain`` as :func:`tacswitch.predict_motion` takes it (a number or a sensor name),
    checked against the method it will run with before any image is read."""
    from tacswitch.cli.options import UsageError
    from tacswitch.motion.infer import _rule_gain

    if text is None:
        return None
    try:
        gain: float | str = float(text)
    except ValueError:
        gain = text
    try:
        _rule_gain(method, gain)
    except ValueError as e:
        raise UsageError(f"--gain: {str(e).removeprefix('gain: ')}") from None
    return gain


def _check_sequence_gain(args: argparse.Namespace, ref) -> None:  # type: ignore[no-untyped-def]
    """:class:`UsageError` naming ``--gain`` when only sequences are tracked from a no-contact
    frame (``--ref`` or the first frame): the tracker runs the flow there, and the gain is the
    mechanics rule's, which runs only on the first frame with ``--starts-in-contact``."""
    from tacswitch.cli.options import UsageError

    if args.gain is not None and args.method == "auto" and not args.starts_in_contact:
        src = "--ref" if ref is not None else "the first frame"
        raise UsageError(f"--gain: a sequence is read by the flow from the no-contact frame "
                         f"({src}), which has no gain; it sets the mechanics rule's with "
                         f"--starts-in-contact; drop --gain")


def _flow_preset_option(args: argparse.Namespace) -> str | None:
    """The DIS preset of the trackers and the pairwise flow (``--flow-preset``; None: the
    library's default); :class:`UsageError` naming the option when it was given and nothing of
    this run computes flow."""
    from tacswitch.cli.options import UsageError

    if args.flow_preset is None:
        return None
    if args.method not in ("auto", "flow"):
        raise UsageError(f"--flow-preset: --method {args.method} runs no optical flow; drop "
                         "--flow-preset or use --method flow / auto")
    return str(args.flow_preset)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from tacswitch._io import atomic_open, read_image, write_image
    from tacswitch.cli.options import (
        UsageError,
        device_option,
        input_file,
        load_model_option,
        output_dir,
    )
    from tacswitch.cli.progress import progress, say
    from tacswitch.cli.sources import (
        check_distinct_outputs,
        collect_inputs,
        read_quiet,
        report_unreadable,
    )
    from tacswitch.motion.infer import load_model, predict_motion

    if args.method == "flow" and not args.ref:
        raise UsageError("--ref: --method flow measures motion from a reference frame; pass the "
                         "markerless no-contact frame")
    if args.sequence and args.method != "auto":
        raise UsageError(f"--sequence: the tracker chooses its own methods (flow from the "
                         f"no-contact frame; with --starts-in-contact the mechanics rule on the "
                         f"first frame, flow from it); drop --method {args.method}")
    device = device_option(args.device)
    model = load_model_option(lambda m: load_model(m, device), args.model)
    if args.method in LEARNED_PART:
        from tacswitch.motion.ensemble import learned_model

        # Refused before any image is read (a model that needs a reference cannot be the
        # ensemble's single-frame half).
        load_model_option(lambda m: learned_model(m, device), args.model)
    ref = read_image(input_file(args.ref, "--ref"), "--ref", quiet=True) if args.ref else None
    preset = _flow_preset_option(args)
    if args.starts_in_contact and ref is not None:
        raise UsageError("--starts-in-contact: --ref is the no-contact frame; drop one of them")
    for flag, given in (("--anchor", args.anchor is not None),
                        ("--rest-frames", args.rest_frames is not None)):
        if given and args.starts_in_contact:
            raise UsageError(f"{flag}: applies from a no-contact frame; with "
                             "--starts-in-contact the first frame is the anchor")
    for flag, given in (("--anchor", args.anchor is not None),
                        ("--rest-frames", args.rest_frames is not None),
                        ("--starts-in-contact", args.starts_in_contact)):
        if given and args.method == "model":
            raise UsageError(f"{flag}: MarkerlessTracker's option; --method model reads each "
                             f"frame from --ref (else the first frame) itself; drop {flag}")
    anchor = args.anchor or "contact"
    # "auto" runs the ensemble without --ref and flow with one (which ignores the gain):
    # check --gain as the ensemble's.
    gain = _gain_option(args.gain, "ensemble" if args.method == "auto" else args.method)
    centres = _read_centres(str(input_file(args.centres, "--centres"))) if args.centres else None
    from tacswitch.cli.bagio import bag_sink, only_bag

    bag = only_bag(args.inputs, args)
    if bag is not None:
        _check_sequence_gain(args, ref)
        if args.method != "auto":
            raise UsageError(f"--method: a bag is one sequence, tracked by MarkerlessTracker "
                             f"(the flow from rest); drop --method {args.method}")
        out = output_dir(args.out, "--out")
        with bag_sink(bag, args) as sink:
            _track_video(bag.path, ref, centres, gain, args, out, stream=bag, sink=sink,
                         preset=preset, anchor=anchor)
        return 0
    files, videos = collect_inputs(args.inputs)
    for flag, given in (("--anchor", args.anchor is not None),
                        ("--rest-frames", args.rest_frames is not None),
                        ("--starts-in-contact", args.starts_in_contact)):
        if given and not (videos or args.sequence):
            raise UsageError(f"{flag}: applies to a video, a bag or --sequence (single images "
                             f"are each read on their own); drop {flag}")
    if args.sequence or (videos and not files):
        _check_sequence_gain(args, ref)
    if videos and args.method not in ("auto", "model"):
        raise UsageError(f"--method: a video is one sequence, tracked by MarkerlessTracker "
                         f"(the flow from rest) or, with --method model, by the model from "
                         f"--ref (else the first settled frame); drop --method {args.method}")
    out = output_dir(args.out, "--out")
    check_distinct_outputs([(p, out / f"{p.stem}.csv") for p in [*files, *videos]])
    if centres is None:
        say("centres: the default grid (the GelSight Mini's 9 x 11 markers scaled to the "
            "frame); pass --centres for your sensor's own", quiet=args.quiet)
    failed: list[tuple[Path, str]] = []
    done = 0
    for path in videos:
        try:
            _track_video(path, ref, centres, gain, args, out,
                         model=model if args.method == "model" else None, preset=preset,
                         anchor=anchor)
        except ValueError as exc:  # a video that does not decode: skipped and named, as images
            if not str(exc).startswith("inputs:"):
                raise
            failed.append((path, str(exc)))
            continue
        done += 1
    tracker = None
    skip = 0  # readable images before the first settled one (--sequence without --ref)
    if args.sequence:
        tracker = _SequenceTracker(ref, centres, gain, args, preset, anchor)
        if ref is None:
            skip = _settled_start(files)
    readable = 0
    # Pairs run flow with --method flow, or auto with --ref; the preset goes only there.
    pair_preset = preset if args.method == "flow" or (args.method == "auto" and ref is not None) \
        else None
    with progress(files, desc="motion", unit="img", quiet=args.quiet) as bar:
        for path in bar:
            img = read_quiet(path)
            if img is None:
                failed.append((path, f"inputs: cannot read an image from {str(path)!r}"))
                continue
            if ref is not None and img.shape != ref.shape:
                failed.append((path, f"--ref: shape {ref.shape} does not match "
                                     f"{str(path)!r} {img.shape}"))
                continue
            readable += 1
            if readable <= skip:
                continue
            if readable == skip + 1 and skip:
                say(f"--sequence: the first {skip} readable image(s) come before the camera "
                    f"settled (exposure changing, or frames left from before), so motion is "
                    f"measured from {path}; those get no output (pass --ref to choose the "
                    "reference)", quiet=args.quiet)
            try:
                if tracker is not None:
                    motion = tracker.update(img)
                    assert tracker.centres is not None  # set by the first update
                    pts = tracker.centres
                else:
                    pts = model.centres_for(*img.shape[:2]) if centres is None else centres
                    motion = (model(img, ref=ref, centres=pts) if args.method == "model" else
                              predict_motion(img, ref, pts, method=args.method, gain=gain,
                                             model=args.model if args.method in LEARNED_PART
                                             else None, device=device, preset=pair_preset))
            except ValueError as exc:  # this image cannot be read as asked (too small, ...)
                why = str(exc)
                if centres is not None and why.startswith("centres:"):
                    # The given centres do not fit this image: --centres names the cause.
                    failed.append((path, f"--{why} ({str(path)!r})"))
                else:
                    failed.append((path, f"inputs: {str(path)!r}: {why}"))
                continue
            buf = io.StringIO()
            w = csv.writer(buf)
            w.writerow(["x", "y", "dx", "dy"])
            for (x, y), (dx, dy) in zip(pts, motion, strict=True):
                w.writerow([f"{x:.3f}", f"{y:.3f}", f"{dx:.4f}", f"{dy:.4f}"])
            with atomic_open(out / f"{path.stem}.csv") as fh:
                fh.write(buf.getvalue())
            write_image(out / f"{path.stem}_motion.png", _arrows(img, pts, motion, args.scale))
            mx = float(np.hypot(motion[:, 0], motion[:, 1]).max()) if len(motion) else 0.0
            say(f"{path}: {len(motion)} markers, largest motion {mx:.2f} px -> "
                f"{out / (path.stem + '.csv')}", quiet=args.quiet)
            done += 1
    report_unreadable("motion", failed, done)
    return 0


def _arrows(img, pts, motion, scale: float):  # type: ignore[no-untyped-def]
    """``img`` with an arrow per marker, ``scale`` px per px of motion."""
    import cv2
    import numpy as np

    vis = img.copy()
    # Tips far outside the frame are clipped (OpenCV clips the line there anyway): a huge
    # predicted motion must not overflow the integer pixel coordinates.
    reach = 4.0 * max(img.shape[:2])
    for (x, y), (dx, dy) in zip(pts, motion, strict=True):
        tx, ty = (float(np.clip(np.nan_to_num(v), -reach, reach)) for v in
                  (x + scale * dx, y + scale * dy))
        tip = (round(tx), round(ty))
        cv2.arrowedLine(vis, (round(float(x)), round(float(y))), tip, (0, 0, 255), 1,
                        cv2.LINE_AA, tipLength=0.3)
    return vis


class _SequenceTracker:
    """A :class:`~tacswitch.motion.sequence.MarkerlessTracker` from ``ref`` (the no-contact
    frame), or without one from the first frame it is given: that frame is the no-contact
    frame, or with ``--starts-in-contact`` the tracker starts without one (the first frame is
    its anchor, the mechanics rule on it). Measured on the real GelSight Mini videos (markers
    removed for motion, 14 held-out objects): 0.44x zero motion from the first frame as the
    no-contact frame, 0.48x with it as an anchor in contact."""

    def __init__(self, ref, centres, gain, args: argparse.Namespace,  # type: ignore[no-untyped-def]
                 preset: str | None, anchor: str) -> None:
        self._options = {"centres": centres, "gain": gain, "model": args.model,
                         "preset": preset, "anchor": anchor}
        if args.rest_frames is not None:
            self._options["rest_frames"] = args.rest_frames
        self._first_is_rest = not args.starts_in_contact
        self._tracker = None if ref is None else self._make(ref)

    def _make(self, no_contact):  # type: ignore[no-untyped-def]
        from tacswitch.motion.sequence import MarkerlessTracker

        return MarkerlessTracker(no_contact, **self._options)

    @property
    def centres(self):  # type: ignore[no-untyped-def]
        return None if self._tracker is None else self._tracker.centres

    def update(self, img):  # type: ignore[no-untyped-def]
        if self._tracker is None:
            self._tracker = self._make(img if self._first_is_rest else None)
        return self._tracker.update(img)


class _ModelFromAnchor:
    """``--method model`` on a video: each frame's motion from the anchor (``ref``, else the
    video's first frame) by the learned ``model`` (a :class:`~tacswitch.motion.infer.MotionModel`;
    a single-frame model sees each frame alone, from rest), the tracker interface of
    :class:`~tacswitch.motion.sequence.MarkerlessTracker`."""

    def __init__(self, model, ref, centres) -> None:  # type: ignore[no-untyped-def]
        self.model, self.anchor, self.centres = model, ref, centres

    def update(self, img):  # type: ignore[no-untyped-def]
        if self.centres is None:
            self.centres = self.model.centres_for(*img.shape[:2])
        if self.model.design == "single":
            return self.model(img, centres=self.centres)
        if self.anchor is None:
            self.anchor = img.copy()
        return self.model(img, ref=self.anchor, centres=self.centres)


def _settled_start(files: list[Path]) -> int:
    """How many readable images of a ``--sequence`` come before the camera settled, as a
    video's frames are read (:func:`tacswitch.cli.rest_frame.choose_rest_frame`, markerless:
    exposure still changing, or an isolated jump of the whole image at the start)."""
    from tacswitch.cli.rest_frame import choose_rest_frame
    from tacswitch.cli.sources import read_quiet

    rest, _ = choose_rest_frame((read_quiet(p) for p in files), None, source="--sequence")
    return 0 if rest is None else rest.index


def _track_video(path: Path, ref, centres, gain, args: argparse.Namespace,  # type: ignore[no-untyped-def]
                 out: Path, stream=None, sink=None, model=None, preset=None,
                 anchor: str = "contact") -> None:
    """Every frame of the video ``path`` through one :class:`_SequenceTracker` (``ref``: the
    no-contact frame, or None: the first frame is (of a video, the first after the camera
    settled), or with ``--starts-in-contact`` the anchor), or with ``model`` (``--method
    model``) through :class:`_ModelFromAnchor`; ``<stem>.csv`` with a row per
    frame and marker, ``<stem>_motion.png`` the last frame's arrows. Frames that do not decode
    are skipped (their rows are absent); a video with none raises ``ValueError``. ``stream``:
    the frames when they come from elsewhere (a :class:`tacswitch.bags.BagSource`, whose
    ``frames`` then give ``sink``, a :class:`tacswitch.bags.BagSink` or None, each frame's
    stamps). ``preset``: the tracker's DIS preset (``--flow-preset``; None: the default);
    ``anchor``: its ``anchor`` (``--anchor``)."""
    import numpy as np

    from tacswitch._io import atomic_open, write_image
    from tacswitch.cli.progress import progress, say
    from tacswitch.cli.rest_frame import choose_rest_frame
    from tacswitch.cli.sources import frame_count, video_frames

    tracker = (_SequenceTracker(ref, centres, gain, args, preset, anchor)
               if model is None else _ModelFromAnchor(model, ref, centres))
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["frame", "x", "y", "dx", "dy"])
    last = None
    n = 0
    from tacswitch.cli.bagio import motion_fields

    frames = video_frames(path, "inputs") if stream is None else stream
    skip = 0  # readable frames before the rest frame (the camera settling)
    if ref is None and stream is None:
        # As `tacswitch slip --markerless` chooses its rest frame: the first settled frame.
        rest, frames = choose_rest_frame(frames, None, source=str(path))
        skip = 0 if rest is None else rest.index
    readable = 0
    # A bar over the frames: a long video, or the slow `accurate` flow, takes minutes.
    total = frame_count(str(path)) if stream is None else (len(stream) or None)
    with progress(total=total, desc=path.name, unit="frame", quiet=args.quiet) as bar:
        for t, img in enumerate(frames):
            bar.update(1)
            if img is None:
                continue
            if ref is not None and img.shape != ref.shape:
                raise ValueError(f"--ref: shape {ref.shape} does not match the frames of "
                                 f"{str(path)!r} {img.shape}")
            readable += 1
            if readable <= skip:
                continue
            if n == 0 and skip:
                before = "frame 0 comes" if t == 1 else f"frames 0-{t - 1} come"
                say(f"{path}: {before} before the camera settled (exposure "
                    "changing, or frames left from before), so motion is measured from frame "
                    f"{t}; those frames get no rows (pass --ref to choose the reference)",
                    quiet=args.quiet)
            motion = tracker.update(img)
            pts = tracker.centres
            assert pts is not None  # set by the first update
            if sink is not None:
                sink.points(stream.frames[t], motion_fields(pts, motion))
            for (x, y), (dx, dy) in zip(pts, motion, strict=True):
                w.writerow([t, f"{x:.3f}", f"{y:.3f}", f"{dx:.4f}", f"{dy:.4f}"])
            last = (img, pts, motion)
            n += 1
    if last is None:
        raise ValueError(f"inputs: no frame of {str(path)!r} could be decoded")
    with atomic_open(out / f"{path.stem}.csv") as fh:
        fh.write(buf.getvalue())
    write_image(out / f"{path.stem}_motion.png", _arrows(*last, args.scale))
    mx = float(np.hypot(*last[2].T).max()) if len(last[2]) else 0.0
    say(f"{path}: {n} frames, {len(last[2])} markers, largest motion at the last frame "
        f"{mx:.2f} px -> {out / (path.stem + '.csv')}", quiet=args.quiet)
