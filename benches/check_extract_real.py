"""Markers found per frame on every video of the real GelSight Mini slip training split.

For each video (``../shared/data/real/gsmini_slip_train/<object>/<exp>/camera_*.avi``), counts
the markers :func:`tacswitch.extract_markers` finds (defaults) on every ``--step``-th frame
(frame 0 always included) and reports the frames where the count drops below 90 % of the clip's
median. Run it once per build and compare (issue #35: textured objects in contact):

    python benches/check_extract_real.py --out /tmp/before.json      # old build
    python benches/check_extract_real.py --out /tmp/after.json       # new build
    python benches/check_extract_real.py --compare /tmp/before.json /tmp/after.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2] / "shared"
TRAIN = SHARED / "data" / "real" / "gsmini_slip_train"
DROP = 0.9


def count_video(path: Path, step: int) -> dict[str, int]:
    import cv2

    import tacswitch as ts

    cap = cv2.VideoCapture(str(path))
    counts: dict[str, int] = {}
    i = 0
    while cap.grab():
        if i % step == 0:
            ok, img = cap.retrieve()
            if ok:
                counts[str(i)] = len(ts.extract_markers(img))
        i += 1
    cap.release()
    return counts


def summarise(data: dict[str, dict[str, int]]) -> dict[str, object]:
    frames = drops = clips_with_drop = 0
    first, worst = [], []
    for name, counts in sorted(data.items()):
        if not counts:
            continue
        vals = np.array(list(counts.values()))
        med = float(np.median(vals))
        low = [(int(k), v) for k, v in counts.items() if v < DROP * med]
        frames += len(vals)
        drops += len(low)
        clips_with_drop += bool(low)
        first.append(counts.get("0", 0))
        if low:
            worst.append((len(low), name, med, low[:8]))
    worst.sort(reverse=True)
    return {"clips": len(data), "frames": frames, "frames_below_90pct_median": drops,
            "clips_with_a_drop": clips_with_drop,
            "first_frame_markers_min_median": (int(np.min(first)), float(np.median(first))),
            "first_frames_below_30": int(np.sum(np.array(first) < 30)),
            "worst": worst[:10]}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, help="write per-frame counts (JSON) of the installed build")
    ap.add_argument("--step", type=int, default=10, help="every n-th frame (default 10)")
    ap.add_argument("--limit", type=int, default=0, help="first n videos only (smoke test)")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"))
    args = ap.parse_args()
    if args.compare:
        before, after = (json.loads(p.read_text()) for p in args.compare)
        for label, data in (("before", before), ("after", after)):
            s = summarise(data)
            print(f"{label}: " + ", ".join(f"{k} {v}" for k, v in s.items() if k != "worst"))
            for n, name, med, low in s["worst"]:  # type: ignore[union-attr]
                print(f"    {name}: median {med:g}, {n} frames low, e.g. {low}")
        changed = [(k, before[k].get("0"), after[k].get("0")) for k in sorted(before)
                   if k in after and before[k].get("0") != after[k].get("0")]
        print(f"first-frame count changed on {len(changed)} clips:")
        for name, b, a in changed:
            print(f"    {name}: {b} -> {a}")
        return 0
    if not TRAIN.is_dir():
        print(f"no data at {TRAIN}: nothing to check", file=sys.stderr)
        return 0
    videos = sorted(TRAIN.rglob("*.avi"))
    if args.limit:
        videos = videos[: args.limit]
    t0 = time.perf_counter()
    data = {str(v.relative_to(TRAIN)): count_video(v, args.step) for v in videos}
    s = summarise(data)
    print(f"{len(videos)} videos in {time.perf_counter() - t0:.0f} s")
    print(", ".join(f"{k} {v}" for k, v in s.items() if k != "worst"))
    if args.out:
        args.out.write_text(json.dumps(data))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
