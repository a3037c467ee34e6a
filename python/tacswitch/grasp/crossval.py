"""Running the online detector over tracked clips, and object-grouped cross-validation of the
learned scorer (training needs ``tacswitch[train]``)."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.grasp.augment import augmented_experiments
from tacswitch.grasp.dataset import TrackedClip, clip_features
from tacswitch.grasp.detector import run_clip
from tacswitch.grasp.evaluate import object_folds
from tacswitch.grasp.train import COMMITTEE, SLIP_TAIL


def clip_flags(clip: TrackedClip, **options: Any) -> NDArray[np.bool_]:
    """Per-frame slip flags of one tracked clip through :class:`GraspSlipDetector` (options:
    its keyword arguments), frame by frame as the online loop runs, at the clip's frame rate;
    none for a clip whose first frame showed no marker. As in ``tacswitch slip``, the detector
    starts at the clip's rest frame (none before it is flagged), so both flag the same frames,
    and reads the contact phases since that frame (``first_frame_rest``: a clip is tracked from
    its rest frame, but the markerless tracker gives that frame a motion of its own)."""
    flags = np.zeros(len(clip.motion), bool)
    if len(clip.points) == 0:
        return flags
    options.setdefault("fps", clip.fps)
    options.setdefault("first_frame_rest", True)
    r = clip.rest
    states = run_clip(clip.motion[r:], clip.valid[r:], clip.points, image_width=clip.width,
                      **options)
    flags[r:] = [s.slip for s in states]
    return flags


def torch_scorer(net: Any) -> Any:
    """A torch scorer as the detector's ``model`` callable."""
    from tacswitch.grasp.train import frame_scores

    return lambda x: frame_scores(net, x)


def cross_validated_flags(clips: list[list[TrackedClip]], labels: list[bool],
                          objects: list[str], *, seed: int = 0, epochs: int | None = None,
                          folds: int = 5,
                          test_sets: dict[str, list[list[TrackedClip]]] | None = None,
                          extra: tuple[list[list[TrackedClip]], list[bool]] | None = None,
                          seeds: int = COMMITTEE, votes: int | None = None,
                          paired: list[list[TrackedClip]] | None = None,
                          augment: int = 0, still_filter: bool = False,
                          slip_tail: float = SLIP_TAIL, quiet: bool = True
                          ) -> dict[str, list[list[NDArray[np.bool_]]]]:
    """Flags of every experiment's videos from a scorer trained on ``clips`` of the other
    folds' objects (:func:`object_folds`): under key ``"train"`` for ``clips`` themselves and
    under each name of ``test_sets`` (the same experiments seen otherwise, e.g. markerless).
    ``extra`` (experiments, labels) joins every fold's training set (e.g. rendered grasps), as
    :func:`~tacswitch.grasp.train.train_committee` takes it (not for its real-only members).
    ``paired``: another view of the same experiments, index for index (the marker tracks of
    markerless ``clips``); each fold also trains on the paired view of its training objects,
    never of the held-out ones. ``augment``: rescaled copies of each of ``clips``'
    experiments (:func:`~tacswitch.grasp.augment.augmented_experiments`; each fold trains on
    the copies of its training objects only; ``extra`` is not copied). Each fold's scorer
    is the recipe's committee (:func:`~tacswitch.grasp.train.train_committee`: ``seeds``
    scorers from seed ``seed``, ``votes`` of them to flag). ``still_filter``: features read
    through the still-marker hysteresis in training and scoring (a marker scorer's recipe,
    :class:`~tacswitch.grasp.features.FieldFeatures`). ``slip_tail``: the share of each
    cut-short slip video that may carry its label in training
    (:func:`~tacswitch.grasp.train.counted_from`)."""
    from tacswitch.grasp.train import train_committee

    feats = clip_features(clips, still_filter)
    if paired is not None and len(paired) != len(clips):
        raise ValueError(f"paired: one entry per experiment ({len(clips)}); got {len(paired)}")
    paired_feats = clip_features(paired, still_filter) if paired else None
    copies, owner = augmented_experiments(clips, augment)
    copy_feats = clip_features(copies, still_filter)
    extra_feats = clip_features(extra[0], still_filter) if extra else []
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
        kept = set(train)
        train_feats += [x for x, i in zip(copy_feats, owner, strict=True) if i in kept]
        train_labels += [labels[i] for i in owner if i in kept]
        res = train_committee(train_feats, train_labels, seed=seed, seeds=seeds, votes=votes,
                              epochs=epochs, extra=(extra_feats, extra_labels),
                              slip_tail=slip_tail)
        scorer = torch_scorer(res.net)
        for name, test in sets.items():
            for i, k in enumerate(fold_of):
                if k == f:
                    out[name][i] = [clip_flags(c, model=scorer, threshold=0.0,
                                               votes=res.votes, still_filter=still_filter,
                                               half_vote=res.half_vote)
                                    for c in test[i]]
    return out
