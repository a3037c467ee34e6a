"""``tacswitch evaluate slip`` and ``tacswitch train slip``: slip detection on a user's own
labelled grasp recordings.

A folder ``DIR`` holds ``labels.csv`` (columns ``object, experiment, slip``; slip 1 or 0 for the
whole experiment) and ``OBJECT/EXPERIMENT/*.avi`` (or .mp4, ...), one video per sensor. Each video
is tracked once (cached in ``--cache``, resumable). An experiment counts as slip when any frame of
any of its videos is flagged.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from tacswitch.cli.options import UsageError
from tacswitch.cli.progress import stderr_is_terminal


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", help="folder with labels.csv and OBJECT/EXPERIMENT/*.avi videos")
    p.add_argument("--labels", default=None, help="labels CSV (default: DATA/labels.csv)")
    p.add_argument("--cache", default=None,
                   help="folder for the tracked clips (default: DATA/.tacswitch-cache)")
    p.add_argument("--workers", type=int, default=1,
                   help="tracking processes (default: 1; at most one per video and CPU core)")
    from tacswitch.grasp.detector import SCORER_REMOVAL_TEXT

    p.add_argument("--markerless", action="store_true",
                   help=f"remove the markers first (remove_markers with "
                        f"{SCORER_REMOVAL_TEXT}) and predict their motion (MarkerlessTracker): "
                        "the markerless sensor these videos would be")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")


def add_evaluate_parser(what: argparse._SubParsersAction) -> None:
    p = what.add_parser("slip", help="slip detection on your labelled grasp videos",
                        description=__doc__)
    _common(p)
    p.add_argument("--rule", choices=("learned", "paper"), default="learned",
                   help="the learned scorer (default) or the paper's displacement rule")
    p.add_argument("--model", default=None,
                   help="ONNX scorer (default: the shipped one, for markers or with --markerless "
                        "for predicted motion)")
    p.add_argument("--score-threshold", type=float, default=None, metavar="LOGIT",
                   help="--rule learned: a committee member fires on a frame whose score "
                        "exceeds this (default: the model's, 0)")
    from tacswitch.cli.options import px_or_auto

    p.add_argument("--rigid-threshold-px", type=px_or_auto, default=None, metavar="PX|auto",
                   help="--rule paper: add the rigid criterion (pixels > 0, or 'auto')")
    p.add_argument("--cv", type=int, default=None, metavar="K",
                   help="instead of the model: train and score K folds grouped by object "
                        "(needs tacswitch[train])")
    _committee_options(p, "--cv: per fold, ")
    _marker_tracks_option(p, "--cv: ")
    _augment_option(p, "--cv: per fold, ")
    _slip_tail_option(p, "--cv: ")
    p.add_argument("--json", default=None, help="also write the scores and each experiment's "
                                                "decision to this JSON file")
    p.set_defaults(run=run_evaluate)


def add_train_parser(what: argparse._SubParsersAction) -> None:
    p = what.add_parser("slip", help="the slip scorer, on your labelled grasp videos",
                        description=__doc__)
    _common(p)
    p.add_argument("--out", required=True, help="ONNX file to write")
    from tacswitch.grasp.train import EPOCHS

    p.add_argument("--epochs", type=int, default=None, help="passes over the experiments "
                                                            f"(default: {EPOCHS})")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    _committee_options(p, "")
    p.add_argument("--simulated", type=int, default=None, metavar="N",
                   help="add N rendered grasps per kind (slip / hold / vibration) and sensor "
                        "(GelSight, GelSight Mini) to the training set of half the committee "
                        "(the other half trains on your grasps alone): the textbook slip your "
                        "recordings may lack (default: 48, as the shipped scorer; 0: none; "
                        "ignored with --markerless)")
    _marker_tracks_option(p, "")
    _augment_option(p, "")
    _slip_tail_option(p, "")
    p.set_defaults(run=run_train)


def _committee_options(p: argparse.ArgumentParser, scope: str) -> None:
    from tacswitch.grasp.train import VOTE_FRACTION, default_committee_text

    p.add_argument("--seeds", type=int, default=None, metavar="N",
                   help=f"{scope}train a committee of N scorers (seeds --seed, --seed + 1, ...; "
                        f"default: {default_committee_text('with --markerless')}; 1: one "
                        "scorer): a grasp is flagged once --votes of them have "
                        "fired in it, which decides more steadily on unseen objects than any "
                        "one scorer (BENCHMARKS.md)")
    p.add_argument("--votes", type=int, default=None, metavar="K",
                   help=f"{scope}members that must fire in a grasp (default: "
                        f"{round(VOTE_FRACTION * 100)} %% of --seeds, rounded up; fewer: more "
                        "slips caught, more false alarms, earlier flags)")


def _committee(args: argparse.Namespace) -> tuple[int, int | None]:
    """``--seeds`` and ``--votes``, checked (defaults: the recipe's)."""
    from tacswitch.grasp.train import recipe_committee

    if args.seeds is not None and not 1 <= args.seeds <= 100:
        raise UsageError(f"--seeds: must be in [1, 100]; got {args.seeds}")
    seeds = recipe_committee(args.markerless) if args.seeds is None else int(args.seeds)
    if args.votes is not None and not 1 <= args.votes <= seeds:
        raise UsageError(f"--votes: must be in [1, --seeds={seeds}]; got {args.votes}")
    return seeds, args.votes


def _augment_option(p: argparse.ArgumentParser, scope: str) -> None:
    from tacswitch.grasp.augment import COPIES

    p.add_argument("--augment", type=int, default=None, metavar="N",
                   help=f"{scope}add N rescaled copies of each of your experiments to the "
                        "training set (displacements scaled, time resampled: the same grasp on "
                        "a stiffer or softer gel, shaken faster or slower; default: "
                        f"{COPIES}). On unseen real objects 1 decided better, but then the "
                        "rendered holds were flagged (docs/slip.md)")


def _augment(args: argparse.Namespace) -> int:
    """``--augment``, checked (default: the recipe's)."""
    from tacswitch.grasp.augment import COPIES

    if args.augment is None:
        return COPIES
    if not 0 <= args.augment <= 20:
        raise UsageError(f"--augment: must be in [0, 20]; got {args.augment}")
    return int(args.augment)


def _slip_tail_option(p: argparse.ArgumentParser, scope: str) -> None:
    from tacswitch.grasp.train import CUT_SHORT, recipe_slip_tail

    p.add_argument("--slip-tail", type=float, default=None, metavar="F",
                   help=f"{scope}in a slip video cut short by its slip (shorter than "
                        f"{CUT_SHORT:g} of the median held video: the recording stopped once "
                        "the object fell), only its last share F may carry the slip label in "
                        "training, for the scorers trained on your grasps alone (default: "
                        f"{recipe_slip_tail():g}; with --markerless {recipe_slip_tail(True):g}, "
                        "every frame; docs/slip.md); clips all of one length: it changes "
                        "nothing")


def _slip_tail(args: argparse.Namespace) -> float:
    """``--slip-tail``, checked (default: the recipe's, :func:`recipe_slip_tail`)."""
    from tacswitch.grasp.train import recipe_slip_tail

    if args.slip_tail is None:
        return recipe_slip_tail(bool(args.markerless))
    if not (math.isfinite(args.slip_tail) and 0 < args.slip_tail <= 1):
        raise UsageError(f"--slip-tail: must be in (0, 1]; got {args.slip_tail}")
    return float(args.slip_tail)


def _marker_tracks_option(p: argparse.ArgumentParser, scope: str) -> None:
    p.add_argument("--no-marker-tracks", action="store_true",
                   help=f"{scope}with --markerless, train on the markerless tracks alone (by "
                        "default the same videos' marker tracks join the training set, which "
                        "decides better on real grasps of unseen objects: BENCHMARKS.md)")


def _paired_marker_clips(args: argparse.Namespace, exps):  # type: ignore[no-untyped-def]
    """The marker tracks of the experiments, to train a markerless scorer on beside the
    markerless ones (None without --markerless or with --no-marker-tracks)."""
    from tacswitch.grasp.dataset import experiment_clips

    if not args.markerless or args.no_marker_tracks:
        return None
    # A video that cannot be tracked was named when the markerless tracks were loaded.
    return experiment_clips(exps, _cache_dir(args), markerless=False, workers=args.workers,
                            progress=not args.quiet and stderr_is_terminal(), unreadable=[])


def _cache_dir(args: argparse.Namespace) -> Path:
    """``--cache``, or ``DATA/.tacswitch-cache``: where the tracked clips are kept, created if
    missing (:class:`UsageError` naming ``--cache`` where it is a file or cannot be made). An
    existing folder is used as it is: a read-only cache of a read-only dataset is still read."""
    from tacswitch.cli.options import output_dir

    folder = Path(args.cache) if args.cache else Path(args.data) / ".tacswitch-cache"
    if folder.is_dir():
        return folder
    return output_dir(folder, "--cache")


def _load(args: argparse.Namespace, folds: int = 0,  # type: ignore[no-untyped-def]
          command: str = "evaluate slip"):
    """The labelled experiments and their tracked clips (``folds``: ``--cv``'s, checked against
    the objects before anything is tracked)."""
    from tacswitch.grasp.dataset import experiment_clips, read_labels

    if args.workers < 1:
        raise UsageError(f"--workers: must be >= 1; got {args.workers}")
    try:
        exps = read_labels(args.data, args.labels)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg.replace("root:", "data:", 1)
                         .replace("labels:", "--labels:", 1)) from None
    n_objects = len({e.object for e in exps})
    if folds > n_objects:
        raise UsageError(f"--cv: {folds} folds grouped by object need at least {folds} "
                         f"objects; the labels name {n_objects}")
    unreadable: list[tuple[Path, str]] = []
    clips = experiment_clips(exps, _cache_dir(args), markerless=args.markerless,
                             workers=args.workers, progress=not args.quiet and stderr_is_terminal(),
                             unreadable=unreadable)
    return _usable(exps, clips, unreadable, command)


