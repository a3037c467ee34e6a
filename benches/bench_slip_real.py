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
  a model that never saw its object (``--seeds`` repeats the whole protocol with other seeds);
- ``--markerless``: the same on the markerless sensor each video would have been (markers
  removed, motion predicted by ``MarkerlessTracker``), scorer trained on markers.

``--export PATH`` trains on every experiment and writes the scorer (the shipped models:
``python/tacswitch/models/slip_scorer.onnx``, and with ``--markerless``
``slip_scorer_markerless.onnx``).

    python benches/bench_slip_real.py [--data DIR] [--seeds 3] [--workers 2] [--markerless]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tacswitch.grasp.crossval import clip_flags, cross_validated_flags
from tacswitch.grasp.dataset import experiment_clips, read_labels
from tacswitch.grasp.evaluate import TABLE_HEADER, format_scores, score_experiments

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared/data/real/gsmini_slip_train"
CACHE = Path(__file__).resolve().parents[1] / "bench-results" / "slip_real"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--epochs", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--markerless", action="store_true")
    ap.add_argument("--export", type=Path, default=None)
    ap.add_argument("--no-rules", action="store_true", help="skip the paper-rule rows")
    args = ap.parse_args()

    exps = read_labels(args.data)
    labels = [e.slip for e in exps]
    objects = [e.object for e in exps]
    t0 = time.perf_counter()
    clips = experiment_clips(exps, CACHE, workers=args.workers, progress=True)
    print(f"tracked {sum(len(c) for c in clips)} videos in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    if args.export is not None:
        from tacswitch.grasp.train import EPOCHS, export_scorer, train_scorer

        if args.markerless:
            clips = experiment_clips(exps, CACHE, markerless=True, workers=args.workers)
        res = train_scorer([[c.features() for c in exp] for exp in clips], labels,
                           epochs=args.epochs or EPOCHS, seed=0,
                           log=lambda s: print(s, file=sys.stderr))
        motion = "markers removed, MarkerlessTracker" if args.markerless else "markers"
        export_scorer(res, args.export, extra={
            "trained_on": f"{args.data.name}: {len(exps)} experiments, "
                          f"{len(set(objects))} objects (real GelSight Mini, {motion})"})
        print(f"wrote {args.export}")
        return 0
    print(f"REAL GelSight Mini grasps: {len(exps)} experiments, {len(set(objects))} objects, "
          f"{sum(labels)} slip; an experiment is slip when any frame of either finger is "
          f"flagged.\n")
    print(TABLE_HEADER)
    if not args.no_rules:
        for name, opts in (("paper rule (displacement from the grasp start)", {}),
                           ("paper rule + rigid (auto)", {"rigid_threshold_px": "auto"})):
            flags = [[clip_flags(c, rule="paper", **opts) for c in exp] for exp in clips]
            print(format_scores(f"markers: {name}", score_experiments(labels, flags)),
                  flush=True)
    test = None
    if args.markerless:
        test = experiment_clips(exps, CACHE, markerless=True, workers=args.workers,
                                progress=True)
    for seed in range(args.seeds):
        flags = cross_validated_flags(clips, labels, objects, seed=seed, epochs=args.epochs,
                                      test_sets={"markerless": test} if test else None)
        print(format_scores(f"markers: learned, objects held out (5 folds, seed {seed})",
                            score_experiments(labels, flags["train"])), flush=True)
        if test is not None:
            print(format_scores(f"markerless: the marker scorer, objects held out (seed "
                                f"{seed})", score_experiments(labels, flags["markerless"])),
                  flush=True)
            own = cross_validated_flags(test, labels, objects, seed=seed, epochs=args.epochs)
            print(format_scores(f"markerless: learned on markerless motion, objects held out "
                                f"(seed {seed})", score_experiments(labels, own["train"])),
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
