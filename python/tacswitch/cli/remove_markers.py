"""``tacswitch remove-markers``: markerless images and videos from marker ones."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from tacswitch.cli.options import UsageError
from tacswitch.cli.resume import OutputRecord
from tacswitch.cli.sources import VIDEO_SUFFIXES, collect_inputs

#: Methods that run the TacDiff model (onnxruntime already uses every core: run serially).
MODEL_METHODS = ("tacdiff", "hybrid")

Remover = Callable[[np.ndarray], np.ndarray]


def add_parser(sub: argparse._SubParsersAction) -> None:
    from tacswitch.cli.batch import CODECS
    from tacswitch.cli.options import add_extraction_options
    from tacswitch.inpaint import DEFAULT_RADIUS, NS_RADIUS

    p = sub.add_parser(
        "remove-markers",
        help="remove the painted markers from images and videos",
        description="Extracts each frame's markers, grows the mask over their soft edges and "
        "inpaints it. An image becomes OUT/<stem>.png; a video (" + ", ".join(
            sorted(VIDEO_SUFFIXES)) + ") becomes OUT/<stem>.mp4 (--codec mp4v, the default: "
        "LOSSY, frames differ from the in-memory result by a few grey levels) or "
        "OUT/<stem>.mkv (--codec ffv1: lossless, bit-exact frames), same size and fps, or "
        "with --frames a folder OUT/<stem>/ of lossless PNG frames named by frame index. "
        "Folders are searched for both. Frames that do not decode are skipped and counted; "
        "unreadable images and videos are skipped, counted and named at the end. Existing "
        "outputs made from the same input with the same options are skipped, so an "
        "interrupted run resumes (a video file is redone, a --frames folder resumes frame by "
        "frame); outputs made with other options or from another input of the same name are "
        "redone (OUT/.tacswitch-remove-markers.json records which input and options made "
        "each output); every write is atomic. For markerless motion from the outputs "
        "(tacswitch motion), --dilate 5 --radius 5 leaves no fill seams for the flow to "
        "misread, and --codec ffv1 no codec noise (docs/markerless-motion.md).",
        epilog="Exit status: 0 when every readable input is done (unreadable ones are named "
        "in a warning on stderr), 1 when no input could be read or an input cannot be "
        "processed, 2 for an unusable option value (e.g. a file that is not a TacDiff "
        "--model, an --out path under a file).",
    )
    p.add_argument("inputs", nargs="+", help="image files, video files or folders of them")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--method", choices=("telea", "biharmonic", "ns", *MODEL_METHODS),
                   default="telea",
                   help="telea (fast, default; the most accurate classical fill on real "
                        "frames), biharmonic (smooth fill: on real frames it leaves grey "
                        "ghosts where TELEA does not), ns (OpenCV), tacdiff (diffusion model), "
                        "hybrid (tacdiff near the contact, telea elsewhere)")
    p.add_argument("--radius", type=int, default=None,
                   help=f"inpainting radius, px (default: {DEFAULT_RADIUS} for telea and "
                        f"hybrid, the best on real frames; {NS_RADIUS} for ns)")
    p.add_argument("--steps", type=int, default=None,
                   help="tacdiff/hybrid sampler steps K (default: 1)")
    p.add_argument("--separation", type=int, default=None, metavar="PX",
                   help="tacdiff/hybrid: holes within PX of one another are filled in separate "
                        "passes (default: 4; 0: one pass)")
    p.add_argument("--orientations", type=int, choices=(1, 2, 4, 8), default=None,
                   help="tacdiff/hybrid: run the network on the frame in N orientations (as is, "
                        "mirrored, turned) and average them: lower error, N times the network "
                        "time (default: 4, or 1 with --model fast)")
    p.add_argument("--ref", default=None,
                   help="hybrid: no-contact frame of the sensor to find the contact against "
                        "(default for a video: its first frame after the camera settled, which "
                        "should show no contact; for images: the contact is found from local "
                        "texture)")
    p.add_argument("--model", default=None,
                   help="tacdiff/hybrid ONNX model, or 'fast' for the shipped narrow model "
                        "(default: the shipped model)")
    from tacswitch.cli.options import add_device_option

    add_device_option(p, "tacdiff/hybrid's network")
    p.add_argument("--codec", choices=tuple(CODECS), default="mp4v",
                   help="video output: mp4v -> OUT/<stem>.mp4 (lossy, plays anywhere; "
                        "default), ffv1 -> OUT/<stem>.mkv (lossless, bit-exact frames; use it, "
                        "or --frames, for videos that `tacswitch slip --markerless` or "
                        "`tacswitch motion` will read)")
    p.add_argument("--frames", action="store_true",
                   help="write a video's frames as PNGs (lossless) into OUT/<stem>/ instead of "
                        "a video")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="telea/biharmonic/ns: threads over images and video frames (default: "
                        "all cores); tacdiff/hybrid run one item at a time, onnxruntime uses "
                        "all cores")
    p.add_argument("--overwrite", action="store_true",
                   help="redo existing outputs, even those made with the same options")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bars or messages (warnings still go to stderr)")
    add_extraction_options(p, border_default="keep", dilate=True)
    from tacswitch.cli.bagio import add_bag_options

    add_bag_options(p, "<topic>/markerless (sensor_msgs/Image, bgr8); default for a bag input: "
                       "OUT/<bag name> (OUT/<stem>.bag for ROS 1)")
    from tacswitch.cli.cluster import add_ray_option

    add_ray_option(p)
    p.set_defaults(run=run)


def _remover(args: argparse.Namespace, ref: np.ndarray | None) -> Remover:
    import tacswitch as ts
    from tacswitch.cli.options import extraction_options

    opts: dict[str, Any] = extraction_options(args)
    if args.method in MODEL_METHODS:
        opts.update(steps=args.steps, ref=ref, model=args.model, separation=args.separation,
                    orientations=args.orientations, device=args.device)

    def remove(img: np.ndarray) -> np.ndarray:
        return ts.remove_markers(img, method=args.method, radius=args.radius, **opts)

    return remove


def _finds_markers(img: np.ndarray, args: argparse.Namespace) -> bool:
    """Whether the extraction options find any marker in ``img`` (none found: the fill leaves
    the frame as it is, which deserves a warning, not a silent copy)."""
    import tacswitch as ts
    from tacswitch.cli.options import extraction_options

    return len(ts.extract_markers(img, **extraction_options(args))) > 0


def _warn_no_markers(names: list[str]) -> None:
    """One warning for the inputs in which no marker was found."""
    from tacswitch.cli.progress import warn

    if names:
        more = f" and {len(names) - 1} more" if len(names) > 1 else ""
        warn("remove-markers", f"no markers found in {names[0]}{more}, so the output equals the "
             "input there; check --polarity and --threshold (tacswitch markers shows what is "
             "found)")


def _output_options(args: argparse.Namespace) -> dict[str, Any]:
    """The options that shape the outputs, by flag (those the method ignores left out): an
    output is only skipped on a rerun with the same ones."""
    from tacswitch.cli.options import extraction_options

    opts: dict[str, Any] = {"--method": args.method, "--radius": args.radius}
    if args.method in MODEL_METHODS:
        opts |= {"--steps": args.steps, "--separation": args.separation,
                 "--orientations": args.orientations, "--model": args.model}
    if args.method == "hybrid":
        opts["--ref"] = str(Path(args.ref).resolve()) if args.ref is not None else None
    opts |= {f"--{k.replace('_', '-')}": v for k, v in extraction_options(args).items()}
    return opts


def _video_target(path: Path, out: Path, args: argparse.Namespace) -> Path:
    """Where a video's output goes: a folder of PNGs (--frames) or a file of --codec."""
    from tacswitch.cli.batch import CODECS

    return out / path.stem if args.frames else out / f"{path.stem}{CODECS[args.codec][1]}"


