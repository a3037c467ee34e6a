"""What `tacswitch remove-markers` video output loses, per codec, and what slip's grasp start
changes on press recordings. Simulated data only (``tacswitch.sim``); prints a Markdown table.

    python benches/bench_cli_video.py [--frames 30] [--seeds 4] [--update]

1. Video codecs: a rendered grasp (GelSight preset, 640x480, lossless FFV1 input) through the
   command with ``--codec mp4v`` (default) and ``--codec ffv1``; decoded frames against the
   in-memory ``remove_markers`` result (mean / max absolute difference, grey levels) and bytes
   per frame.
2. Grasp start: rendered press recordings (a no-contact lead-in, press, shear, hold, release;
   GelSight Mini preset) through ``tacswitch slip`` with the detected start and with
   ``--start 0`` (the old behaviour), by the learned detector (the default) and the paper's
   rule; frames flagged as slip during the lead-in, loading and hold, after the release
   (all false alarms: these grasps never slip), and in all.
"""

from __future__ import annotations

import argparse
import csv
import tempfile
from pathlib import Path

import cv2
import numpy as np

import tacswitch as ts
from tacswitch import sim
from tacswitch.cli import main


def decode(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        out.append(frame)
    cap.release()
    return out


def codecs(n_frames: int) -> list[str]:
    seq = sim.grasp_sequence("gelsight", "slip", n_frames=n_frames, seed=0)
    frames = [seq.reference, *seq.frames]
    rows = ["| codec | lossless | mean abs diff (grey) | max abs diff | kB per frame |",
            "|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "rec.mkv"
        h, w = frames[0].shape[:2]
        writer = cv2.VideoWriter(str(src), cv2.VideoWriter.fourcc(*"FFV1"), 30, (w, h))
        for f in frames:
            writer.write(f)
        writer.release()
        expected = [ts.remove_markers(f) for f in frames]
        for codec, suffix in (("mp4v", ".mp4"), ("ffv1", ".mkv")):
            out = Path(tmp) / codec
            assert main(["remove-markers", str(src), "-o", str(out), "--codec", codec,
                         "-q"]) == 0
            got = decode(out / f"rec{suffix}")
            assert len(got) == len(expected)
            diff = np.stack([np.abs(a.astype(np.int16) - b) for a, b in zip(got, expected,
                                                                              strict=True)])
            size = (out / f"rec{suffix}").stat().st_size / len(got) / 1e3
            rows.append(f"| {codec} | {'yes' if diff.max() == 0 else 'no'} | "
                        f"{diff.mean():.2f} | {diff.max()} | {size:.0f} |")
    return rows


def grasp_start(seeds: int) -> list[str]:
    rows = ["| detector, grasp start | frames | flagged before the hold ends | flagged after "
            "the release | flagged in all |", "|---|---|---|---|---|"]
    lead = 4
    runs = {"learned rule (default), detected start": [],
            "paper rule, detected start": ["--rule", "paper"],
            "paper rule, --start 0": ["--rule", "paper", "--start", "0"]}
    totals = {name: [0, 0, 0, 0] for name in runs}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=30, seed=seed)
            frames = ([seq.reference] * lead + list(seq.frames)
                      + list(seq.frames[: seq.grasp_start][::-1]) + [seq.reference] * 3)
            folder = Path(tmp) / f"rec{seed}"
            folder.mkdir()
            for i, f in enumerate(frames):
                cv2.imwrite(str(folder / f"{i:04d}.png"), f)
            hold_end = lead + len(seq.frames)
            release = lead + len(seq.frames) + seq.grasp_start
            for name, extra in runs.items():
                log = Path(tmp) / "log.csv"
                assert main(["slip", str(folder), "--log", str(log), "-q", *extra]) == 0
                with open(log) as fh:
                    flagged = [int(r["frame"]) for r in csv.DictReader(fh) if r["slip"] == "1"]
                t = totals[name]
                t[0] += len(frames)
                t[1] += sum(1 for f in flagged if f < hold_end)
                t[2] += sum(1 for f in flagged if f >= release)
                t[3] += len(flagged)
    for name, (n, early, after, flagged) in totals.items():
        rows.append(f"| {name} | {n} | {early} ({100 * early / n:.0f} %) | {after} | "
                    f"{flagged} ({100 * flagged / n:.0f} %) |")
    return rows


SECTION = "## Command line: video output and grasp start"


def run() -> None:
    from harness import update_markdown

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--seeds", type=int, default=4)
    p.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = p.parse_args()
    import datetime

    from harness import machine

    body = "\n".join([
        f"Data: **simulated**. Measured {datetime.date.today()}; {machine()}.", "",
        f"`tacswitch remove-markers` video output (simulated GelSight 640x480, "
        f"{args.frames + 1} frames), decoded frames against the in-memory result:", "",
        *codecs(args.frames), "",
        f"`tacswitch slip` on {args.seeds} simulated press recordings (GelSight Mini, no slip: "
        "4 no-contact frames, press, shear, hold, release in reverse, 3 no-contact frames); "
        "every flagged frame is a false alarm. The learned detector (the default) runs only "
        "while the markers show a contact and flags nothing; with the paper's rule the "
        "detected start leaves the release, where the markers move back, as the only flagged "
        "frames:", "",
        *grasp_start(args.seeds), "",
        f"Command: `python benches/bench_cli_video.py --frames {args.frames} --seeds "
        f"{args.seeds}`",
    ])
    print(body)
    if args.update:
        update_markdown(SECTION, body)


if __name__ == "__main__":
    run()
