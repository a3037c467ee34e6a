"""``tacswitch train motion``: train the markerless -> marker motion regressor (needs torch).

Data: synthetic pairs rendered into ``--data`` (``--simulate N``; resumable shards), or a user's
own marker sensor (``--frames DIR --reference IMG``): ground-truth motions from the marker
tracker, markerless inputs from TELEA (``tacswitch.remove_markers``). ``--videos`` trains the
consistent model on a marker sensor's videos (:mod:`tacswitch.motion.real_pairs`: markers
tracked for the targets, removed with a grown mask for the inputs; CPU or GPU).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tacswitch.cli import slip_cmds, tacdiff_cmds


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help="train a learned model (needs tacswitch[train])",
                       description="Trains a model; resumable: rerun the same command to continue.")
    what = p.add_subparsers(dest="what", required=True, metavar="MODEL")
    m = what.add_parser("motion", help="markerless -> marker motion regressor",
                        description=__doc__)
    m.add_argument("--out", required=True, help="run folder (checkpoint, log.jsonl, model.onnx)")
    m.add_argument("--data", default=None, help="folder of synthetic shards (train_*.npz)")
    m.add_argument("--split", default="train", choices=("train", "pair_train", "gel_train"),
                   help="train: frame vs the no-contact reference; pair_train: frame vs an "
                        "earlier frame of the same contact (motion since then; needs --use-ref); "
                        "gel_train: pairs with random sensor looks, moving gel grain and capture "
                        "degradations, both frames' motions from rest (for --design consistent)")
    m.add_argument("--design", choices=("plain", "consistent"), default="plain",
                   help="consistent: identical frames give exactly zero motion, brightness is "
                        "normalised in the graph, the reference frame is optional (needs "
                        "--split gel_train)")
    m.add_argument("--simulate", type=int, default=0, metavar="N",
                   help="render N synthetic training samples into --data first (resumable)")
    m.add_argument("--preset", default="gelsight_mini",
                   help="simulator preset (default: %(default)s)")
    m.add_argument("--frames", default=None,
                   help="folder of frames from your marker sensor (instead of --data)")
    m.add_argument("--reference", default=None,
                   help="no-contact frame of your marker sensor (with --frames)")
    m.add_argument("--videos", nargs="+", default=None, metavar="VIDEO",
                   help="videos of your marker sensor, or folders of them (instead of --data): "
                        "each video's first frame is its no-contact rest unless --reference is "
                        "given; trains the consistent model (pair and single frame) for --steps "
                        "steps, writes OUT/model.onnx and OUT/single.onnx")
    m.add_argument("--every", type=int, default=3,
                   help="--videos: keep every N-th frame (default: %(default)s)")
    m.add_argument("--grow-px", type=int, default=4,
                   help="--videos: grow the marker mask by this many px before the fill, so no "
                        "trace of a dot is left to follow (default: %(default)s)")
    m.add_argument("--mask", choices=("static", "per-frame"), default="static",
                   help="--videos: static (default): every kept frame of a video filled on one "
                        "mask, the union of its marker masks, so the fills' places say nothing "
                        "of the motion; per-frame: each frame on its own markers' mask (the "
                        "model learns to follow the fills, which a markerless gel does not "
                        "have: it then predicts false motion on truly markerless frames)")
    m.add_argument("--steps", type=int, default=3000,
                   help="--videos: training steps (default: %(default)s)")
    m.add_argument("--workers", type=int, default=1,
                   help="--videos: processes that track and clean the videos (default: "
                        "%(default)s)")
    m.add_argument("--device", choices=("auto", "cpu", "cuda"), default="auto",
                   help="--videos: where to train (auto: a CUDA GPU when torch sees one)")
    m.add_argument("--arch", choices=("unet", "lraspp", "deeplabv3"), default="unet",
                   help="unet: the light default; deeplabv3: the paper's reference")
    m.add_argument("--use-ref", action="store_true",
                   help="also feed the markerless no-contact reference frame to the network")
    m.add_argument("--loss", choices=("mse", "euclid"), default="euclid",
                   help="mse: the paper's; euclid: mean per-marker Euclidean error, the metric "
                        "itself (default)")
    m.add_argument("--epochs", type=int, default=8,
                   help="passes over the training data (default: %(default)s)")
    m.add_argument("--batch", type=int, default=16,
                   help="training batch size (default: %(default)s)")
    m.add_argument("--lr", type=float, default=2e-3,
                   help="learning rate (default: %(default)s)")
    m.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    m.add_argument("--max-steps", type=int, default=0,
                   help="cap on steps per epoch (0: whole data set)")
    m.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    m.set_defaults(run=run)
    tacdiff_cmds.add_train_parser(what)
    slip_cmds.add_train_parser(what)


def _check(args: argparse.Namespace) -> None:
    """Option values that cannot work (before torch is even looked for)."""
    from tacswitch.cli.options import UsageError, preset_option

    if (args.design == "consistent") != (args.split == "gel_train"):
        raise UsageError("--design consistent and --split gel_train go together (the design "
                         "trains on both frames' motions from rest, which only gel_ splits hold)")
    if args.split == "pair_train" and not args.use_ref:
        raise UsageError("--split pair_train: the targets are motions since an earlier frame, "
                         "which the network only sees with --use-ref")
    if args.videos is not None and (args.frames is not None or args.data is not None):
        raise UsageError("--videos: give either --videos, --frames or --data")
    if args.frames is not None and args.reference is None:
        raise UsageError("--reference: needed with --frames (the no-contact frame)")
    if args.frames is None and args.data is None and args.videos is None:
        raise UsageError("--data: give a data folder (or --frames / --videos for your own "
                         "sensor)")
    for flag, value, low in (("--epochs", args.epochs, 1), ("--batch", args.batch, 1),
                             ("--simulate", args.simulate, 0), ("--seed", args.seed, 0),
                             ("--max-steps", args.max_steps, 0), ("--every", args.every, 1),
                             ("--grow-px", args.grow_px, 0), ("--steps", args.steps, 1),
                             ("--workers", args.workers, 1)):
        if value < low:
            raise UsageError(f"{flag}: must be >= {low}; got {value}")
    if not args.lr > 0 or args.lr == float("inf"):
        raise UsageError(f"--lr: must be a positive number; got {args.lr}")
    if args.preset != "mixed":
        preset_option(args.preset)


def run(args: argparse.Namespace) -> int:
    _check(args)
    try:
        import torch  # noqa: F401
    except ImportError:
        raise ValueError('training needs torch: pip install "tacswitch[train]"') from None
    if args.videos is not None:
        return _run_videos(args)
    from tacswitch.motion import data as mdata
    from tacswitch.motion.export import export_onnx
    from tacswitch.motion.train import TrainConfig, train

    if args.frames is not None:
        arrays = mdata.pairs_from_marker_frames(args.frames, args.reference,
                                                progress=not args.quiet)
        source: dict[str, object] = {"frames": str(args.frames),
                                     "reference": str(args.reference)}
    else:
        if args.simulate:
            mdata.generate_split(args.data, args.split, args.simulate, preset=args.preset,
                                 seed=args.seed, progress=not args.quiet)
        arrays = mdata.load_split(args.data, args.split)
        source = {"data": str(args.data), "split": args.split, "preset": args.preset,
                  "n": len(arrays["image"])}
    cfg = TrainConfig(arch=args.arch, use_ref=bool(args.use_ref), loss=args.loss,
                      epochs=args.epochs,
                      batch=args.batch, lr=args.lr, seed=args.seed,
                      max_steps_per_epoch=args.max_steps, design=args.design)
    net = train(arrays, args.out, cfg, progress=not args.quiet)
    h, w = arrays["image"].shape[1:3]
    # Default read-out grid of predict_motion: the preset's ideal grid (sim) or the user's markers.
    grid_preset = "gelsight_mini" if args.preset == "mixed" else args.preset
    rest = arrays["rest"][0] if args.frames is not None else mdata.preset_grid(grid_preset)
    meta = {"work_width": int(w), "work_height": int(h), "seed": args.seed,
            "default_centres": [[round(float(x), 3), round(float(y), 3)] for x, y in rest],
            "trained_on": source, "epochs": args.epochs, "loss": args.loss}
    path = export_onnx(net, Path(args.out) / "model.onnx", metadata=meta, height=h, width=w)
    if not args.quiet:
        print(f"exported {path}")
    return 0


def _run_videos(args: argparse.Namespace) -> int:
    """``--videos``: pairs from the marker videos, then :func:`train_real`."""
    from tacswitch._io import read_image
    from tacswitch.motion.real_pairs import pairs_from_videos
    from tacswitch.motion.train_real import RealTrainConfig, train_real

    ref = read_image(args.reference, "--reference") if args.reference else None
    pairs = pairs_from_videos(args.videos, ref, every=args.every, grow_px=args.grow_px,
                              static=args.mask == "static", seed=args.seed, workers=args.workers,
                              progress=not args.quiet)
    cfg = RealTrainConfig(steps=args.steps, batch=args.batch, lr=args.lr, seed=args.seed,
                          device=args.device, loss=args.loss)
    try:
        last = train_real(pairs, args.out, cfg, progress=not args.quiet)
    except ValueError as exc:
        if "device" in str(exc):
            raise ValueError(f"--device: {exc}") from None
        raise
    if not args.quiet:
        scores = ", ".join(f"{k} {v:.3f}" for k, v in last.items())
        print(f"validation (held-out videos): {scores or 'none (one video)'}")
        print(f"exported {Path(args.out) / 'model.onnx'} and {Path(args.out) / 'single.onnx'}")
    return 0
