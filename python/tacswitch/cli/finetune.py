"""``tacswitch finetune --images DIR``: adapt TacDiff to your own marker sensor (needs torch).

The paper's marker-offset strategy, made to look like inference: your frames have markers and no
ground truth, so each frame's markers are removed by the start model's own fill (``--pseudo
model``, the default; ``--pseudo telea``: TELEA), a pseudo-markerless frame, never a loss
target, and each real marker's appearance (its darkening relative to the gel, soft edge
and compression ring included) is transplanted about half a marker pitch away, onto real gel
(``--shifts``: in several directions, for more training gel from the same frames).
The network learns to fill those moved markers with the mask remove_markers would use; the loss
sees only their real gel pixels. ``--no-transplant`` cuts clean shifted holes instead (the
paper's variant). Starts from the shipped model's weights; resumable (rerun the command).

The fine-tune checks itself without ground truth: a share of the frames is held out, their
markers are transplanted by another shift (gel never trained on), and the starting model and
the EMA weights every ``--val-every`` steps fill them. ``OUT/model.onnx`` (for
``remove_markers(..., method="tacdiff", model=...)``) is the best checkpoint if it beats the
starting model beyond noise, otherwise the starting model itself; the last line says which,
``OUT/finetune.json`` has every score.
"""

from __future__ import annotations

import argparse

from tacswitch.tacdiff.finetune import DEFAULT_SHIFTS, DEFAULT_STEPS  # numpy only
from tacswitch.tacdiff.train import LOSSES
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
    p.add_argument("--shifts", type=int, default=DEFAULT_SHIFTS,
                   help="how many shifts each frame's markers are moved by: the offset, its "
                        "opposite and its axis parts, those that land on gel clear of the "
                        "other markers and of the validation gel (more training gel from the "
                        "same frames; dense grids keep fewer; 1: the offset alone, as before; "
                        "default: %(default)s)")
    p.add_argument("--no-transplant", dest="transplant", action="store_false",
                   help="clean shifted holes in the TELEA frame (the paper) instead of moved "
                        "real markers")
    p.add_argument("--ring", type=int, default=DEFAULT_RING,
                   help="px beyond the removal mask over which a marker's darkening is "
                        "measured and moved (default: %(default)s)")
    p.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                   help="training steps (default: %(default)s)")
    p.add_argument("--batch", type=int, default=8,
                   help="training batch size (default: %(default)s)")
    p.add_argument("--crop", type=int, default=96, help="crop side, multiple of 16")
    p.add_argument("--lr", type=float, default=2e-4,
                   help="learning rate (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--val-every", type=int, default=100,
                   help="validate the weights every N steps (default: %(default)s)")
    p.add_argument("--val-frames", type=int, default=8,
                   help="most frames held out for validation (a fifth of them; with fewer "
                        "than 5 frames all train and validation uses other gel; default: "
                        "%(default)s)")
    p.add_argument("--init", default=None,
                   help="starting weights: 'default' or 'fast' (a shipped model), or a "
                        ".safetensors, checkpoint or TacDiff .onnx file (default: the shipped "
                        "default model's)")
    p.add_argument("--loss", default=None, choices=LOSSES,
                   help="training loss (default: the one the starting model records, e.g. "
                        "x0_l1 for the shipped default)")
    p.add_argument("--terminal-fraction", type=float, default=None, metavar="F",
                   help="share of crops trained at t = 1, in [0, 1] (default: the starting "
                        "model's, 0.9 for the shipped models)")
    p.add_argument("--recompress", default="auto", metavar="auto|none|jpeg:Q|h264:CRF",
                   help="re-compress the transplanted frames like your recording, so the gel "
                        "around a moved marker is quantised with it as around a real one "
                        "(default: auto, which recognises a JPEG/MJPEG source's quality; H.264 "
                        "recordings: pass h264:CRF, e.g. h264:23)")
    p.add_argument("--pseudo", default="model", choices=("model", "telea"),
                   help="the fill your markers are removed with where the transplants are "
                        "built: model (the start model's own fill, closer to the gel) or telea "
                        "(TELEA r=3, the choice before 0.6; default: %(default)s)")
    p.add_argument("--mask-originals", action=argparse.BooleanOptionalAction, default=True,
                   help="make every original marker a hole too in the training and validation "
                        "inputs, as at inference (default: on; --no-mask-originals: the moved "
                        "markers only, as before 0.6)")
    p.add_argument("--trust-dense", action="store_true",
                   help="on a dense marker grid (one training shift fits, e.g. a GelSight "
                        "Mini's), train and let the check choose; default: keep the start "
                        "model there without training (its check has passed worse models)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from tacswitch.cli.options import UsageError

    # The options first: a mistake is named before torch is even looked for.
    offset = None
    if args.offset is not None:
        try:
            dx, dy = (int(v) for v in args.offset.split(","))
        except ValueError:
            raise UsageError(f"--offset: expected DX,DY in px; got {args.offset!r}") from None
        offset = (dx, dy)
    if args.ring < 0:
        raise UsageError(f"--ring: must be >= 0 px; got {args.ring}")
    for name in ("steps", "batch", "val_every", "val_frames", "shifts"):
        if getattr(args, name) < 1:
            raise UsageError(f"--{name.replace('_', '-')}: must be >= 1; got "
                             f"{getattr(args, name)}")
    if args.terminal_fraction is not None and not 0 <= args.terminal_fraction <= 1:
        raise UsageError(f"--terminal-fraction: must be in [0, 1]; got {args.terminal_fraction}")
    try:
        import torch  # noqa: F401
    except ImportError:
        raise ValueError('fine-tuning needs torch: pip install "tacswitch[train]"') from None
    from tacswitch._io import read_image
    from tacswitch.cli.sources import collect_images
    from tacswitch.tacdiff.finetune import finetune

    files = collect_images(args.images)
    frames = [read_image(f) for f in files]
    result = finetune(frames, args.out, init=args.init, steps=args.steps, batch=args.batch,
                      crop=args.crop, lr=args.lr, seed=args.seed, offset=offset,
                      transplant=args.transplant, ring=args.ring, val_every=args.val_every,
                      val_frames=args.val_frames, progress=not args.quiet, loss=args.loss,
                      terminal_fraction=args.terminal_fraction, recompress=args.recompress,
                      pseudo=args.pseudo, mask_originals=args.mask_originals,
                      shifts=args.shifts, trust_dense=args.trust_dense,
                      extra={"finetune": [str(f) for f in files]})
    # The choice is the result: printed even with -q.
    print(result.summary())
    return 0
