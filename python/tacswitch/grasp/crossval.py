"""Running the online detector over tracked clips, and object-grouped cross-validation of the
learned scorer (training needs ``tacswitch[train]``)."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.grasp.dataset import TrackedClip
from tacswitch.grasp.detector import run_clip
from tacswitch.grasp.evaluate import object_folds, score_experiments


def clip_flags(clip: TrackedClip, **options: Any) -> NDArray[np.bool_]:
    """Per-frame slip flags of one tracked clip through :class:`GraspSlipDetector` (options:
    its keyword arguments), frame by frame as the online loop runs; none for a clip whose
    first frame showed no marker."""
    if len(clip.points) == 0:
        return np.zeros(len(clip.motion), bool)
    states = run_clip(clip.motion, clip.valid, clip.points, image_width=clip.width, **options)
    return np.array([s.slip for s in states], bool)


def torch_scorer(net: Any) -> Any:
    """A torch scorer as the detector's ``model`` callable."""
    from tacswitch.grasp.train import frame_scores

    return lambda x: frame_scores(net, x)


#: Seeds :func:`train_validated` trains by default; it keeps the one the validation grasps favour.
VALIDATED_SEEDS = 3
#: The validation grasps (:func:`validation_grasps`): rendered grasps per kind and sensor, and
#: their first seed. Disjoint from the training grasps (seeds 1000-1023) and from the held-out
#: test grasps of ``benches/bench_slip_real.py`` (seeds 3000-3005).
VALIDATION_PER_KIND = 6
VALIDATION_SEED = 4000

Grasps = tuple[list[TrackedClip], list[bool]]


def validation_grasps() -> Grasps:
    """Rendered slip / hold / vibration grasps on the GelSight and the GelSight Mini
    (:data:`VALIDATION_PER_KIND` each, seeds from :data:`VALIDATION_SEED`), tracked: the
    validation set of :func:`train_validated`, another sensor than most users' recordings."""
    from tacswitch.grasp.simulated import simulated_clips

    return simulated_clips(VALIDATION_PER_KIND, VALIDATION_SEED)


def train_validated(features: list[list[NDArray[np.float32]]], labels: list[bool],
                    validation: Grasps | None, *, seed: int = 0, seeds: int = VALIDATED_SEEDS,
                    epochs: int | None = None, log: Any = None) -> Any:
    """Trains a scorer from each of ``seeds`` seeds (``seed, seed + 1, ...``) and keeps the one
    whose online decisions on the ``validation`` grasps (clips, labels; see
    :func:`validation_grasps`) have the best balanced accuracy (ties: the lowest seed). Returns
    its :class:`~tacswitch.grasp.train.SlipTrainResult`, with ``validation`` set to the
    balanced accuracy of every seed. Without validation grasps, or with ``seeds=1``: the first
    seed alone.

    Why: the multiple-instance objective (an experiment's largest frame score) leaves seeds that
    decide alike on real grasps of unseen objects (5-fold leave-objects-out balanced accuracy
    0.80-0.84 on the real GelSight Mini grasps) but not on grasps of another sensor: on rendered
    grasps some flag every hold. The validation grasps are never trained on."""
    from tacswitch.grasp.train import EPOCHS, train_scorer

    best: Any = None
    scores: list[float] = []
    for s in range(seed, seed + max(1, seeds)):
        res = train_scorer(features, labels, epochs=epochs or EPOCHS, seed=s, log=log)
        if validation is None or seeds <= 1:
            return res
        scorer = torch_scorer(res.net)
        flags = [[clip_flags(c, model=scorer, threshold=0.0)] for c in validation[0]]
        scores.append(score_experiments(validation[1], flags).balanced_accuracy)
        if log is not None:
            log(f"seed {s}: balanced accuracy {scores[-1]:.3f} on the validation grasps")
        if best is None or scores[-1] > max(scores[:-1]):
            best = res
    best.validation = scores
    return best


def cross_validated_flags(clips: list[list[TrackedClip]], labels: list[bool],
                          objects: list[str], *, seed: int = 0, epochs: int | None = None,
                          folds: int = 5,
                          test_sets: dict[str, list[list[TrackedClip]]] | None = None,
                          extra: tuple[list[list[TrackedClip]], list[bool]] | None = None,
                          validation: Grasps | None = None,
                          seeds: int = VALIDATED_SEEDS,
                          paired: list[list[TrackedClip]] | None = None,
                          quiet: bool = True) -> dict[str, list[list[NDArray[np.bool_]]]]:
    """Flags of every experiment's videos from a scorer trained on ``clips`` of the other
    folds' objects (:func:`object_folds`): under key ``"train"`` for ``clips`` themselves and
    under each name of ``test_sets`` (the same experiments seen otherwise, e.g. markerless).
    ``extra`` (experiments, labels) joins every fold's training set (e.g. rendered grasps).
    ``paired``: another view of the same experiments, index for index (the marker tracks of
    markerless ``clips``); each fold also trains on the paired view of its training objects,
    never of the held-out ones. Each fold's scorer is :func:`train_validated`'s (``seeds``
    seeds from ``seed``, kept by the ``validation`` grasps; without them, seed ``seed``
    alone)."""
    feats = [[c.features() for c in exp] for exp in clips]
    if paired is not None and len(paired) != len(clips):
        raise ValueError(f"paired: one entry per experiment ({len(clips)}); got {len(paired)}")
    paired_feats = [[c.features() for c in exp] for exp in paired] if paired else None
    extra_feats = [[c.features() for c in exp] for exp in extra[0]] if extra else []
    extra_labels = list(extra[1]) if extra else []
    fold_of = object_folds(objects, folds)
    sets = {"train": clips, **(test_sets or {})}
    out: dict[str, list[list[NDArray[np.bool_]]]] = {k: [[] for _ in clips] for k in sets}
    for f in sorted(set(fold_of)):
        train = [i for i, k in enumerate(fold_of) if k != f]
        if not quiet:
            print(f"fold {f + 1}/{folds}: training on {len(train)} experiments",
                  file=sys.stderr)
        train_feats = [feats[i] for i in train]
        train_labels = [labels[i] for i in train]
        if paired_feats is not None:
            train_feats += [paired_feats[i] for i in train]
            train_labels += [labels[i] for i in train]
        res = train_validated(train_feats + extra_feats, train_labels + extra_labels,
                              validation, seed=seed, seeds=seeds, epochs=epochs)
        scorer = torch_scorer(res.net)
        for name, test in sets.items():
            for i, k in enumerate(fold_of):
                if k == f:
                    out[name][i] = [clip_flags(c, model=scorer, threshold=0.0)
                                    for c in test[i]]
    return out
