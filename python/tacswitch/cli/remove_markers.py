"""``tacswitch remove-markers``: markerless images from marker images (files or folders)."""

from __future__ import annotations

import argparse
from pathlib import Path

from tacswitch.cli.sources import collect_images


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "remove-markers",
        help="remove the painted markers from images",
        description="Extracts each image's markers, dilates the mask once (as the paper) and "
        "inpaints it. Outputs keep the input file names; existing outputs are skipped, so an "
        "interrupted run resumes. Writes are atomic.",
    )
    p.add_argument("inputs", nargs="+", help="image files or folders")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--method", choices=("telea", "ns", "tacdiff", "hybrid"), default="telea",
                   help="telea (fast, default), ns (OpenCV), tacdiff (diffusion model), hybrid "
                        "(tacdiff near the contact, telea elsewhere)")
    p.add_argument("--radius", type=int, default=3, help="inpainting radius, px (default: 3)")
    p.add_argument("--steps", type=int, default=None,
                   help="tacdiff/hybrid sampler steps K (default: 1)")
    p.add_argument("--ref", default=None,
                   help="hybrid: no-contact frame of the sensor to find the contact against")
    p.add_argument("--model", default=None, help="tacdiff/hybrid ONNX model (default: shipped)")
    p.add_argument("--overwrite", action="store_true", help="redo existing outputs")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import tacswitch as ts
    from tacswitch._io import read_image, write_image

    files = collect_images(args.inputs)
    out = Path(args.out)
    ref = read_image(args.ref) if args.ref is not None else None
    opts = {"steps": args.steps, "ref": ref, "model": args.model} \
        if args.method in ("tacdiff", "hybrid") else {}
    done = skipped = 0
    for path in files:
        target = out / f"{path.stem}.png"
        if target.exists() and not args.overwrite:
            skipped += 1
            continue
        img = read_image(path)
        write_image(target, ts.remove_markers(img, method=args.method, radius=args.radius,
                                              **opts))
        done += 1
        if not args.quiet:
            print(f"{path} -> {target}")
    if not args.quiet:
        print(f"{done} written, {skipped} already done, in {out}")
    return 0