def _usable(exps, clips, unreadable, command):  # type: ignore[no-untyped-def]
    """The experiments with at least one video that could be tracked, each with those videos:
    a video that does not decode, or shows no marker in its first frames (a blank recording:
    it would be scored as a grasp left alone), is left out and named in a warning, and so is an
    experiment left with no video; ``ValueError`` if none is left."""
    from tacswitch.cli.progress import warn

    bad = [(str(v), reason) for v, reason in unreadable]
    untracked = {v for v, _ in bad}
    keep_exps, keep_clips = [], []
    for e, cs in zip(exps, clips, strict=True):
        videos = [v for v in e.videos if str(v) not in untracked]
        usable = []
        for v, c in zip(videos, cs, strict=True):
            if len(c.points) == 0:
                bad.append((str(v), "no markers found in its first frames (a blank recording?)"))
            else:
                usable.append(c)
        if usable:
            keep_exps.append(e)
            keep_clips.append(usable)
    if bad:
        dropped = len(exps) - len(keep_exps)
        warn(command, f"{len(bad)} video(s) left out: " + "; ".join(
            f"{v}: {why}" for v, why in bad[:5]) + (" ..." if len(bad) > 5 else "") + (
            f"; {dropped} experiment(s) with no usable video are not scored" if dropped else ""))
    if not keep_exps:
        raise ValueError("data: no experiment has a video that can be tracked")
    return keep_exps, keep_clips


