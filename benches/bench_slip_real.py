"""Slip detection on REAL GelSight Mini grasps (lift and shake; some slip), objects held out.

Data: a folder laid out as ``tacswitch evaluate slip`` reads it (``labels.csv`` with object,
experiment, slip; ``OBJECT/EXPERIMENT/*.avi``, one video per finger), by default the training
split of the public GelSight Mini slip study (``../shared/data/real/gsmini_slip_train``: 150
experiments, 29 objects, 65 slip). Every video is tracked once (cached under
``bench-results/slip_real``). An experiment counts as slip when any frame of either finger is
flagged, online and causally.

Rows:
- the paper's displacement rule from the detected grasp start, and with the rigid criterion
  (what ``tacswitch slip --rule paper`` does), on every experiment (nothing is fitted);
- the learned scorer, 5-fold cross-validation grouped by object: every experiment is scored by
  a model that never saw its object. Each fold trains the recipe (``train_committee``: 32
  scorers from consecutive seeds, a grasp flagged once 13 have fired in it, for the markerless
  scorers too); ``--seeds``
  repeats the whole protocol from other first seeds, ``--committee 1`` trains one scorer per
  fold, ``--votes`` sets the votes. Every fold's training set also holds the rendered grasps
  (``--simulated``; for half the members only: the others train on the real grasps alone) and
  ``--augment`` rescaled copies of each of its real experiments
  (``tacswitch.grasp.augment``: displacements scaled and time resampled; none in the recipe);
- ``--markerless``: the same on the markerless sensor each video would have been (markers
  removed, motion predicted by ``MarkerlessTracker``): the marker scorer, a scorer trained on
  the markerless tracks alone, and one trained on them and the same experiments' marker
  tracks (the recipe since 2026-11-28; only the training objects' tracks, never the held-out
  fold's), each a committee as above. ``--no-marker-scorer`` skips the marker scorer's own
  cross-validation.

``--export PATH`` trains on every experiment and writes the scorer (the shipped models:
``python/tacswitch/models/slip_scorer.onnx``, and with ``--markerless``
``slip_scorer_markerless.onnx``, trained on the markerless and the marker tracks).

    python benches/bench_slip_real.py [--data DIR] [--seeds 3] [--workers 2] [--markerless]
        [--committee 32] [--votes 13] [--augment 0] [--simulated 24]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tacswitch.grasp.augment import COPIES, copies_phrase, marker_training_set, with_copies
from tacswitch.grasp.crossval import clip_flags, cross_validated_flags
from tacswitch.grasp.dataset import (
    Experiment,
    TrackedClip,
    clip_features,
    experiment_clips,
    read_labels,
)
from tacswitch.grasp.detector import (
    SCORER_FLOW_PRESET,
    SCORER_FRAME_TO_FRAME,
    SCORER_REMOVAL_TEXT,
)
from tacswitch.grasp.evaluate import TABLE_HEADER, format_scores, score_experiments
from tacswitch.grasp.simulated import SIMULATED_PER_KIND, SIMULATED_SEED, simulated_clips
from tacswitch.grasp.train import (
    committee_votes,
    default_committee_text,
    real_only_members,
    recipe_committee,
    recipe_slip_tail,
    train_committee,
)

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared/data/real/gsmini_slip_train"
CACHE = Path(__file__).resolve().parents[1] / "bench-results" / "slip_real"


Flags = list[list[NDArray[np.bool_]]]


def shipped_committee_as_recorded(data: Path, workers: int, recorded: str, first_row: str, *,
                                  still_filter: bool | None = None
                                  ) -> tuple[list[Experiment], list[bool],
                                             list[list[TrackedClip]], Flags]:
    """The preamble of the benches that vary the real grasps (rate, codec, light, start): the
    experiments, labels and tracked clips (cached), the table header, and the shipped marker
    committee's row on the grasps ``recorded`` (how they were recorded), named ``first_row``.
    The committee was trained on these grasps: the rows after it measure what a change does to
    the same decisions, not accuracy on new objects. ``still_filter``: the detector's option
    (None: as the committee's metadata says)."""
    exps = read_labels(data)
    labels = [e.slip for e in exps]
    clips = experiment_clips(exps, CACHE, workers=workers, progress=True)
    print(f"REAL GelSight Mini grasps ({recorded}): {len(exps)} experiments, "
          f"{len({e.object for e in exps})} objects, {sum(labels)} slip; the shipped marker "
          "committee (trained on them as recorded); an experiment is slip when any frame of "
          "either finger is flagged.\n")
    print(TABLE_HEADER)
    flags = [[clip_flags(c, model="markers", still_filter=still_filter) for c in exp]
             for exp in clips]
    print(format_scores(first_row, score_experiments(labels, flags)), flush=True)
    return exps, labels, clips, flags


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--epochs", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--markerless", action="store_true")
    ap.add_argument("--no-still-filter", action="store_true",
                    help="marker scorers read the tracks as tracked (before 2026-11-29: no "
                         "still-marker hysteresis)")
    ap.add_argument("--export", type=Path, default=None)
    ap.add_argument("--no-rules", action="store_true", help="skip the paper-rule rows")
    ap.add_argument("--no-marker-scorer", action="store_true",
                    help="--markerless: skip the marker scorer's cross-validation")
    ap.add_argument("--committee", type=int, default=None,
                    help="scorers per model, from consecutive seeds (default: "
                         f"{default_committee_text('markerless scorers')}; 1: one scorer)")
    ap.add_argument("--votes", type=int, default=None,
                    help="members that must fire in a grasp (default: the recipe's)")
    ap.add_argument("--simulated", type=int, default=SIMULATED_PER_KIND,
                    help="rendered grasps per kind and sensor added to every training set "
                         "of the marker scorer (default: %(default)s; 0: real grasps only)")
    ap.add_argument("--augment", type=int, default=COPIES,
                    help="rescaled copies of each real experiment in the marker scorer's "
                         "training set (the training objects' only; default: %(default)s)")
    ap.add_argument("--slip-tail", type=float, default=None,
                    help="the share of each cut-short slip video that may carry its label in "
                         "training (tacswitch.grasp.train.counted_from; default: the recipe's, "
                         f"{recipe_slip_tail()} for the marker scorer's real-only members, "
                         f"{recipe_slip_tail(True)} for the markerless scorer)")
    args = ap.parse_args()
    # Each path trains with its own recipe's share unless one is given.
    tail, markerless_tail = ({"slip_tail": recipe_slip_tail(m) if args.slip_tail is None
                              else args.slip_tail} for m in (False, True))

    exps = read_labels(args.data)
    labels = [e.slip for e in exps]
    objects = [e.object for e in exps]
    t0 = time.perf_counter()
    clips = experiment_clips(exps, CACHE, workers=args.workers, progress=True)
    print(f"tracked {sum(len(c) for c in clips)} videos in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    # --committee sets both; by default each path trains the recipe's committee.
    marker_seeds, markerless_seeds = ((args.committee, args.committee)
                                      if args.committee is not None
                                      else (recipe_committee(), recipe_committee(True)))
    if args.export is not None:
        from tacswitch.grasp.train import export_scorer

        if args.markerless:
            # The markerless tracks and, for the same experiments, the marker tracks.
            markerless = experiment_clips(exps, CACHE, markerless=True, workers=args.workers)
            clips = markerless + clips
            labels = labels + labels
            rendered, rendered_labels = [], []
        else:
            clips, labels, rendered, rendered_labels = marker_training_set(
                clips, labels, args.simulated, args.augment)
        still = not args.markerless and not args.no_still_filter
        res = train_committee(clip_features(clips, still), labels,
                              seeds=markerless_seeds if args.markerless else marker_seeds,
                              votes=args.votes, epochs=args.epochs,
                              log=lambda s: print(s, file=sys.stderr),
                              extra=(clip_features(rendered, still), rendered_labels),
                              **(markerless_tail if args.markerless else tail))
        motion = (f"markers removed by remove_markers(frame, {SCORER_REMOVAL_TEXT}), "
                  f"MarkerlessTracker ({SCORER_FLOW_PRESET} flow, frame_to_frame="
                  f"{SCORER_FRAME_TO_FRAME:g}); and the marker tracks"
                  if args.markerless else "markers")
        export_scorer(res, args.export, extra={
            "trained_on": f"{args.data.name}: {len(exps)} experiments, "
                          f"{len(set(objects))} objects (real GelSight Mini, {motion})"},
                      still_filter=still, motion="markerless" if args.markerless else "markers")
        print(f"wrote {args.export}")
        return 0
    print(f"REAL GelSight Mini grasps: {len(exps)} experiments, {len(set(objects))} objects, "
          f"{sum(labels)} slip; an experiment is slip when any frame of either finger is "
          f"flagged.\n")
    print(TABLE_HEADER)
    if not args.no_rules:
        for name, opts in (("paper rule (displacement from the grasp start)", {}),
                           ("paper rule + rigid (auto)", {"rigid_threshold_px": "auto"})):
            rule_flags = [[clip_flags(c, rule="paper", **opts) for c in exp] for exp in clips]
            print(format_scores(f"markers: {name}", score_experiments(labels, rule_flags)),
                  flush=True)
    extra = None
    if args.simulated:
        sim_clips, sim_labels = simulated_clips(args.simulated, SIMULATED_SEED)
        extra = ([[c] for c in sim_clips], sim_labels)
    test = None
    if args.markerless:
        test = experiment_clips(exps, CACHE, markerless=True, workers=args.workers,
                                progress=True)
    marker_scorer = not (args.markerless and args.no_marker_scorer)
    # The marker scorers read the tracks through the still-marker hysteresis (as shipped).
    still = not args.no_still_filter
    for seed in range(args.seeds):
        if marker_scorer:
            flags = cross_validated_flags(clips, labels, objects, seed=seed * marker_seeds,
                                          epochs=args.epochs,
                                          test_sets={"markerless": test} if test else None,
                                          extra=extra, seeds=marker_seeds, votes=args.votes,
                                          augment=args.augment, still_filter=still, **tail)
            with_sim = f" + {copies_phrase(args.augment)}" if args.augment else ""
            if extra:
                alone = real_only_members(marker_seeds, True)
                with_sim += (f" + {len(extra[1])} rendered grasps (not for {alone} members, "
                             f"on the real grasps alone)" if alone
                             else f" + {len(extra[1])} rendered grasps")
            print(format_scores(f"markers: learned{with_sim}, "
                                f"{committee_name(marker_seeds, args.votes)}, objects held out "
                                f"(5 folds, seed {seed * marker_seeds})",
                                score_experiments(labels, flags["train"])), flush=True)
        if test is not None:
            if marker_scorer:
                print(format_scores(f"markerless: the marker scorer, objects held out (seed "
                                    f"{seed})", score_experiments(labels, flags["markerless"])),
                      flush=True)
            first = seed * markerless_seeds
            committee = committee_name(markerless_seeds, args.votes)
            own = cross_validated_flags(test, labels, objects, seed=first, epochs=args.epochs,
                                        seeds=markerless_seeds, votes=args.votes,
                                        **markerless_tail)
            print(format_scores(f"markerless: learned on markerless motion, {committee}, "
                                f"objects held out (seed {first})",
                                score_experiments(labels, own["train"])), flush=True)
            both = cross_validated_flags(test, labels, objects, seed=first, epochs=args.epochs,
                                         seeds=markerless_seeds, votes=args.votes, paired=clips,
                                         **markerless_tail)
            print(format_scores(f"markerless: learned on markerless + marker motion, "
                                f"{committee}, objects held out (seed {first})",
                                score_experiments(labels, both["train"])), flush=True)
    if extra is not None and marker_scorer:
        from tacswitch.grasp.crossval import torch_scorer

        # Simulated grasps of seeds never trained on nor validated on, scored by the scorer
        # trained on every real experiment and the rendered training grasps (as shipped).
        held, held_labels = simulated_clips(HELD_OUT_SIM, HELD_OUT_SIM_SEED)
        # The rendered grasps are those of ``extra`` (rendered once).
        real, real_labels = with_copies(clips, labels, args.augment)
        res = train_committee(clip_features(real, still), real_labels,
                              seeds=marker_seeds, votes=args.votes, epochs=args.epochs,
                              extra=(clip_features(extra[0], still), extra[1]), **tail)
        scorer = torch_scorer(res.net)
        flags_sim = [[clip_flags(c, model=scorer, threshold=0.0, votes=res.votes,
                                 still_filter=still, half_vote=res.half_vote)] for c in held]
        paper_sim = [[clip_flags(c, rule="paper")] for c in held]
        print(format_scores(f"SIMULATED held-out grasps ({len(held)}: slip / hold / vibration, "
                            "GelSight + Mini): learned", score_experiments(held_labels, flags_sim)))
        print(format_scores("SIMULATED held-out grasps: paper rule",
                            score_experiments(held_labels, paper_sim)))
    return 0


def committee_name(seeds: int, votes: int | None) -> str:
    """How a row names its scorer: the committee and its votes, or one scorer."""
    return (f"{seeds} scorers, {committee_votes(seeds, votes)} votes" if seeds > 1
            else "one scorer")


#: Rendered grasps per kind and sensor scored as a second, simulated test set.
HELD_OUT_SIM = 6
HELD_OUT_SIM_SEED = 3000


if __name__ == "__main__":
    raise SystemExit(main())
