"""The shipped slip scorer on the real grasps re-encoded with other codecs (needs PyAV for H.264)
or captured otherwise (light, optics, sensor noise).

The real GelSight Mini grasps of ``bench_slip_real.py`` (MPEG-4 part 2, as recorded) are decoded,
re-encoded frame by frame (JPEG) or as one stream (x264, ``tacswitch.sim.capture``), decoded
again, tracked as ``tacswitch slip`` tracks them, and scored by the shipped marker committee.
``--capture``: the decoded frames captured otherwise instead (:data:`CAPTURE`: the exposure
drifting down by 30 % over the clip, the white balance drifting by 15 % a channel, a light that
flickers by 6 % from frame to frame, an optical blur of 1.5 px, sensor noise of 2, 4 or 8 grey
levels).
The committee was trained on these experiments as recorded, so the rows measure what a codec or
the capture does to the same decisions, not accuracy on new objects.

    python benches/bench_slip_codecs.py [--data DIR] [--codecs jpeg50 h264-23 h264-30]
        [--capture exposure-drift white-balance flicker blur noise]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np
from bench_slip_real import CACHE, DEFAULT_DATA, shipped_committee_as_recorded

from tacswitch.grasp.crossval import clip_flags
from tacswitch.grasp.dataset import (
    MARKER_TRACKS_TAG,
    TrackedClip,
    load_clip,
    read_video,
    save_clip,
    track_clip,
)
from tacswitch.grasp.evaluate import format_scores, score_experiments

CODECS = {"jpeg50": "JPEG quality 50, every frame", "h264-23": "H.264 CRF 23 (x264's default)",
          "h264-30": "H.264 CRF 30 (small files)"}


CAPTURE = {"exposure-drift": "exposure drifting down by 30 % over the clip",
           "white-balance": "white balance drifting (blue -15 %, red +15 % over the clip)",
           "flicker": "light flickering by 6 % from frame to frame",
           "blur": "optical blur (Gaussian, sigma 1.5 px)",
           "noise": "sensor noise (Gaussian, sigma 4 grey levels, every pixel and channel)",
           "noise-2": "sensor noise (Gaussian, sigma 2 grey levels)",
           "noise-8": "sensor noise (Gaussian, sigma 8 grey levels)"}
#: Sensor noise of each noise case, grey levels.
NOISE_SIGMA = {"noise": 4.0, "noise-2": 2.0, "noise-8": 8.0}


def captured(frames: list[np.ndarray], how: str) -> list[np.ndarray]:
    """``frames`` (BGR uint8) as another capture (:data:`CAPTURE`) records them: a gain per
    frame (and per channel for the white balance), a blur, or noise (seeded by the frame
    number), rounded and clipped to uint8."""
    import cv2

    n = max(len(frames) - 1, 1)
    out = []
    for t, f in enumerate(frames):
        x = f.astype(np.float32)
        if how == "exposure-drift":
            x *= np.float32(1.0 - 0.3 * t / n)
        elif how == "white-balance":
            x *= np.array([1.0 - 0.15 * t / n, 1.0, 1.0 + 0.15 * t / n], np.float32)
        elif how == "flicker":  # mains light beating with the shutter, 0.37 cycles a frame
            x *= np.float32(1.0 + 0.06 * np.sin(2 * np.pi * 0.37 * t))
        elif how == "blur":
            x = cv2.GaussianBlur(x, (0, 0), 1.5)
        elif how in NOISE_SIGMA:
            x += np.random.default_rng(t).normal(0.0, NOISE_SIGMA[how], x.shape).astype(np.float32)
        else:
            raise ValueError(f"how: one of {sorted(CAPTURE)}; got {how!r}")
        out.append(np.clip(np.rint(x), 0, 255).astype(np.uint8))
    return out


def reencoded_clip(job: tuple[Path, str]) -> TrackedClip:
    """The tracked clip of ``video`` re-encoded with ``codec``, or captured as one of
    :data:`CAPTURE` (cached under the bench cache)."""
    from tacswitch.sim.capture import h264_roundtrip, jpeg_roundtrip

    video, codec = job
    # The tracking rules' version in the name: tracks of an older rest frame are made again.
    name = (f"{video.parent.parent.name}__{video.parent.name}__{video.stem}__{codec}__"
            f"{MARKER_TRACKS_TAG}.npz")
    key = CACHE / "codecs" / name
    if key.is_file():
        with np.load(key) as z:
            current = "rest" in z.files  # older files lack the rest frame: tracked again
        if current:
            return load_clip(key)
    frames = list(read_video(video))
    if codec in CAPTURE:
        frames = captured(frames, codec)
    elif codec.startswith("jpeg"):
        frames = [jpeg_roundtrip(f, int(codec[4:])) for f in frames]
    else:
        frames = list(h264_roundtrip(np.stack(frames), int(codec.split("-")[1])))
    clip = track_clip(iter(frames))
    save_clip(key, clip)
    return clip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--codecs", nargs="*", choices=sorted(CODECS), default=list(CODECS))
    ap.add_argument("--capture", nargs="*", choices=sorted(CAPTURE), default=list(CAPTURE))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-still-filter", action="store_true",
                    help="score the tracks as tracked (the committee's rows before 2026-11-29, "
                         "sixteenth stop: no still-marker filter)")
    a = ap.parse_args()
    still = False if a.no_still_filter else None  # None: as the scorer's metadata says (on)
    exps, labels, clips, _ = shipped_committee_as_recorded(
        a.data, a.workers, "MPEG-4 as recorded", "as recorded (MPEG-4)", still_filter=still)
    for codec in [*a.codecs, *a.capture]:
        jobs = [(v, codec) for e in exps for v in e.videos]
        with get_context("spawn").Pool(a.workers) as pool:
            flat = pool.map(reencoded_clip, jobs, chunksize=4)
        it = iter(flat)
        # Frame rate as recorded: the re-encoding keeps every frame.
        recoded = [[replace(next(it), fps=c.fps) for c in exp] for exp in clips]
        flags = [[clip_flags(c, model="markers", still_filter=still) for c in exp]
                 for exp in recoded]
        name = (f"captured: {CAPTURE[codec]}" if codec in CAPTURE
                else f"re-encoded: {CODECS[codec]}")
        print(format_scores(name, score_experiments(labels, flags)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
