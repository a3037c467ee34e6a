"""``tacswitch markers``: extract markers from images and videos, write centres (CSV/JSON) and
overlays."""

from __future__ import annotations

import argparse
import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from tacswitch.cli.options import UsageError
from tacswitch.cli.sources import VIDEO_SUFFIXES, collect_inputs


def add_parser(sub: argparse._SubParsersAction) -> None:
    from tacswitch.cli.options import add_extraction_options

    p = sub.add_parser(
        "markers", help="extract markers from images and videos (CSV/JSON + overlay)",
        description="Extracts the markers of image files, of one frame of each video ("
        + ", ".join(sorted(VIDEO_SUFFIXES)) + "; the first frame by default, --frame N "
        "otherwise: on a recording that starts without contact these are the rest centres "
        "`tacswitch motion --centres` takes), or of the images and videos found in folders. "
        "Writes OUT/<stem>.csv (x, y, area, bounding box, contrast; or .json) per input. "
        "Unreadable files are skipped, counted and named in a warning on stderr.",
        epilog="Exit status: 0 when every readable input is done, 1 when no input could be "
        "read, 2 for an unusable option value (e.g. --out under a file).")
    p.add_argument("inputs", nargs="+", help="image files, video files or folders of them")
    p.add_argument("-o", "--out", default="markers-out",
                   help="output folder (default: %(default)s)")
    p.add_argument("--format", choices=("csv", "json"), default="csv",
                   help="output file format (default: %(default)s)")
    p.add_argument("--overlay", action="store_true", help="also write an overlay PNG per input")
    p.add_argument("--frame", type=int, default=0, metavar="N",
                   help="videos: the frame to extract from (0 = first, default)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar or messages (warnings still go to stderr)")
    add_extraction_options(p, border_default="exclude", dilate=False)
    from tacswitch.cli.bagio import add_bag_options

    add_bag_options(p, "every frame's markers on <topic>/markers (sensor_msgs/PointCloud2: x, "
                       "y, area, contrast); a bag is read as a video (--frame N for the CSV)")
    p.set_defaults(run=run)


def video_frame(path: Path, index: int) -> np.ndarray:
    """Frame ``index`` (0-based, counting undecodable frames) of a video; ``ValueError`` naming
    ``inputs`` if the video cannot be decoded, or ``--frame`` if it is shorter or that frame
    does not decode."""
    from tacswitch.cli.sources import video_frames

    n = 0
    for i, frame in enumerate(video_frames(path, "inputs")):
        n = i + 1
        if i == index:
            if frame is None:
                raise ValueError(f"--frame: frame {index} of {str(path)!r} does not decode")
            return frame
    raise ValueError(f"--frame: {str(path)!r} has {n} frames; frame {index} does not exist")


def _rows(m: Any) -> list[dict[str, Any]]:
    return [
        {"x": round(float(c[0]), 3), "y": round(float(c[1]), 3), "area": int(a),
         "bx": int(b[0]), "by": int(b[1]), "bw": int(b[2]), "bh": int(b[3]),
         "contrast": round(float(k), 4)}
        for c, a, b, k in zip(m.centres, m.areas, m.bboxes, m.contrast, strict=True)
    ]


def run(args: argparse.Namespace) -> int:
    import tacswitch as ts
    from tacswitch import viz
    from tacswitch._io import write_image
    from tacswitch.cli.options import UsageError, extraction_options, output_dir
    from tacswitch.cli.progress import progress, say, warn
    from tacswitch.cli.sources import check_distinct_outputs, read_quiet, report_unreadable

    if args.frame < 0:
        raise UsageError(f"--frame: must be >= 0; got {args.frame}")
    from tacswitch.cli.bagio import only_bag

    bag = only_bag(args.inputs, args)
    if bag is not None:
        return _bag(bag, args)
    images, videos = collect_inputs(args.inputs)
    out = output_dir(args.out, "--out")
    opts = extraction_options(args)
    inputs = [(p, False) for p in images] + [(p, True) for p in videos]
    check_distinct_outputs([(p, out / f"{p.stem}.{args.format}") for p, _ in inputs])
    failed: list[tuple[Path, str]] = []
    done = 0
    with progress(inputs, desc="markers", unit="file", quiet=args.quiet) as bar:
        for path, is_video in bar:
            img: np.ndarray | None
            if is_video:
                try:
                    img = video_frame(path, args.frame)
                except ValueError as exc:
                    failed.append((path, str(exc)))
                    continue
                source = f"{path} (frame {args.frame})"
            else:
                img = read_quiet(path)
                if img is None:
                    failed.append((path, f"inputs: cannot read an image from {str(path)!r}"))
                    continue
                source = str(path)
            m = ts.extract_markers(img, **opts)
            target = out / f"{path.stem}.{args.format}"
            record: dict[str, Any] = {"image": str(path)}
            if is_video:
                record["frame"] = args.frame
            _write(target, m, record, args.format)
            if args.overlay:
                write_image(out / f"{path.stem}_markers.png", viz.draw_markers(img, m.centres))
            done += 1
            say(f"{source}: {len(m)} markers -> {target}", quiet=args.quiet)
            if len(m) == 0:
                warn("markers", f"no markers found in {source}; check --polarity and "
                     "--threshold")
    report_unreadable("markers", failed, done)
    return 0


def _write(target: Path, m: Any, record: dict[str, Any], fmt: str) -> None:
    """The markers ``m`` as CSV or JSON (``record``: the JSON's leading fields)."""
    from tacswitch._io import atomic_open

    rows = _rows(m)
    with atomic_open(target) as fh:
        if fmt == "json":
            json.dump(record | {"threshold": m.threshold, "markers": rows}, fh, indent=1)
        else:
            buf = io.StringIO()
            writer = csv.DictWriter(buf, fieldnames=list(rows[0]) if rows else ["x", "y"])
            writer.writeheader()
            writer.writerows(rows)
            fh.write(buf.getvalue())


def _bag(src: Any, args: argparse.Namespace) -> int:
    """A ROS bag: frame ``--frame`` of the topic to ``OUT/<stem>.csv`` (as a video), and with
    ``--out-bag`` every frame's markers on ``<topic>/markers``."""
    import tacswitch as ts
    from tacswitch.cli.bagio import bag_sink
    from tacswitch.cli.options import extraction_options, output_dir
    from tacswitch.cli.progress import progress, say

    out = output_dir(args.out, "--out")
    opts = extraction_options(args)
    wrote = None
    with bag_sink(src, args) as sink, \
            progress(total=len(src) or None, desc="markers", unit="frame",
                     quiet=args.quiet or sink is None) as bar:
        for i, frame in enumerate(src):
            bar.update()
            if sink is None and i > args.frame:
                break
            if frame is None:
                continue
            m = ts.extract_markers(frame, **opts)
            if sink is not None:
                sink.points(src.frames[i], {"x": m.centres[:, 0], "y": m.centres[:, 1],
                                            "area": m.areas, "contrast": m.contrast},
                            suffix="markers")
            if i == args.frame:
                wrote = out / f"{src.path.stem}.{args.format}"
                _write(wrote, m, {"bag": str(src.path), "topic": src.topic, "frame": i},
                       args.format)
                say(f"{src.path} {src.topic} (frame {i}): {len(m)} markers -> {wrote}",
                    quiet=args.quiet)
    if wrote is None:
        raise UsageError(f"--frame: {src.topic} in {str(src.path)!r} has no readable frame "
                         f"{args.frame}")
    return 0