def run_evaluate(args: argparse.Namespace) -> int:
    from tacswitch.grasp.crossval import clip_flags, cross_validated_flags
    from tacswitch.grasp.evaluate import TABLE_HEADER, format_scores, score_experiments

    rigid = args.rigid_threshold_px
    if args.rule == "learned" and rigid is not None:
        raise UsageError("--rigid-threshold-px: applies to --rule paper only")
    if args.cv is not None and args.cv < 2:
        raise UsageError(f"--cv: at least 2 folds; got {args.cv}")
    if args.cv:
        for opt, given in (("--rule paper", args.rule == "paper"),
                           ("--model", args.model is not None),
                           ("--score-threshold", args.score_threshold is not None)):
            if given:
                raise UsageError(f"{opt}: does not apply with --cv (which trains its own "
                                 "scorers)")
    if args.rule == "paper" and args.score_threshold is not None:
        raise UsageError("--score-threshold: applies to --rule learned only")
    if args.score_threshold is not None and not math.isfinite(args.score_threshold):
        raise UsageError(f"--score-threshold: must be finite; got {args.score_threshold}")
    if args.rule == "paper" and args.model is not None:
        raise UsageError("--model: applies to --rule learned only")
    seeds, votes = _committee(args)
    for opt, val in (("--seeds", args.seeds), ("--votes", args.votes)):
        if val is not None and not args.cv:
            raise UsageError(f"{opt}: applies to --cv (training) only")
    if args.no_marker_tracks and not (args.cv and args.markerless):
        raise UsageError("--no-marker-tracks: applies to --cv with --markerless only")
    if args.augment is not None and not args.cv:
        raise UsageError("--augment: applies to --cv (training) only")
    if args.slip_tail is not None and not args.cv:
        raise UsageError("--slip-tail: applies to --cv (training) only")
    augment = _augment(args)
    slip_tail = _slip_tail(args)
    if args.json is not None:
        out = Path(args.json)
        if out.is_dir() or not out.parent.is_dir():
            raise UsageError(f"--json: cannot write {args.json!r} (a folder, or its folder "
                             "does not exist)")
        from tacswitch.cli.options import output_file

        output_file(out, "--json")  # a folder that cannot be written: said before tracking
    if args.model is not None:
        # Before tracking: a file that cannot be read is named at once, and a scorer of the
        # other kind of motion is said.
        from tacswitch.cli.slip import checked_scorer

        checked_scorer(args.model, args.markerless, command="evaluate slip", flag="--model")
    exps, clips = _load(args, folds=args.cv or 0)
    labels = [e.slip for e in exps]
    if len(set(labels)) == 1:
        from tacswitch.cli.progress import warn

        kind = "slip (1)" if labels[0] else "without slip (0)"
        warn("evaluate", f"--labels: every experiment is labelled {kind}, so the rate of the "
             "other class and the balanced accuracy are undefined (nan)")
    if args.cv:
        flags = cross_validated_flags(clips, labels, [e.object for e in exps], folds=args.cv,
                                      seeds=seeds, votes=votes,
                                      paired=_paired_marker_clips(args, exps),
                                      augment=augment, still_filter=not args.markerless,
                                      slip_tail=slip_tail, quiet=args.quiet)["train"]
        name = f"learned, {args.cv} folds grouped by object"
    elif args.rule == "paper":
        opts = {} if rigid is None else {"rigid_threshold_px": rigid}
        flags = [[clip_flags(c, rule="paper", **opts) for c in exp] for exp in clips]
        name = "paper rule" + ("" if rigid is None else f" + rigid ({rigid})")
    else:
        # Without --model, the shipped scorer of the tracks' kind (as `tacswitch slip` picks).
        kind = "markerless" if args.markerless else "marker"
        model = args.model or ("markerless" if args.markerless else "markers")
        flags = [[clip_flags(c, model=model, threshold=args.score_threshold) for c in exp]
                 for exp in clips]
        name = f"learned ({args.model or f'shipped {kind} scorer'})"
    scores = score_experiments(labels, flags, fps=[[c.fps for c in exp] for exp in clips])
    print(TABLE_HEADER)
    print(format_scores(("markerless: " if args.markerless else "markers: ") + name, scores))
    if args.json:
        from dataclasses import asdict

        from tacswitch._io import atomic_open

        per = [{"object": e.object, "experiment": e.name, "slip": e.slip,
                "called": any(bool(f.any()) for f in fl),
                "first_flag": [int(f.argmax()) if f.any() else None for f in fl],
                "videos": [str(v) for v in e.videos]} for e, fl in zip(exps, flags, strict=False)]
        with atomic_open(args.json, "w") as fh:
            # NaN (e.g. balanced accuracy without held grasps) is not JSON: null.
            values = {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                      for k, v in asdict(scores).items()}
            json.dump({"detector": name, "scores": values, "experiments": per}, fh, indent=1)
    return 0


