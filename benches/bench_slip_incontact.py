"""The shipped slip scorer on real grasps whose recording starts in contact.

A recording that begins while the object is already held has no contact onset to find: the
first frame, the reference of every marker motion, shows a loaded gel. Every real grasp of
``bench_slip_real.py`` is cut to start a few frames after its established grasp (the detected
start plus ``--offsets``), its tracks re-referenced at the cut (each marker's motion minus its
motion there, its rest point moved there: what tracking from that frame gives), and scored by
the shipped marker committee twice: with the grasp start the detector finds, and with
``start=0`` (``tacswitch slip --start 0``, what the guide advises for such recordings).

Cutting also removes what happened before the cut: a slip that was over by then cannot be
caught. The bench counts the slip experiments whose first flag as recorded (either finger)
comes after the cut, the slips a detector could still catch.

The scorer was trained on these very experiments: the rows measure what a loaded first frame
does to the same decisions, not accuracy on new objects (``bench_slip_real.py`` measures that).

    python benches/bench_slip_incontact.py [--data DIR] [--offsets 10 40]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from bench_slip_real import DEFAULT_DATA, shipped_committee_as_recorded

from tacswitch.grasp.crossval import clip_flags
from tacswitch.grasp.dataset import TrackedClip
from tacswitch.grasp.detector import run_clip
from tacswitch.grasp.evaluate import format_scores, score_experiments
from tacswitch.grasp.phases import GRASP


def grasp_start(clip: TrackedClip) -> int:
    """The first frame of the clip's first established grasp as the detector finds it (0: none);
    the scorer is not run (the phases do not depend on it)."""
    if len(clip.points) == 0:
        return 0
    r = clip.rest  # from the rest frame, as clip_flags scores it
    states = run_clip(clip.motion[r:], clip.valid[r:], clip.points, image_width=clip.width,
                      model=lambda x: np.zeros(len(x), np.float32), fps=clip.fps,
                      first_frame_rest=True)
    return next((r + t for t, s in enumerate(states) if s.phase == GRASP), 0)


def starting_at(clip: TrackedClip, frame: int) -> TrackedClip:
    """``clip`` as tracking from ``frame`` records it: the markers valid there, their motion
    since that frame, their rest points where they are then (at least the last 3 frames kept)."""
    s = int(min(max(frame, 0), len(clip.motion) - 3))
    ok = clip.valid[s]
    return replace(clip, motion=clip.motion[s:, ok] - clip.motion[s, ok][None],
                   valid=clip.valid[s:, ok], points=(clip.points + clip.motion[s])[ok], rest=0)


def first_flag(flags: np.ndarray) -> int:
    """The first flagged frame (-1: none)."""
    hit = np.flatnonzero(flags)
    return int(hit[0]) if hit.size else -1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--offsets", type=int, nargs="+", default=[10, 40])
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    _, labels, clips, recorded = shipped_committee_as_recorded(
        a.data, a.workers, "recorded from before the contact", "as recorded (from the rest frame)")
    starts = [[grasp_start(c) for c in exp] for exp in clips]
    notes = []
    for off in a.offsets:
        cut = [[starting_at(c, s + off) for c, s in zip(exp, ss, strict=True)]
               for exp, ss in zip(clips, starts, strict=True)]
        # Slips whose first flag as recorded comes after the cut: still in the cut clip.
        still = [y and any(first_flag(f) > s + off for f, s in zip(fl, ss, strict=True))
                 for y, fl, ss in zip(labels, recorded, starts, strict=True)]
        caught = []
        for start in (None, 0):
            how = "grasp start detected" if start is None else "start=0 (--start 0)"
            flags = [[clip_flags(c, model="markers", start=start) for c in exp] for exp in cut]
            print(format_scores(f"starts in contact: grasp start + {off} frames, {how}",
                                score_experiments(labels, flags)), flush=True)
            caught.append(sum(s and any(f.any() for f in fl)
                              for s, fl in zip(still, flags, strict=True)))
        notes.append(f"grasp start + {off} frames: {sum(still)} of {sum(labels)} slips are "
                     f"flagged as recorded after the cut; of those, {caught[0]} are caught "
                     f"with the grasp start detected, {caught[1]} with start=0")
    print("\n" + "\n".join(notes))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