def _jobs(images: list[Path], videos: list[Path], out: Path, args: argparse.Namespace
          ) -> list[tuple[Path, Path, str]]:
    """Every input with its output and kind: ``(path, target, "image" | "video")``; an image
    becomes ``OUT/<stem>.png``, a video :func:`_video_target`."""
    jobs = [(p, out / f"{p.stem}.png", "image") for p in images]
    return jobs + [(p, _video_target(p, out, args), "video") for p in videos]


def _targets(images: list[Path], videos: list[Path], out: Path,
             args: argparse.Namespace) -> None:
    """``ValueError`` if two inputs would write the same output (same stem, same kind), or an
    output would replace its own input (a :class:`UsageError` of ``--out``)."""
    from tacswitch.cli.options import UsageError
    from tacswitch.cli.sources import check_distinct_outputs

    jobs = _jobs(images, videos, out, args)
    for path, target, _ in jobs:
        if target.resolve() == path.resolve():
            raise UsageError(f"--out: writing {str(target)!r} would replace its input; choose "
                             "another output folder")
    check_distinct_outputs([(path, target) for path, target, _ in jobs])


def _check_options(args: argparse.Namespace) -> None:
    """Option values that cannot work, and options the method ignores (a warning)."""
    from tacswitch.cli.options import UsageError, device_option, load_model_option
    from tacswitch.cli.progress import warn

    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers: must be >= 1; got {args.workers}")
    if args.radius is not None and args.radius < 1:
        raise UsageError(f"--radius: must be >= 1 px; got {args.radius}")
    if args.steps is not None and args.steps < 1:
        raise UsageError(f"--steps: must be >= 1; got {args.steps}")
    if args.separation is not None and args.separation < 0:
        raise UsageError(f"--separation: must be >= 0 px; got {args.separation}")
    ignored = [flag for flag, value, used_by in (
        ("--steps", args.steps, MODEL_METHODS), ("--model", args.model, MODEL_METHODS),
        ("--separation", args.separation, MODEL_METHODS),
        ("--orientations", args.orientations, MODEL_METHODS),
        ("--device", None if args.device == "auto" else args.device, MODEL_METHODS),
        ("--ref", args.ref, ("hybrid",)),
        ("--radius", args.radius, ("telea", "ns", "hybrid"))) if value is not None
        and args.method not in used_by]
    if ignored:
        users = {"--ref": "hybrid", "--radius": "telea, ns and hybrid"}
        warn("remove-markers", "; ".join(
            f"{flag} is ignored by --method {args.method} (used by "
            f"{users.get(flag, 'tacdiff and hybrid')})" for flag in ignored))
    if args.method in MODEL_METHODS:
        from tacswitch.tacdiff.infer import load_model

        device = device_option(args.device)
        # A wrong file fails here, in one line.
        load_model_option(lambda m: load_model(m, device), args.model)


