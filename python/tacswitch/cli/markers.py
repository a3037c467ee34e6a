"""``tacswitch markers``: extract markers from images, write centres (CSV/JSON) and overlays."""

from __future__ import annotations

import argparse
import csv
import io
import json
from pathlib import Path

from tacswitch.cli.sources import collect_images


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("markers", help="extract markers from images (CSV/JSON + overlay)",
                       description="Extracts markers from image files or folders of images.")
    p.add_argument("inputs", nargs="+", help="image files or folders")
    p.add_argument("-o", "--out", default="markers-out",
                   help="output folder (default: %(default)s)")
    p.add_argument("--format", choices=("csv", "json"), default="csv")
    p.add_argument("--overlay", action="store_true", help="also write an overlay PNG per image")
    p.add_argument("--polarity", choices=("dark", "bright"), default="dark")
    p.add_argument("--threshold", type=float, default=None,
                   help="darkness threshold in grey levels (default: chosen per image)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or messages")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import tacswitch as ts
    from tacswitch import viz
    from tacswitch._io import atomic_open, read_image, write_image
    from tacswitch.cli.progress import progress, say

    out = Path(args.out)
    files = collect_images(args.inputs)
    with progress(files, desc="markers", unit="img", quiet=args.quiet) as bar:
        for path in bar:
            img = read_image(path)
            m = ts.extract_markers(img, polarity=args.polarity, threshold=args.threshold)
            rows = [
                {"x": round(float(c[0]), 3), "y": round(float(c[1]), 3), "area": int(a),
                 "bx": int(b[0]), "by": int(b[1]), "bw": int(b[2]), "bh": int(b[3]),
                 "contrast": round(float(k), 4)}
                for c, a, b, k in zip(m.centres, m.areas, m.bboxes, m.contrast, strict=True)
            ]
            target = out / f"{path.stem}.{args.format}"
            with atomic_open(target) as fh:
                if args.format == "json":
                    json.dump({"image": str(path), "threshold": m.threshold, "markers": rows}, fh,
                              indent=1)
                else:
                    buf = io.StringIO()
                    writer = csv.DictWriter(buf, fieldnames=list(rows[0]) if rows else ["x", "y"])
                    writer.writeheader()
                    writer.writerows(rows)
                    fh.write(buf.getvalue())
            if args.overlay:
                write_image(out / f"{path.stem}_markers.png", viz.draw_markers(img, m.centres))
            say(f"{path}: {len(m)} markers -> {target}", quiet=args.quiet)
    return 0
