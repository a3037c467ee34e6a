"""The shipped slip scorer at other frame rates: resampling to its time base, against none.

The learned slip rule's cues (marker velocities over 1 and 4 frames, accelerations, 8-frame
windows) and the grasp phases' frame counts were learned at 25 frames/s, the rate of the real
GelSight Mini grasps. A sensor filmed at another rate moves its markers farther or less far per
frame. ``GraspSlipDetector(fps=...)`` (``tacswitch slip --fps``, a video's stated rate by
default) resamples a faster stream to 25 frames/s first and reads a slower one frame by frame
(``tacswitch.grasp.timebase``); each rate is scored both ways.

Data: the real GelSight Mini grasps of ``bench_slip_real.py`` (150 experiments, 29 objects, 65
slip; tracks cached under ``bench-results/slip_real``), played at other rates:

- slower (8.3, 12.5, 16.7 frames/s): every 3rd / 2nd / 1.5th frame of the real video: real
  frames (at 16.7, every other one interpolated between two real ones);
- faster (30, 50, 60 frames/s): frames interpolated linearly between the real ones (a
  stand-in: a real faster camera also sees motion between them).

The scorer is the shipped marker committee, trained on these very experiments: the rows measure
what a rate does to the same decisions, not accuracy on new objects (``bench_slip_real.py``
measures that, at 25 frames/s).

    python benches/bench_slip_rates.py [--data DIR] [--rates 8.333 12.5 16.667 30 50 60]
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

from bench_slip_real import DEFAULT_DATA, shipped_committee_as_recorded

from tacswitch.grasp.augment import rescaled_clip
from tacswitch.grasp.crossval import clip_flags
from tacswitch.grasp.dataset import TrackedClip
from tacswitch.grasp.evaluate import format_scores, score_experiments
from tacswitch.grasp.timebase import TRAINED_FPS, needs_resampling, resample_field


def at_rate(clip: TrackedClip, fps: float) -> TrackedClip:
    """``clip`` (recorded at 25 frames/s) as a camera at ``fps`` would have delivered it."""
    played = rescaled_clip(clip, 1.0, TRAINED_FPS / fps) if fps != TRAINED_FPS else clip
    return replace(played, fps=fps)


def resampled(clip: TrackedClip) -> TrackedClip:
    """``clip`` on the 25 frames/s time base, as ``TimeBase`` resamples it online."""
    assert clip.fps is not None
    motion, valid = resample_field(clip.motion, clip.valid, clip.fps)
    # The rest frame on the new time base: the first tick at or after it.
    rest = min(math.ceil(clip.rest * TRAINED_FPS / clip.fps - 1e-9), len(motion) - 1)
    return replace(clip, motion=motion, valid=valid, fps=None, rest=max(rest, 0))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--rates", type=float, nargs="+",
                    default=[25 / 3, 12.5, 50 / 3, 30.0, 50.0, 60.0])
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    _, labels, clips, _ = shipped_committee_as_recorded(
        a.data, a.workers, "recorded at 25 frames/s", "25 frames/s, as recorded")
    for fps in a.rates:
        played = [[at_rate(c, fps) for c in exp] for exp in clips]
        kind = "real frames" if fps < TRAINED_FPS else "interpolated"
        default = "resampled" if needs_resampling(fps) else "frame by frame"
        for resample in (False, True):
            how = "resampled to 25" if resample else "read frame by frame"
            how += " (the detector's choice)" if (default == "resampled") == resample else ""
            flags = [[clip_flags(resampled(c) if resample else c, model="markers", fps=None)
                      for c in exp] for exp in played]
            print(format_scores(f"{fps:g} frames/s ({kind}), {how}",
                                score_experiments(labels, flags)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