def run(args: argparse.Namespace) -> int:
    from tacswitch.cli.batch import default_workers
    from tacswitch.cli.options import input_file, output_dir
    from tacswitch.cli.progress import say
    from tacswitch.cli.sources import read_quiet, report_unreadable

    _check_options(args)
    from tacswitch.cli.bagio import only_bag

    bag = only_bag(args.inputs, args)
    if bag is not None:
        if args.ray is not None:
            raise UsageError("--ray: runs image and video files; a bag is read in one stream "
                             "(drop --ray)")
        return _bag(bag, args)
    images, videos = collect_inputs(args.inputs)
    out = Path(args.out)
    _targets(images, videos, out, args)
    ref = None
    if args.ref is not None and args.method == "hybrid":
        ref = read_quiet(input_file(args.ref, "--ref"))
        if ref is None:
            raise UsageError(f"--ref: cannot read an image from {args.ref!r}")
    output_dir(out, "--out")
    workers = 1 if args.method in MODEL_METHODS else (args.workers or default_workers())
    with OutputRecord(out, "remove-markers", _output_options(args)) as record:
        if args.ray is not None:
            done, skipped, failed, bad = _on_ray(images, videos, out, ref, args, record)
            videos = []
        else:
            done, skipped, failed = _images(images, out, _remover(args, ref), workers, args,
                                            record)
            bad = 0
        for path in videos:
            try:
                d, s, b = _video(path, out, ref, workers, args, record)
            except _Unreadable as exc:
                failed.append((path, str(exc)))
                continue
            done, skipped, bad = done + d, skipped + s, bad + b
    report_unreadable("remove-markers", failed, done + skipped)
    say(f"{done} written, {skipped} already done"
        + (f", {len(failed)} unreadable skipped" if failed else "")
        + (f", {bad} unreadable video frames skipped" if bad else "") + f", in {out}",
        quiet=args.quiet)
    return 0


