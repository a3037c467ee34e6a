"""Augmented copies of tracked grasps for training the slip scorer.

A real training set holds few objects (the public GelSight Mini study: 29), and an object's own
stiffness, weight and grip set how far its markers move and how fast: a scorer can learn "this
much motion is a slip" from them, which does not hold for the next object. Each copy is the same
grasp as another gel, grip or shake would have recorded it, with its label unchanged:

- every displacement scaled by one factor (a softer or stiffer gel, a firmer grip, another
  sensor's pixel scale);
- time resampled by one factor (a faster or slower shake or slide; frames interpolated
  linearly, a marker valid where both frames it comes from are).

Both fingers of an experiment get the same factors (one grasp). The factors are drawn
log-uniformly, so a copy is as likely to be larger as smaller.

Off in the shipped recipe (``tacswitch train slip --augment N`` turns it on). Measured on the
real GelSight Mini grasps, objects held out, committees of 8 at 4 votes (the rendered grasps in
training): one copy of each real grasp 0.874 / 0.810 against 0.820 / 0.789 (seeds 0-7 / 8-15),
but the committee trained so flags all 24 held-out rendered holds; copying the rendered grasps
too spares them and gives back the gain (0.826 / 0.781). The same trade as fewer rendered
grasps (``docs/notes/2026-11-slip.md``). Markers only: not measured on markerless motion.
"""

from __future__ import annotations

import math

import numpy as np

from tacswitch._checks import as_count, as_number
from tacswitch.grasp.dataset import TrackedClip

#: Rescaled copies of each real experiment in the shipped scorers' training sets (the default of
#: ``tacswitch train slip --augment``): none (see the module doc).
COPIES = 0
#: Seed of the draws of scale and speed.
SEED = 0
#: Largest displacement scale of a copy (drawn log-uniformly in [1/x, x]).
SCALE_RANGE = 1.5
#: Largest time-resampling factor of a copy (drawn log-uniformly in [1/x, x]); > 1 is faster.
SPEED_RANGE = 1.33


def rescaled_clip(clip: TrackedClip, scale: float, speed: float) -> TrackedClip:
    """``clip`` with every displacement times ``scale`` and played ``speed`` times as fast
    (``T`` frames become ``round((T - 1) / speed) + 1``, at least 2), frames linearly
    interpolated; the rest frame becomes the first output frame at or after it. Reference
    points, pitch and width are unchanged."""
    for name, v in (("scale", scale), ("speed", speed)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v)
                and v > 0):
            raise ValueError(f"{name}: must be a finite number > 0; got {v!r}")
    m, valid = clip.motion, clip.valid
    t_in = len(m)
    if t_in == 0:
        return clip
    t_out = max(2, round((t_in - 1) / float(speed)) + 1) if t_in > 1 else 1
    t = np.minimum(np.arange(t_out) * float(speed), t_in - 1)
    i0 = np.floor(t).astype(np.int64)
    i1 = np.minimum(i0 + 1, t_in - 1)
    frac = (t - i0).astype(np.float32)
    w = frac[:, None, None]
    motion = (m[i0] * (1 - w) + m[i1] * w) * np.float32(scale)
    # A frame that falls on an input frame is that frame; one between two needs both.
    on_frame = (frac == 0)[:, None]
    both = valid[i0] & valid[i1]
    return TrackedClip(motion.astype(np.float32), np.where(on_frame, valid[i0], both),
                       clip.points, clip.pitch, clip.width, clip.fps,
                       min(math.ceil(clip.rest / float(speed) - 1e-9), t_out - 1))


def augmented_experiments(clips: list[list[TrackedClip]], copies: int, *, seed: int = SEED,
                          scale_range: float = SCALE_RANGE, speed_range: float = SPEED_RANGE,
                          ) -> tuple[list[list[TrackedClip]], list[int]]:
    """``copies`` rescaled copies of every experiment (:func:`rescaled_clip`, one draw of scale
    and speed per copy, shared by its videos) and, for each copy, the index of the experiment it
    came from (its label and object are that experiment's). Deterministic for a seed."""
    copies = as_count(copies, "copies", 0, None)
    scale_range = as_number(scale_range, "scale_range", minimum=1.0)
    speed_range = as_number(speed_range, "speed_range", minimum=1.0)
    rng = np.random.RandomState(seed)
    out: list[list[TrackedClip]] = []
    owner: list[int] = []
    for _ in range(copies):
        for i, exp in enumerate(clips):
            s = float(np.exp(rng.uniform(-np.log(scale_range), np.log(scale_range))))
            v = float(np.exp(rng.uniform(-np.log(speed_range), np.log(speed_range))))
            out.append([rescaled_clip(c, s, v) for c in exp])
            owner.append(i)
    return out, owner


def copies_phrase(copies: int) -> str:
    """How a report names ``copies`` rescaled copies: "1 rescaled copy", "2 rescaled copies"."""
    return f"{copies} rescaled cop{'y' if copies == 1 else 'ies'}"


def with_copies(experiments: list[list[TrackedClip]], labels: list[bool], copies: int, *,
                seed: int = SEED) -> tuple[list[list[TrackedClip]], list[bool]]:
    """``experiments`` followed by ``copies`` rescaled copies of each
    (:func:`augmented_experiments`), and their labels."""
    if len(labels) != len(experiments):
        raise ValueError(f"labels: one per experiment ({len(experiments)}); got {len(labels)}")
    extra, owner = augmented_experiments(experiments, copies, seed=seed)
    return experiments + extra, list(labels) + [labels[i] for i in owner]


def marker_training_set(clips: list[list[TrackedClip]], labels: list[bool], simulated: int,
                        copies: int) -> tuple[list[list[TrackedClip]], list[bool],
                                              list[list[TrackedClip]], list[bool]]:
    """The marker scorer's training set as the recipe builds it (what ``tacswitch train slip``
    and ``benches/bench_slip_real.py --export`` train on), in two parts: the real experiments
    and ``copies`` rescaled copies of each, with their labels; then ``simulated`` rendered
    grasps per kind and sensor (:func:`tacswitch.grasp.simulated.simulated_clips`; none for 0)
    and theirs, which :func:`tacswitch.grasp.train.train_committee` takes as ``extra``."""
    from tacswitch.grasp.simulated import SIMULATED_SEED, simulated_clips

    real, real_labels = with_copies(clips, labels, copies)
    if not simulated:
        return real, real_labels, [], []
    sim_clips, sim_labels = simulated_clips(simulated, SIMULATED_SEED)
    return real, real_labels, [[c] for c in sim_clips], list(sim_labels)