def run_train(args: argparse.Namespace) -> int:
    from tacswitch.cli.options import UsageError, output_file

    if args.workers < 1:
        raise UsageError(f"--workers: must be >= 1; got {args.workers}")
    if args.epochs is not None and args.epochs < 1:
        raise UsageError(f"--epochs: must be >= 1; got {args.epochs}")
    if args.simulated is not None and not 0 <= args.simulated <= 1000:
        raise UsageError(f"--simulated: must be in [0, 1000]; got {args.simulated}")
    seeds, votes = _committee(args)
    if args.no_marker_tracks and not args.markerless:
        raise UsageError("--no-marker-tracks: applies to --markerless only")
    augment = _augment(args)
    slip_tail = _slip_tail(args)
    out = output_file(args.out, "--out")
    try:
        import torch  # noqa: F401
    except ImportError:
        raise ValueError("train slip: needs torch: pip install 'tacswitch[train]'") from None
    from tacswitch.grasp.train import EPOCHS, export_scorer, train_committee

    epochs = args.epochs if args.epochs is not None else EPOCHS
    from tacswitch.grasp.simulated import KINDS, SENSORS, SIMULATED_PER_KIND

    n_sim = SIMULATED_PER_KIND if args.simulated is None else args.simulated
    exps, clips = _load(args, command="train slip")
    labelled = [e.slip for e in exps]
    from tacswitch.grasp.augment import copies_phrase, marker_training_set, with_copies
    from tacswitch.grasp.dataset import clip_features

    rendered: list[list[Any]] = []
    rendered_labels: list[bool] = []
    if args.markerless:
        train, labels = with_copies(clips, labelled, augment)
        paired = _paired_marker_clips(args, exps)
        if paired is not None:
            train, labels = train + paired, labels + labelled
    else:
        train, labels, rendered, rendered_labels = marker_training_set(clips, labelled, n_sim,
                                                                       augment)
        paired = None
    # Tracked markers are read through the still-marker hysteresis (a noisy camera's still
    # markers stay still, as in the shipped scorer's recordings); predicted motion is not.
    still = not args.markerless
    feats = clip_features(train, still)
    log = None if args.quiet else (lambda s: print(s, file=sys.stderr))
    res = train_committee(feats, labels, seed=args.seed, seeds=seeds, votes=votes,
                          epochs=epochs, log=log, slip_tail=slip_tail,
                          extra=(clip_features(rendered, still), rendered_labels))
    n_rendered = 0 if args.markerless else n_sim * len(KINDS) * len(SENSORS)
    views = "" if paired is None else " (markerless and marker tracks)"
    if augment:
        views += f", {copies_phrase(augment)} of each"
    export_scorer(res, out, extra={"trained_on": f"{Path(args.data).name}: {len(exps)} "
                                                 f"experiments{views}, "
                                                 f"{sum(e.slip for e in exps)} slip; "
                                                 f"{n_rendered} rendered"},
                  still_filter=still, motion="markerless" if args.markerless else "markers")
    if not args.quiet:
        kept = (f", {res.committee} scorers, {res.votes} votes" if res.committee > 1
                else ", one scorer")
        print(f"wrote {out} ({len(exps)} experiments{views}, {sum(e.slip for e in exps)} "
              f"slip, {n_rendered} rendered grasps, {epochs} epochs{kept})")
    return 0