def _bag(src: Any, args: argparse.Namespace) -> int:
    """A ROS bag: a new bag with every input message and ``<topic>/markerless``, at
    ``--out-bag`` or ``OUT/<bag name>`` (``OUT/<stem>.bag`` for ROS 1). Written whole every
    run (atomically); frames that do not decode are skipped and counted."""
    from tacswitch.bags import check_output
    from tacswitch.cli.bagio import bag_sink
    from tacswitch.cli.batch import default_workers, ordered_map
    from tacswitch.cli.options import input_file, output_dir
    from tacswitch.cli.progress import progress, say
    from tacswitch.cli.sources import read_quiet

    ref = None
    if args.ref is not None and args.method == "hybrid":
        ref = read_quiet(input_file(args.ref, "--ref"))
        if ref is None:
            raise UsageError(f"--ref: cannot read an image from {args.ref!r}")
    target = args.out_bag
    if target is None:
        out = output_dir(args.out, "--out")
        target = out / (f"{src.path.stem}.bag" if src.kind == "ros1" else src.path.stem)
        try:
            check_output(src.path, target, args.bag_storage, "--out")
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    workers = 1 if args.method in MODEL_METHODS else (args.workers or default_workers())
    remove: Remover | None = None

    def items() -> Iterator[tuple[int, np.ndarray | None]]:
        nonlocal remove
        stream: Iterator[np.ndarray | None] = iter(src)
        if ref is None and args.method == "hybrid":
            # As for a video (the replayed stream keeps the bag's frame order and indices).
            remove, stream = _hybrid_reference(stream, src.path, f"{src.path} {src.topic}",
                                               args, args.quiet)
        for i, frame in enumerate(stream):
            if remove is None and frame is not None:
                remove = _remover(args, ref)
            yield i, frame

    def clean(item: tuple[int, np.ndarray | None]) -> tuple[int, np.ndarray | None]:
        i, frame = item
        if frame is None:
            return i, None
        assert remove is not None
        return i, remove(frame)

    done = bad = 0
    with bag_sink(src, args, target) as sink, \
            progress(total=len(src) or None, desc="bag", unit="frame", quiet=args.quiet) as bar, \
            ordered_map(clean, items(), workers) as cleaned:
        for i, out_frame in cleaned:
            bar.update()
            if out_frame is None:
                bad += 1
                continue
            sink.image(src.frames[i], out_frame)
            done += 1
        if done == 0:
            raise ValueError(f"inputs: no frame of {src.topic} in {str(src.path)!r} decodes")
    say(f"{src.path} {src.topic} -> {target} ({done} markerless frames on "
        f"{src.topic.rstrip('/')}/markerless" + (f", {bad} unreadable skipped" if bad else "")
        + ")", quiet=args.quiet)
    return 0


class _Unreadable(ValueError):
    """An input (image or video) that cannot be decoded at all: skipped and counted."""


def _images(images: list[Path], out: Path, remove: Remover, workers: int,
            args: argparse.Namespace, record: OutputRecord
            ) -> tuple[int, int, list[tuple[Path, str]]]:
    """Marker removal on image files, ``workers`` at a time; (written, already done with the
    same options, unreadable files with the reason). Files are decoded on this thread
    (quietly: libpng's own messages are kept off the terminal), filled and written on the
    workers."""
    from tacswitch._io import write_image
    from tacswitch.cli.batch import ordered_map
    from tacswitch.cli.progress import progress, say
    from tacswitch.cli.sources import read_quiet

    jobs = [(p, t) for p, t, _ in _jobs(images, [], out, args)]
    todo = [(p, t) for p, t in jobs if args.overwrite or not record.made_here(t, p)]
    failed: list[tuple[Path, str]] = []

    def decoded() -> Iterator[tuple[Path, Path, np.ndarray | None]]:
        for path, target in todo:
            yield path, target, read_quiet(path)

    def one(job: tuple[Path, Path, np.ndarray | None]) -> tuple[Path, Path, bool, bool]:
        """Fills one image; (path, target, read, changed: False where no marker was found)."""
        path, target, img = job
        if img is None:
            return path, target, False, False
        result = remove(img)
        write_image(target, result)
        return path, target, True, not np.array_equal(result, img)

    unmarked: list[str] = []
    with progress(total=len(todo), desc="images", unit="img", quiet=args.quiet) as bar, \
            ordered_map(one, decoded(), workers) as results:
        for path, target, ok, marked in results:
            bar.update()
            if ok:
                record.add(target, path)
                say(f"{path} -> {target}", quiet=args.quiet)
                if not marked:
                    unmarked.append(str(path))
            else:
                failed.append((path, f"inputs: cannot read an image from {str(path)!r}"))
    _warn_no_markers(unmarked)
    return len(todo) - len(failed), len(jobs) - len(todo), failed


