"""The shipped slip scorer on the real grasps re-encoded with other codecs (needs PyAV for H.264).

The real GelSight Mini grasps of ``bench_slip_real.py`` (MPEG-4 part 2, as recorded) are decoded,
re-encoded frame by frame (JPEG) or as one stream (x264, ``tacswitch.sim.capture``), decoded
again, tracked as ``tacswitch slip`` tracks them, and scored by the shipped marker committee. The
committee was trained on these experiments as recorded, so the rows measure what a codec does
to the same decisions, not accuracy on new objects.

    python benches/bench_slip_codecs.py [--data DIR] [--codecs jpeg50 h264-23 h264-30]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from bench_slip_real import CACHE, DEFAULT_DATA

from tacswitch.grasp.crossval import clip_flags
from tacswitch.grasp.dataset import (
    TrackedClip,
    experiment_clips,
    load_clip,
    read_labels,
    read_video,
    save_clip,
    track_clip,
)
from tacswitch.grasp.evaluate import TABLE_HEADER, format_scores, score_experiments

CODECS = {"jpeg50": "JPEG quality 50, every frame", "h264-23": "H.264 CRF 23 (x264's default)",
          "h264-30": "H.264 CRF 30 (small files)"}


def reencoded_clip(job: tuple[Path, str]) -> TrackedClip:
    """The tracked clip of ``video`` re-encoded with ``codec`` (cached under the bench cache)."""
    from tacswitch.sim.capture import h264_roundtrip, jpeg_roundtrip

    video, codec = job
    name = f"{video.parent.parent.name}__{video.parent.name}__{video.stem}__{codec}.npz"
    key = CACHE / "codecs" / name
    if key.is_file():
        return load_clip(key)
    frames = list(read_video(video))
    if codec.startswith("jpeg"):
        frames = [jpeg_roundtrip(f, int(codec[4:])) for f in frames]
    else:
        frames = list(h264_roundtrip(np.stack(frames), int(codec.split("-")[1])))
    clip = track_clip(iter(frames))
    save_clip(key, clip)
    return clip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--codecs", nargs="+", choices=sorted(CODECS), default=list(CODECS))
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    exps = read_labels(a.data)
    labels = [e.slip for e in exps]
    clips = experiment_clips(exps, CACHE, workers=a.workers)
    print(f"REAL GelSight Mini grasps (MPEG-4 as recorded): {len(exps)} experiments, "
          f"{len({e.object for e in exps})} objects, {sum(labels)} slip; the shipped marker "
          "committee (trained on them as recorded); an experiment is slip when any frame of "
          "either finger is flagged.\n")
    print(TABLE_HEADER)
    flags = [[clip_flags(c, model="markers") for c in exp] for exp in clips]
    print(format_scores("as recorded (MPEG-4)", score_experiments(labels, flags)), flush=True)
    for codec in a.codecs:
        jobs = [(v, codec) for e in exps for v in e.videos]
        with get_context("spawn").Pool(a.workers) as pool:
            flat = pool.map(reencoded_clip, jobs, chunksize=4)
        it = iter(flat)
        # Frame rate as recorded: the re-encoding keeps every frame.
        recoded = [[replace(next(it), fps=c.fps) for c in exp] for exp in clips]
        flags = [[clip_flags(c, model="markers") for c in exp] for exp in recoded]
        print(format_scores(f"re-encoded: {CODECS[codec]}", score_experiments(labels, flags)),
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
