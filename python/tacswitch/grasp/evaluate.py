"""Scoring slip decisions against per-experiment labels, and object-grouped folds.

An experiment is called slip when any frame of any of its videos is flagged (what a user gets
from ``tacswitch slip VIDEO --log CSV`` per finger). Folds group experiments by object: two
experiments of one object are not independent, and a detector is used on objects it never saw.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Frames per second of the recordings, for false alarms per minute (the Mini's 25).
DEFAULT_FPS = 25.0


def object_folds(objects: Sequence[str], k: int = 5) -> list[int]:
    """Fold index (0..k-1) of each experiment, every object in one fold. Objects are dealt
    largest first to the fold with the fewest experiments (ties: lowest index), in name order
    among equals: deterministic and balanced."""
    if k < 2:
        raise ValueError(f"k: at least 2 folds; got {k}")
    names = sorted(set(objects))
    if len(names) < k:
        raise ValueError(f"k: {k} folds need at least {k} objects; got {len(names)}")
    counts = {n: sum(1 for o in objects if o == n) for n in names}
    sizes = [0] * k
    fold_of: dict[str, int] = {}
    for n in sorted(names, key=lambda n: (-counts[n], n)):
        f = min(range(k), key=lambda i: (sizes[i], i))
        fold_of[n] = f
        sizes[f] += counts[n]
    return [fold_of[o] for o in objects]


@dataclass(frozen=True)
class SlipScores:
    """Per-experiment decisions against labels.

    Attributes:
        n: experiments; n_slip / n_hold: labelled slip / not.
        tp, fp, tn, fn: counts (positive = slip).
        accuracy, balanced_accuracy, tpr (slips caught), tnr (held grasps left alone).
        false_alarms_per_min: flagged episodes per minute of footage of held grasps (every
            video counted; an episode is a run of consecutive flagged frames).
        median_first_frame: median frame of the first flag in caught slips (NaN if none).
    """

    n: int
    n_slip: int
    n_hold: int
    tp: int
    fp: int
    tn: int
    fn: int
    accuracy: float
    balanced_accuracy: float
    tpr: float
    tnr: float
    false_alarms_per_min: float
    median_first_frame: float


def score_experiments(labels: Sequence[bool], flags: Sequence[Sequence[np.ndarray]],
                      fps: float | Sequence[Sequence[float | None]] = DEFAULT_FPS
                      ) -> SlipScores:
    """Scores ``flags[i]`` (one bool array per video of experiment ``i``, per frame) against
    ``labels[i]``. ``fps``: the videos' frame rate (frames/s), one for all or one per video
    (``fps[i][j]``, None: :data:`DEFAULT_FPS`), for the false alarms per minute."""
    if len(labels) != len(flags):
        raise ValueError("flags: one list of videos per label")
    rates = ([[fps] * len(exp) for exp in flags] if isinstance(fps, (int, float))
             else [[DEFAULT_FPS if r is None else r for r in exp] for exp in fps])
    if len(rates) != len(flags) or any(len(r) != len(e) for r, e in zip(rates, flags,
                                                                         strict=True)):
        raise ValueError("fps: one frame rate per video of every experiment")
    if not all(np.isfinite(r) and r > 0 for exp in rates for r in exp):
        raise ValueError("fps: frame rates must be finite and positive")
    y = np.asarray(labels, bool)
    called = np.array([any(bool(np.any(v)) for v in exp) for exp in flags], bool)
    tp = int((y & called).sum())
    fp = int((~y & called).sum())
    tn = int((~y & ~called).sum())
    fn = int((y & ~called).sum())
    n_slip, n_hold = int(y.sum()), int((~y).sum())
    tpr = tp / n_slip if n_slip else float("nan")
    tnr = tn / n_hold if n_hold else float("nan")
    episodes = 0
    minutes = 0.0
    for lab, exp, exp_fps in zip(y, flags, rates, strict=True):
        if lab:
            continue
        for v, rate in zip(exp, exp_fps, strict=True):
            a = np.asarray(v, bool)
            minutes += len(a) / rate / 60.0
            episodes += int(a[0]) + int(np.sum(a[1:] & ~a[:-1])) if len(a) else 0
    firsts = [min(int(np.argmax(v)) for v in exp if np.any(v))
              for lab, exp in zip(y, flags, strict=False) if lab and any(np.any(v) for v in exp)]
    return SlipScores(
        n=len(y), n_slip=n_slip, n_hold=n_hold, tp=tp, fp=fp, tn=tn, fn=fn,
        accuracy=(tp + tn) / len(y) if len(y) else float("nan"),
        balanced_accuracy=(tpr + tnr) / 2 if n_slip and n_hold else float("nan"),
        tpr=tpr, tnr=tnr,
        false_alarms_per_min=episodes / minutes if minutes else float("nan"),
        median_first_frame=float(np.median(firsts)) if firsts else float("nan"),
    )


def format_scores(name: str, s: SlipScores) -> str:
    """One Markdown table row: name, balanced accuracy, accuracy, TPR, TNR, false alarms/min,
    median first flagged frame of caught slips."""
    return (f"| {name} | {s.balanced_accuracy:.3f} | {s.accuracy:.3f} | {s.tp}/{s.n_slip} "
            f"({s.tpr:.2f}) | {s.tn}/{s.n_hold} ({s.tnr:.2f}) | {s.false_alarms_per_min:.2f} | "
            f"{s.median_first_frame:.0f} |")


TABLE_HEADER = ("| detector | balanced accuracy | accuracy | slips caught (TPR) | "
                "held left alone (TNR) | false alarms / min of held footage | "
                "first flag (median frame) |\n|---|---|---|---|---|---|---|")