def _stale_parts(out: Path, stem: str) -> None:
    """Removes temporary files a killed run left for this video (one run per OUT at a time)."""
    import glob

    for part in out.glob(f".{glob.escape(stem)}.*.part.*"):
        part.unlink(missing_ok=True)


def _video(path: Path, out: Path, ref: np.ndarray | None, workers: int,
           args: argparse.Namespace, record: OutputRecord) -> tuple[int, int, int]:
    """One video: a markerless ``OUT/<stem>.mp4`` (``.mkv`` for ffv1) or, with ``--frames``,
    PNG frames in ``OUT/<stem>/``. Returns (outputs written, outputs already done, unreadable
    frames); :class:`_Unreadable` if not one frame decodes. Only outputs ``record`` holds as
    made with the same options are kept: a frames folder made with others is redone whole."""
    from tacswitch._io import write_image
    from tacswitch.cli.batch import AtomicVideoWriter, ordered_map
    from tacswitch.cli.progress import progress, say
    from tacswitch.cli.sources import video_frames, video_info

    target = _video_target(path, out, args)
    if not args.frames and record.made_here(target, path) and not args.overwrite:
        return 0, 1, 0
    try:
        fps, count = video_info(path, "inputs")
    except ValueError as exc:
        raise _Unreadable(str(exc)) from None
    remove: Remover | None = None
    quiet = args.quiet

    def items() -> Iterator[tuple[int, np.ndarray | None]]:
        """Decoded frames with their index (on this thread); the remover is made at the first
        readable frame, or for a hybrid run without --ref at the first frame after the camera
        settled (:func:`_hybrid_reference`), its no-contact reference."""
        nonlocal remove
        stream: Iterator[np.ndarray | None] = video_frames(path, "inputs")
        if ref is None and args.method == "hybrid":
            remove, stream = _hybrid_reference(stream, path, str(path), args, quiet)
        warned = False
        for i, frame in enumerate(stream):
            if frame is not None and not warned:
                warned = True
                if remove is None:
                    remove = _remover(args, ref)
                if not _finds_markers(frame, args):
                    _warn_no_markers([f"the first readable frame of {path}"])
            yield i, frame

    bar = progress(total=count, desc=path.name, unit="frame", quiet=quiet)
    if args.frames:
        fresh = not target.exists() or not any(target.iterdir())
        # Frame by frame resume only in a folder of these options' frames; a new folder is
        # recorded at once (every frame in it will be this run's), one of other options only
        # once all its frames are redone.
        redo = args.overwrite or not (fresh or record.made_here(target, path))
        if fresh:
            record.add(target, path)
            record.save()

        def one(item: tuple[int, np.ndarray | None]) -> str:
            i, frame = item
            if frame is None:
                return "bad"
            png = target / f"{i:06d}.png"
            if png.exists() and not redo:
                return "skip"
            assert remove is not None
            write_image(png, remove(frame))
            return "done"

        tally = {"done": 0, "skip": 0, "bad": 0}
        with bar, ordered_map(one, items(), workers) as statuses:
            for status in statuses:
                tally[status] += 1
                bar.update()
        if tally["done"] + tally["skip"] == 0:
            raise _Unreadable(f"inputs: no readable frame in video {str(path)!r}")
        record.add(target, path)
        say(f"{path} -> {target}/ ({tally['done']} frames written, {tally['skip']} already "
            f"done, {tally['bad']} unreadable skipped)", quiet=quiet)
        return tally["done"], tally["skip"], tally["bad"]

    def clean(item: tuple[int, np.ndarray | None]) -> np.ndarray | None:
        frame = item[1]
        if frame is None:
            return None
        assert remove is not None
        return remove(frame)

    _stale_parts(out, path.stem)
    bad = 0
    with bar, AtomicVideoWriter(target, fps or 30.0, args.codec) as writer, \
            ordered_map(clean, items(), workers) as cleaned:
        for out_frame in cleaned:
            if out_frame is None or not writer.write(out_frame):
                bad += 1
            bar.update()
        if writer.frames == 0:
            raise _Unreadable(f"inputs: no readable frame in video {str(path)!r}")
        writer.commit()
    record.add(target, path)
    say(f"{path} -> {target} ({writer.frames} frames, {bad} unreadable skipped)", quiet=quiet)
    return 1, 0, bad


