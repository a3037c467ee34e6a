"""``tacswitch remove-markers``: markerless images and videos from marker ones."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from tacswitch.cli.sources import VIDEO_SUFFIXES, collect_inputs

#: Methods that run the TacDiff model (onnxruntime already uses every core: run serially).
MODEL_METHODS = ("tacdiff", "hybrid")

Remover = Callable[[np.ndarray], np.ndarray]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "remove-markers",
        help="remove the painted markers from images and videos",
        description="Extracts each frame's markers, dilates the mask twice (it must cover the "
        "markers' soft edges) and "
        "inpaints it. An image becomes OUT/<stem>.png; a video (" + ", ".join(
            sorted(VIDEO_SUFFIXES)) + ") becomes OUT/<stem>.mp4 (mp4v, same size and fps; "
        "frames that do not decode are skipped and counted), or with --frames a folder "
        "OUT/<stem>/ of PNG frames named by frame index. Folders are searched for both. "
        "Existing outputs are skipped, so an interrupted run resumes (a video file is redone, "
        "a --frames folder resumes frame by frame); every write is atomic.",
    )
    p.add_argument("inputs", nargs="+", help="image files, video files or folders of them")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--method", choices=("telea", "biharmonic", "ns", *MODEL_METHODS),
                   default="telea",
                   help="telea (fast, default), biharmonic (smooth fill, better on contact "
                        "shading), ns (OpenCV), tacdiff (diffusion model), hybrid (tacdiff near "
                        "the contact, telea elsewhere)")
    p.add_argument("--radius", type=int, default=3, help="inpainting radius, px (default: 3)")
    p.add_argument("--steps", type=int, default=None,
                   help="tacdiff/hybrid sampler steps K (default: 1)")
    p.add_argument("--ref", default=None,
                   help="hybrid: no-contact frame of the sensor to find the contact against "
                        "(default for a video: its first frame, which should show no contact; "
                        "for images: the contact is found from local texture)")
    p.add_argument("--model", default=None,
                   help="tacdiff/hybrid ONNX model, or 'fast' for the shipped narrow model "
                        "(default: the shipped model)")
    p.add_argument("--frames", action="store_true",
                   help="write a video's frames as PNGs into OUT/<stem>/ instead of a video")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="telea/biharmonic/ns: threads over images and video frames (default: "
                        "all cores); tacdiff/hybrid run one item at a time, onnxruntime uses "
                        "all cores")
    p.add_argument("--overwrite", action="store_true", help="redo existing outputs")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars or messages")
    p.set_defaults(run=run)


def _remover(args: argparse.Namespace, ref: np.ndarray | None) -> Remover:
    import tacswitch as ts

    opts: dict[str, Any] = {}
    if args.method in MODEL_METHODS:
        opts = {"steps": args.steps, "ref": ref, "model": args.model}

    def remove(img: np.ndarray) -> np.ndarray:
        return ts.remove_markers(img, method=args.method, radius=args.radius, **opts)

    return remove


def _read(path: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(f"inputs: cannot read an image from {str(path)!r}")
    return img


def _targets(images: list[Path], videos: list[Path], out: Path, frames: bool) -> None:
    """``ValueError`` if two inputs would write the same output (same stem, same kind), or an
    output would replace its own input."""
    seen: dict[Path, Path] = {}
    named = [(p, out / f"{p.stem}.png") for p in images]
    named += [(p, out / p.stem if frames else out / f"{p.stem}.mp4") for p in videos]
    for path, target in named:
        if target.resolve() == path.resolve():
            raise ValueError(f"--out: writing {str(target)!r} would replace its input; choose "
                             "another output folder")
        if target in seen:
            raise ValueError(f"inputs: {str(seen[target])!r} and {str(path)!r} would both "
                             f"write {str(target)!r}; give them different names")
        seen[target] = path


def run(args: argparse.Namespace) -> int:
    from tacswitch.cli.batch import default_workers
    from tacswitch.cli.progress import say

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers: must be >= 1; got {args.workers}")
    images, videos = collect_inputs(args.inputs)
    out = Path(args.out)
    _targets(images, videos, out, args.frames)
    ref = None
    if args.ref is not None:
        if not Path(args.ref).is_file():
            raise FileNotFoundError(f"--ref: no file at {args.ref!r}")
        ref = _read(Path(args.ref))
    workers = 1 if args.method in MODEL_METHODS else (args.workers or default_workers())
    done, skipped = _images(images, out, _remover(args, ref), workers, args)
    bad = 0
    for path in videos:
        d, s, b = _video(path, out, ref, workers, args)
        done, skipped, bad = done + d, skipped + s, bad + b
    say(f"{done} written, {skipped} already done"
        + (f", {bad} unreadable video frames skipped" if bad else "") + f", in {out}",
        quiet=args.quiet)
    return 0


def _images(images: list[Path], out: Path, remove: Remover, workers: int,
            args: argparse.Namespace) -> tuple[int, int]:
    """Marker removal on image files, ``workers`` at a time; (written, already done)."""
    from tacswitch._io import write_image
    from tacswitch.cli.batch import ordered_map
    from tacswitch.cli.progress import progress, say

    jobs = [(p, out / f"{p.stem}.png") for p in images]
    todo = [(p, t) for p, t in jobs if args.overwrite or not t.exists()]

    def one(job: tuple[Path, Path]) -> tuple[Path, Path]:
        path, target = job
        write_image(target, remove(_read(path)))
        return job

    with progress(total=len(todo), desc="images", unit="img", quiet=args.quiet) as bar, \
            ordered_map(one, todo, workers) as results:
        for path, target in results:
            bar.update()
            say(f"{path} -> {target}", quiet=args.quiet)
    return len(todo), len(jobs) - len(todo)


def _stale_parts(out: Path, stem: str) -> None:
    """Removes temporary files a killed run left for this video (one run per OUT at a time)."""
    import glob

    for part in out.glob(f".{glob.escape(stem)}.*.part.mp4"):
        part.unlink(missing_ok=True)


def _video(path: Path, out: Path, ref: np.ndarray | None, workers: int,
           args: argparse.Namespace) -> tuple[int, int, int]:
    """One video: a markerless ``OUT/<stem>.mp4`` or, with ``--frames``, PNG frames in
    ``OUT/<stem>/``. Returns (outputs written, outputs already done, unreadable frames)."""
    from tacswitch._io import write_image
    from tacswitch.cli.batch import AtomicVideoWriter, ordered_map
    from tacswitch.cli.progress import progress, say
    from tacswitch.cli.sources import video_frames, video_info

    target = out / path.stem if args.frames else out / f"{path.stem}.mp4"
    if not args.frames and target.exists() and not args.overwrite:
        return 0, 1, 0
    fps, count = video_info(path, "inputs")
    remove: Remover | None = None
    quiet = args.quiet

    def items() -> Iterator[tuple[int, np.ndarray | None]]:
        """Decoded frames with their index (on this thread); the remover is made at the first
        readable frame, the reference of a hybrid run without --ref."""
        nonlocal remove
        for i, frame in enumerate(video_frames(path, "inputs")):
            if remove is None and frame is not None:
                first = ref is None and args.method == "hybrid"
                remove = _remover(args, frame.copy() if first else ref)
                if first:
                    say(f"{path}: hybrid reference (no contact) = frame {i}", quiet=quiet)
            yield i, frame

    bar = progress(total=count, desc=path.name, unit="frame", quiet=quiet)
    if args.frames:
        def one(item: tuple[int, np.ndarray | None]) -> str:
            i, frame = item
            if frame is None:
                return "bad"
            png = target / f"{i:06d}.png"
            if png.exists() and not args.overwrite:
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
            raise ValueError(f"inputs: no readable frame in video {str(path)!r}")
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
    with bar, AtomicVideoWriter(target, fps or 30.0) as writer, \
            ordered_map(clean, items(), workers) as cleaned:
        for out_frame in cleaned:
            if out_frame is None or not writer.write(out_frame):
                bad += 1
            bar.update()
        if writer.frames == 0:
            raise ValueError(f"inputs: no readable frame in video {str(path)!r}")
        writer.commit()
    say(f"{path} -> {target} ({writer.frames} frames, {bad} unreadable skipped)", quiet=quiet)
    return 1, 0, bad
