"""``tacswitch evaluate motion``: the paper's motion metrics and slip detection on held-out
synthetic data, for the regressor, a zero-motion baseline and tracking on true marker images."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tacswitch.cli import downstream_cmds, slip_cmds, tacdiff_cmds
from tacswitch.cli.options import UsageError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("evaluate", help="score slip on your labelled grasp videos, or a "
                       "motion or removal model on held-out data")
    what = p.add_subparsers(dest="what", required=True, metavar="MODEL")
    m = what.add_parser("motion", help="markerless -> marker motion regressor",
                        description=__doc__)
    m.add_argument("--data", required=True,
                   help="folder of held-out shards (rendered there if missing, resumable)")
    m.add_argument("--n", type=int, default=300, help="samples per held-out split")
    m.add_argument("--model", default=None, help="ONNX model (default: the shipped one)")
    m.add_argument("--preset", default="gelsight_mini",
                   help="simulator preset of the held-out frames (default: %(default)s)")
    m.add_argument("--slip", type=int, default=6, metavar="K",
                   help="grasp sequences per kind (slip/hold/vibration) for slip detection; "
                        "0: skip")
    m.add_argument("--seed", type=int, default=1, help="random seed (default: %(default)s)")
    m.add_argument("--json", default=None, help="also write the results to this JSON file")
    m.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    m.set_defaults(run=run)
    tacdiff_cmds.add_evaluate_parser(what)
    slip_cmds.add_evaluate_parser(what)
    downstream_cmds.add_evaluate_parser(what)


#: Held-out splits (see tacswitch.motion.data): unseen depth, unseen indenter, pure presses.
SPLITS = ("test_depth", "test_indenter", "test_press")


def _fmt(v: float) -> str:
    return f"{v:.3f}" if v == v else "-"


def run(args: argparse.Namespace) -> int:
    if args.n < 2:
        raise UsageError(f"--n: must be >= 2 (the press and pair splits use n // 2); got {args.n}")
    if args.slip < 0:
        raise UsageError(f"--slip: must be >= 0 (0 skips slip detection); got {args.slip}")
    from tacswitch._io import atomic_open
    from tacswitch.motion import data as mdata
    from tacswitch.motion.evaluate import evaluate_slip, evaluate_split
    from tacswitch.motion.infer import load_model

    model = load_model(args.model)
    pitch = __import__("tacswitch.sim.presets", fromlist=["get_preset"]).get_preset(
        args.preset).pitch
    results: dict = {"model": str(model.path), "arch": model.arch, "use_ref": model.use_ref}
    for split in SPLITS:
        n = args.n if split != "test_press" else args.n // 2
        mdata.generate_split(args.data, split, n, preset=args.preset, seed=args.seed,
                             markers=True, progress=not args.quiet, shard=150)
        arrays = mdata.load_split(args.data, split)
        results[split] = evaluate_split(arrays, lambda i, r, c: model(i, ref=r, centres=c),
                                        use_ref=model.use_ref, pitch=pitch)
    # Pair models, and the consistent design (its reference is optional), are also scored on
    # motion since an earlier contact frame.
    pair = "pair_train" in model.metadata.get("tacswitch.trained_on", "") or \
        getattr(model, "design", "plain") == "consistent"
    if pair:
        # Motion since an earlier contact frame (what the model was trained for).
        mdata.generate_split(args.data, "pair_test_indenter", args.n // 2, preset=args.preset,
                             seed=args.seed, progress=not args.quiet, shard=150)
        arrays = mdata.load_split(args.data, "pair_test_indenter")
        results["pair_test_indenter"] = evaluate_split(
            arrays, lambda i, r, c: model(i, ref=r, centres=c), use_ref=True, pitch=pitch)
    if args.slip:
        ref_frame = "grasp_start" if pair else "no_contact" if model.use_ref else "none"
        results["slip"] = evaluate_slip(lambda i, r, c: model(i, ref=r, centres=c),
                                        preset=args.preset, n_per_kind=args.slip,
                                        ref_frame=ref_frame)
    if not args.quiet:
        print("| split | method | e_rmse mean | e_rmse median | e_mag mean | e_mag median | "
              "NaN % | orient mean (deg, >=3 px) |")
        print("|---|---|---|---|---|---|---|---|")
        for split in [s for s in (*SPLITS, "pair_test_indenter") if s in results]:
            for meth, r in results[split].items():
                print(f"| {split} | {meth} | {_fmt(r['e_rmse_mean'])} | "
                      f"{_fmt(r['e_rmse_median'])} | {_fmt(r['e_mag_mean'])} | "
                      f"{_fmt(r['e_mag_median'])} | {r['nan_pct']:.2f} | "
                      f"{_fmt(r['orient_mean_deg'])} |")
        if args.slip:
            for src, r in results["slip"].items():
                print(f"slip ({src}): accuracy {r['accuracy']:.3f} ({r['correct']}/{r['n']}), "
                      f"false alarms {r['false_alarms']}, missed {r['missed']}, "
                      f"delay {r['delays']} frames")
    if args.json:
        with atomic_open(Path(args.json)) as fh:
            json.dump(results, fh, indent=1)
    return 0
