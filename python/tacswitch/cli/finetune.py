"""``tacswitch finetune --images DIR``: adapt TacDiff to your own marker sensor (needs torch).

The paper's marker-offset strategy: your frames have markers and no ground truth, so each frame's
markers are removed by TELEA (a pseudo-markerless frame, never used as a target), the marker mask
is shifted by about half the marker pitch, and the network learns to fill the shifted holes,
which lie on real gel pixels (shifted pixels on an original marker or outside the frame are
dropped from the loss). Starts from the shipped model's weights; resumable (rerun the command);
writes ``OUT/model.onnx`` for ``remove_markers(..., method="tacdiff", model=...)``.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("finetune", help="fine-tune TacDiff on your own marker frames (torch)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--images", required=True, nargs="+",
                   help="frames (files or folders) from your sensor, with markers")
    p.add_argument("--out", required=True, help="run folder (checkpoint, log, model.onnx)")
    p.add_argument("--offset", default=None, metavar="DX,DY",
                   help="mask shift in px (default: half the estimated marker pitch)")
    p.add_argument("--steps", type=int, default=1500, help="training steps (default: 1500)")
    p.add_argument("--batch", type=int, default=12)
    p.add_argument("--crop", type=int, default=96, help="crop side, multiple of 16")
    p.add_argument("--lr", type=float, default=2e-4)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--init", default=None,
                   help="starting weights (.safetensors or checkpoint; default: the shipped "
                        "model's)")
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
    from tacswitch.tacdiff.infer import default_weights_path
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
    pairs = marker_offset_pairs(frames, offset=offset)
    if not pairs["loss_mask"].any():
        raise ValueError("--images: no shifted marker pixel lands on real gel; pass --offset")
    init = Path(args.init) if args.init else default_weights_path()
    arch = load_network(init).cfg
    cfg = TrainConfig(base=arch.base, mults=arch.mults, attention=arch.attention,
                      prior=arch.prior,
                      steps=args.steps, batch=args.batch, crop=args.crop, lr=args.lr,
                      warmup=min(100, args.steps // 10), seed=args.seed,
                      extra={"finetune": [str(f) for f in files], "offset": offset})
    net = train([pairs], args.out, cfg, progress=not args.quiet, init=init)
    path = export_onnx(net, Path(args.out) / "model.onnx",
                       metadata={"finetuned_on": len(files), "steps": args.steps,
                                 "seed": args.seed})
    if not args.quiet:
        print(f"exported {path}")
    return 0
