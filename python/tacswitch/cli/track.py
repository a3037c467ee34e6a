"""``tacswitch track``: marker motion field per frame of a video or image folder, as CSV."""

from __future__ import annotations

import argparse

from tacswitch.cli.rest_frame import choose_rest_frame
from tacswitch.cli.sources import SkipCount, frame_count, frames


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track",
        help="track markers through a video or image folder (motion per frame, CSV)",
        description="The first usable frame is the reference. Writes one CSV row per frame "
        "and marker: frame, marker, x_ref, y_ref, dx, dy, valid (dx, dy empty when lost). The "
        "file is flushed every frame. The reference skips the frames before the camera "
        "settled (exposure still changing, or stale frames ended by a jump of the whole "
        "image) and a first frame that shows no markers or fewer than half as many as a "
        "frame of the first 30 (said on stderr); the frames before it have no rows.",
    )
    p.add_argument("source", help="video file, folder of images, camera index, or ROS bag "
                                  "(with --topic)")
    from tacswitch.cli.options import positive

    p.add_argument("-o", "--out", default="track.csv",
                   help="CSV output, a .csv file name (default: %(default)s)")
    p.add_argument("--max-dist", type=positive, default=None, metavar="PX",
                   help="per-frame gate in pixels (default: half the marker pitch)")
    p.add_argument("--polarity", choices=("dark", "bright"), default="dark",
                   help="markers darker (painted dots, default) or brighter (pins) than the gel")
    p.add_argument("--max-frames", type=int, default=None, metavar="N",
                   help="stop after the first N frames (default: the whole source)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    from tacswitch.cli.bagio import add_bag_options

    add_bag_options(p, "<topic>/marker_motion (sensor_msgs/PointCloud2: x, y, dx, dy, valid "
                       "per marker)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    import tacswitch as ts
    from tacswitch.cli.options import StreamingCsv, UsageError, csv_output
    from tacswitch.cli.progress import progress, warn

    if args.max_frames is not None and args.max_frames < 1:
        raise UsageError(f"--max-frames: must be >= 1; got {args.max_frames}")
    from tacswitch.cli.bagio import bag_sink, bag_source, motion_fields

    bag = bag_source(args.source, args)
    out = csv_output(args.out, "--out")
    tracker: ts.MarkerTracker | None = None
    n = 0
    skipped = SkipCount()
    k = -1  # index in the stream (bag frames are looked up by it)
    total = (frame_count(args.source, args.max_frames) if bag is None else
             min(len(bag), args.max_frames or len(bag)) or None)
    # Opened at the first row: a source that cannot be read leaves an existing file alone.
    with StreamingCsv(out, ["frame", "marker", "x_ref", "y_ref", "dx", "dy", "valid"]) as log, \
            bag_sink(bag, args) as sink, \
            progress(total=total, desc="track", unit="frame", quiet=args.quiet) as bar:
        rest, stream = choose_rest_frame(
            frames(args.source) if bag is None else bag,
            lambda f: ts.extract_markers(f, polarity=args.polarity).centres,
            source=args.source, max_frames=args.max_frames, hint="; check --polarity")
        if rest is not None and rest.index > 0:
            warn("track", rest.message())
        for frame in stream:
            if args.max_frames is not None and n >= args.max_frames:
                break
            k += 1
            bar.update()
            if frame is None:
                skipped.undecodable()
                continue
            skipped.decoded()
            if tracker is None:
                if rest is not None and n < rest.index:  # before the rest frame: no rows
                    n += 1
                    continue
                tracker = ts.MarkerTracker(frame, args.max_dist, polarity=args.polarity)
            if frame.shape[:2] != tracker.reference_shape:
                skipped.unusable()
                continue
            motion, valid = tracker.update(frame)
            ref = tracker.reference
            for i in range(len(ref)):
                dx, dy = ("", "") if not valid[i] else (f"{motion[i, 0]:.3f}",
                                                         f"{motion[i, 1]:.3f}")
                log.writerow([n, i, f"{ref[i, 0]:.3f}", f"{ref[i, 1]:.3f}", dx, dy,
                              int(valid[i])])
            if sink is not None:
                sink.points(bag.frames[k], motion_fields(ref, motion, valid))
            n += 1
            if n % 50 == 1:
                bar.set_postfix_str(f"{int(np.sum(valid))}/{len(ref)} markers tracked",
                                    refresh=False)
    if n == 0:
        raise ValueError(f"source: no readable frames in {args.source!r}")
    if not args.quiet:
        print(f"{n} frames ({skipped}), {len(tracker or [])} markers "
              f"-> {out}")
    return 0
