"""``tacswitch simulate``: write a synthetic paired dataset (PNGs + one JSONL manifest)."""

from __future__ import annotations

import argparse
import os


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate", help="generate a synthetic tactile dataset (paired I_w/I_wo, labels)",
        description="Renders samples (or grasp sequences) with tacswitch.sim and writes PNGs plus "
                    "manifest.jsonl. Deterministic by --seed, independent of --workers; rerunning "
                    "into the same folder skips finished items.")
    p.add_argument("--preset", default="gelsight",
                   help="sensor preset: gelsight, gelsight_mini, digit, dense "
                        "(default: %(default)s)")
    from tacswitch.cli.options import count

    p.add_argument("--n", type=count, default=100,
                   help="samples or sequences (default: %(default)s)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--seed", type=count, default=0,
                   help="dataset seed, a whole number >= 0 (default: %(default)s)")
    p.add_argument("--sequences", action="store_true",
                   help="grasp sequences (press, shear, hold/slip/vibration) instead of samples")
    p.add_argument("--frames", type=int, default=None,
                   help="frames per sequence, with --sequences (default: 30)")
    p.add_argument("--optics", choices=("auto", "taxim", "phong"), default="auto",
                   help="shading: taxim (the real calibration; needs one in the preset), phong, "
                        "or auto (taxim when the preset has a calibration; default)")
    p.add_argument("--vary-grid", action="store_true",
                   help="draw the marker grid per sample (6x8 to 10x14) instead of the preset's")
    p.add_argument("--jpeg", type=int, default=None, metavar="Q",
                   help="JPEG-compress frames at quality Q (PNG files, JPEG artefacts)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes (default: all cores); results do not depend on it")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from tacswitch._checks import as_jpeg_quality
    from tacswitch.cli.options import UsageError, output_dir, preset_option
    from tacswitch.cli.progress import stderr_is_terminal
    from tacswitch.sim.dataset import generate_dataset

    preset_option(args.preset)
    if args.frames is not None and not args.sequences:
        raise UsageError("--frames: applies to --sequences only (samples are single frames)")
    if args.frames is None:
        args.frames = 30
    if args.frames < 1:
        raise UsageError(f"--frames: must be >= 1; got {args.frames}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers: must be >= 1; got {args.workers}")
    try:
        as_jpeg_quality(args.jpeg, "--jpeg")
    except (TypeError, ValueError) as e:
        raise UsageError(str(e)) from None
    output_dir(args.out, "--out")
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)
    options = {"optics": args.optics, "vary_grid": bool(args.vary_grid),
               "jpeg_quality": args.jpeg}
    if args.sequences:
        options["frames"] = args.frames
    summary = generate_dataset(args.out, preset=args.preset, n=args.n, seed=args.seed,
                               sequences=args.sequences, workers=workers,
                               # A bar redrawn with carriage returns only on a terminal,
                               # never into a log file.
                               progress=not args.quiet and stderr_is_terminal(),
                               options=options)
    if not args.quiet:
        print(f"{args.out}: {summary['generated']} generated, {summary['skipped']} already there, "
              f"{summary['items_per_s']:.2f} items/s with {workers} worker(s)")
    return 0