def _hybrid_reference(stream: Iterator[np.ndarray | None], path: Path, label: str,
                      args: argparse.Namespace, quiet: bool
                      ) -> tuple[Remover | None, Iterator[np.ndarray | None]]:
    """The hybrid remover of a video or bag without --ref, and the whole stream again: its
    no-contact reference is the first frame after the camera settled
    (:func:`tacswitch.cli.rest_frame.choose_rest_frame`, as ``slip`` and ``motion`` take it:
    not an under-exposed first frame, nor frames left in the camera's buffer from a previous
    grasp), named on stdout after ``label``. None when no frame decodes."""
    import itertools

    from tacswitch.cli.progress import say
    from tacswitch.cli.rest_frame import choose_rest_frame

    rest, replay = choose_rest_frame(stream, None, source=str(path))
    if rest is None:
        return None, replay
    head: list[np.ndarray | None] = []
    readable = -1
    for frame in replay:  # the look-ahead's frames, replayed up to the reference
        head.append(frame)
        if frame is not None:
            readable += 1
            if readable == rest.index:
                index = len(head) - 1
                say(f"{label}: hybrid reference (no contact) = frame {index}"
                    + (" (the first after the camera settled)" if index else ""), quiet=quiet)
                return _remover(args, frame.copy()), itertools.chain(head, replay)
    return None, iter(head)


#: Stands for the input's path in a Ray task's error message (the task sees a temporary copy).
_INPUT = "\0input\0"


def _on_ray(images: list[Path], videos: list[Path], out: Path, ref: np.ndarray | None,
            args: argparse.Namespace, record: OutputRecord
            ) -> tuple[int, int, list[tuple[Path, str]], int]:
    """Every image and video as a Ray task (:mod:`tacswitch.cli.cluster`): (files written,
    already done with the same options, unreadable files with the reason, unreadable video
    frames skipped). A task runs :func:`_images` / :func:`_video` on a copy of its input, so
    the outputs equal a run without ``--ray``."""
    from tacswitch.cli.cluster import FileResult, connected, map_files, write_outputs
    from tacswitch.cli.progress import progress, say

    jobs = _jobs(images, videos, out, args)
    todo = [(p, t, k) for p, t, k in jobs if args.overwrite or not record.made_here(t, p)]
    target_of = {p: t for p, t, _ in todo}
    task_args = argparse.Namespace(**{**vars(args), "quiet": True})
    failed: list[tuple[Path, str]] = []
    tally = {"done": 0, "bad": 0}

    with connected(args.ray, args.workers) as ray, \
            progress(total=len(todo), desc="files", unit="file", quiet=args.quiet) as bar:
        def arrived(path: Path, res: FileResult) -> None:
            bar.update()
            if res.unreadable is not None:
                failed.append((path, res.unreadable.replace(_INPUT, repr(str(path)))))
                return
            write_outputs(out, res.outputs)
            record.add(target_of[path], path)
            tally["done"] += 1
            tally["bad"] += res.bad_frames
            say(f"{path} -> {target_of[path]}", quiet=args.quiet)

        def unreadable(path: Path, reason: str) -> None:
            bar.update()
            failed.append((path, reason))

        map_files(ray, _ray_task, [(p, (k, task_args, ref)) for p, _, k in todo], arrived,
                  unreadable)
    return tally["done"], len(jobs) - len(todo), failed, tally["bad"]


def _ray_task(name: str, data: bytes,
              job: tuple[str, argparse.Namespace, np.ndarray | None]) -> Any:
    """One input file as a Ray task: the single-machine code on a temporary copy, one thread."""
    from tacswitch.cli.cluster import FileResult, run_in_scratch

    kind, args, ref = job

    def work(src: Path, out: Path) -> FileResult:
        record = OutputRecord(out, "remove-markers", {})
        try:
            if kind == "image":
                failed = _images([src], out, _remover(args, ref), 1, args, record)[2]
                if failed:
                    raise _Unreadable(failed[0][1])
                return FileResult({})
            return FileResult({}, _video(src, out, ref, 1, args, record)[2])
        except _Unreadable as exc:
            return FileResult({}, unreadable=str(exc).replace(repr(str(src)), _INPUT))

    return run_in_scratch(name, data, work)
