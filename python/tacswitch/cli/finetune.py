"""``tacswitch finetune --images DIR``: adapt TacDiff to your own marker sensor (needs torch).

The paper's marker-offset strategy, made to look like inference: your frames have markers and no
ground truth, so each frame's markers are removed by TELEA (a pseudo-markerless frame, never a
loss target), and each real marker's appearance (its darkening relative to the gel, soft edge
and compression ring included) is transplanted about half a marker pitch away, onto real gel.
The network learns to fill those moved markers with the mask remove_markers would use; the loss
sees only their real gel pixels. ``--no-transplant`` cuts clean shifted holes instead (the
paper's variant). Starts from the shipped model's weights; resumable (rerun the command);
writes ``OUT/model.onnx`` for ``remove_markers(..., method="tacdiff", model=...)``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tacswitch.tacdiff.transplant import DEFAULT_RING


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("finetune", help="fine-tune TacDiff on your own marker frames (torch)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--images", required=True, nargs="+",
                   help="frames (files or folders) from your sensor, with markers")
    p.add_argument("--out", required=True, help="run folder (checkpoint, log, model.onnx)")
    p.add_argument("--offset", default=None, metavar="DX,DY",
                   help="mask shift in px (default: half the estimated marker pitch, rounded "
                        "to a multiple of 8 px with transplanted markers)")
    p.add_argument("--no-transplant", dest="transplant", action="store_false",
                   help="clean shifted holes in the TELEA frame (the paper) instead of moved "
                        "real markers")
    p.add_argument("--ring", type=int, default=DEFAULT_RING,
                   help="px beyond the removal mask over which a marker's darkening is "
                        "measured and moved (default: %(default)s)")
    p.add_argument("--steps", type=int, default=1500, help="training steps (default: 1500)")
    p.add_argument("--batch", type=int, default=12)
    p.add_argument("--crop", type=int, default=96, help="crop side, multiple of 16")
    p.add_argument("--lr", type=float, default=2e-4)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--init", default=None,
                   help="starting weights: 'default' or 'fast' (a shipped model), or a "
                        ".safetensors, checkpoint or TacDiff .onnx file (default: the shipped "
                        "default model's)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise ValueError('fine-tuning needs torch: pip install "tacswitch[train]"') from None
    from tacswitch._io import read_image
    from tacswitch.cli.sources import collect_images
    from tacswitch.tacdiff.data import marker_offset_pairs
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.infer import default_weights_path, model_path
    from tacswitch.tacdiff.train import TrainConfig, load_network, train

    files = collect_images(args.images)
    frames = [read_image(f) for f in files]
    offset = None
    if args.offset is not None:
        try:
            dx, dy = (int(v) for v in args.offset.split(","))
        except ValueError:
            raise ValueError(f"--offset: expected DX,DY in px; got {args.offset!r}") from None
        offset = (dx, dy)
    if args.ring < 0:
        raise ValueError(f"--ring: must be >= 0 px; got {args.ring}")
    pairs = marker_offset_pairs(frames, offset=offset, transplant=args.transplant,
                                ring=args.ring)
    if not pairs["loss_mask"].any():
        raise ValueError("--images: no shifted marker pixel lands on real gel; pass --offset")
    init = model_path(args.init) if args.init else default_weights_path()
    arch = load_network(init).cfg
    cfg = TrainConfig(base=arch.base, mults=arch.mults, attention=arch.attention,
                      prior=arch.prior,
                      steps=args.steps, batch=args.batch, crop=args.crop, lr=args.lr,
                      warmup=min(100, args.steps // 10), seed=args.seed,
                      extra={"finetune": [str(f) for f in files], "offset": offset,
                             "transplant": args.transplant, "ring": args.ring})
    net = train([pairs], args.out, cfg, progress=not args.quiet, init=init)
    path = export_onnx(net, Path(args.out) / "model.onnx",
                       metadata={"finetuned_on": len(files), "steps": args.steps,
                                 "seed": args.seed, "transplant": args.transplant})
    if not args.quiet:
        print(f"exported {path}")
    return 0
