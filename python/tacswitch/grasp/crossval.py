"""Running the online detector over tracked clips, and object-grouped cross-validation of the
learned scorer (training needs ``tacswitch[train]``)."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.grasp.dataset import TrackedClip
from tacswitch.grasp.detector import run_clip
from tacswitch.grasp.evaluate import object_folds


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


def cross_validated_flags(clips: list[list[TrackedClip]], labels: list[bool],
                          objects: list[str], *, seed: int = 0, epochs: int | None = None,
                          folds: int = 5,
                          test_sets: dict[str, list[list[TrackedClip]]] | None = None,
                          extra: tuple[list[list[TrackedClip]], list[bool]] | None = None,
                          quiet: bool = True) -> dict[str, list[list[NDArray[np.bool_]]]]:
    """Flags of every experiment's videos from a scorer trained on ``clips`` of the other
    folds' objects (:func:`object_folds`): under key ``"train"`` for ``clips`` themselves and
    under each name of ``test_sets`` (the same experiments seen otherwise, e.g. markerless).
    ``extra`` (experiments, labels) joins every fold's training set (e.g. rendered grasps)."""
    from tacswitch.grasp.train import EPOCHS, train_scorer

    feats = [[c.features() for c in exp] for exp in clips]
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
        res = train_scorer([feats[i] for i in train] + extra_feats,
                           [labels[i] for i in train] + extra_labels,
                           epochs=epochs or EPOCHS, seed=seed)
        scorer = torch_scorer(res.net)
        for name, test in sets.items():
            for i, k in enumerate(fold_of):
                if k == f:
                    out[name][i] = [clip_flags(c, model=scorer, threshold=0.0)
                                    for c in test[i]]
    return out
