"""``tacswitch bench``: the speed/accuracy table (Markdown) and plot (PNG) of marker removal."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="speed/accuracy table and plot of every marker-removal method and knob",
        description="Renders simulated contacts whose markerless truth is known, runs every "
        "marker-removal method at every setting (TELEA radius 3-12, ours and OpenCV's, on one "
        "thread; OpenCV NS; TacDiff at K sampler steps and the hybrid mode, onnxruntime on all "
        "cores) and writes bench.md and bench.png.",
    )
    p.add_argument("-o", "--out", default="tacswitch-bench", help="output folder")
    p.add_argument("--frames", type=int, default=6, help="simulated frames (default: 6)")
    p.add_argument("--preset", default="gelsight", help="sensor preset (default: gelsight)")
    p.add_argument("--radii", default="3,5,8,12", help="inpainting radii (default: 3,5,8,12)")
    p.add_argument("--rounds", type=int, default=3, help="timing rounds (default: 3)")
    p.add_argument("--steps", default="1,2,4,8,20",
                   help="TacDiff sampler steps K (default: 1,2,4,8,20; empty: no TacDiff rows)")
    p.add_argument("--model", default=None, help="TacDiff ONNX model (default: the shipped one)")
    p.add_argument("--real", type=int, default=1,
                   help="real GelSight presses with painted, captured markers (the real-frame "
                   "proxy; needs the taxim package): a second table and bench_real.png "
                   "(default: 1, x 7 style/capture cases; 0: none)")
    p.add_argument("--quick", action="store_true",
                   help="2 frames, radii 3 and 12 (the default), 1 round, 2 real-frame cases")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    p.set_defaults(run=run)


def _missing_for_real(cases: tuple[tuple[str, str], ...]) -> list[str]:
    """The packages the real-frame proxy of ``cases`` needs that are not installed: taxim
    (its real presses), PyAV for an H.264 capture."""
    from importlib.util import find_spec

    def absent(name: str) -> bool:
        try:
            return find_spec(name) is None
        except (ImportError, ValueError):  # a broken or blocked package counts as absent
            return True

    missing = ["the taxim package"] if absent("taxim") else []
    if any(capture == "h264" for _, capture in cases) and absent("av"):
        missing.append("PyAV (av)")
    return missing


def run(args: argparse.Namespace) -> int:
    import os

    os.environ.setdefault("RAYON_NUM_THREADS", "1")
    import cv2

    from tacswitch import tradeoff
    from tacswitch._io import atomic_open, write_image
    from tacswitch.cli.options import UsageError, output_dir, preset_option
    from tacswitch.cli.progress import warn
    from tacswitch.inpaint import DEFAULT_RADIUS

    cv2.setNumThreads(1)
    try:
        radii = [int(r) for r in args.radii.split(",") if r.strip()]
    except ValueError:
        raise UsageError(f"--radii: expected integers like 3,5,8; got {args.radii!r}") from None
    frames, rounds = args.frames, args.rounds
    cases = tradeoff.PROXY_CASES
    if args.quick:
        # r=3 (OpenCV's customary radius) and remove_markers' default.
        frames, rounds, radii, args.steps = 2, 1, [3, DEFAULT_RADIUS], "1,2"
        cases = tradeoff.PROXY_QUICK_CASES
    try:
        steps = [int(k) for k in args.steps.split(",") if k.strip()]
    except ValueError:
        raise UsageError(f"--steps: expected integers like 1,2,4; got {args.steps!r}") from None
    for flag, bad in (("--frames", frames < 1), ("--rounds", rounds < 1),
                      ("--radii", not radii or min(radii) < 1),
                      ("--steps", min(steps, default=1) < 1), ("--real", args.real < 0)):
        if bad:
            raise UsageError(f"{flag}: must be {'>= 0' if flag == '--real' else 'positive'}")
    preset_option(args.preset)
    out = output_dir(args.out, "--out")
    # Checked before any work: the base install lacks what the real-frame table needs.
    missing = _missing_for_real(cases) if args.real else []
    if missing:
        warn("bench", f"--real: skipped the real-frame table: it needs {' and '.join(missing)} "
             "(pip install 'tacswitch[test,train]'); --real 0 runs without it")
        args.real = 0
    data = tradeoff.simulated_frames(frames, args.preset)
    methods = tradeoff.default_methods(radii)
    if steps:
        methods |= tradeoff.tacdiff_methods(steps, hybrid_steps=steps[1:2] or steps[:1],
                                            model=args.model)
    rows = tradeoff.evaluate(data, methods, rounds=rounds)
    real_rows = []
    if args.real:
        # The real-frame proxy: every frame is scored over the true marker footprint with the
        # mask remove_markers builds; one timing round (the simulated table times the knobs).
        real = tradeoff.proxy_frames(args.real, cases=cases)
        real_rows = tradeoff.evaluate(real, methods, rounds=1)
    h, w = data[0].truth.shape[:2]
    table = tradeoff.markdown(rows)
    real_table = tradeoff.markdown(real_rows) if real_rows else ""
    with atomic_open(out / "bench.md") as fh:
        fh.write(f"# Marker removal: speed vs accuracy\n\n{frames} simulated {args.preset} "
                 f"contacts ({w}x{h}), mask = true markers dilated once; TELEA and NS on one "
                 f"thread, TacDiff on all cores (onnxruntime).\n\n{table}\n\n")
        if real_rows:
            fh.write(f"## Real frames with painted markers (real-frame proxy)\n\n{args.real} "
                     f"of Taxim's real GelSight presses (640x480) x {len(cases)} marker "
                     "styles/captures (crisp; soft black and grey dots lossless, MJPEG q75, "
                     "H.264 CRF 26), mask = the one remove_markers builds, error over the "
                     f"true marker footprint; plot: bench_real.png.\n\n{real_table}\n\n")
        fh.write(f"Command: `tacswitch bench --frames {frames} --preset "
                 f"{args.preset} --radii {','.join(map(str, radii))} --rounds {rounds} "
                 f"--steps {','.join(map(str, steps))} --real {args.real}"
                 f"{' --quick' if args.quick else ''}`\n")
    write_image(out / "bench.png", tradeoff.plot(rows))
    if real_rows:
        write_image(out / "bench_real.png", tradeoff.plot(real_rows))
    if not args.quiet:
        print(table)
        if real_rows:
            print("\nReal frames with painted markers:\n" + real_table)
    print(out / "bench.md")
    return 0
