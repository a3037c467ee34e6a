"""``tacswitch export``: a training checkpoint (or weights file) to a self-contained ONNX model.

Training already exports ``RUN/model.onnx`` at the end; this command exports any checkpoint on
its own, e.g. a run stopped early, or EMA weights from ``RUN/checkpoint.pt`` (needs torch).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help="export a training checkpoint to ONNX (needs torch)",
                       description=__doc__)
    what = p.add_subparsers(dest="what", required=True, metavar="MODEL")
    t = what.add_parser("tacdiff", help="TacDiff denoiser: checkpoint.pt or .safetensors",
                        description="Exports the EMA weights of a TacDiff checkpoint (or a "
                        ".safetensors file) as ONNX for remove_markers(..., model=...).")
    t.add_argument("checkpoint", help="RUN/checkpoint.pt or model.safetensors")
    t.add_argument("-o", "--out", required=True, help="ONNX file to write")
    t.set_defaults(run=run_tacdiff)
    m = what.add_parser("motion", help="motion regressor: checkpoint.pt",
                        description="Exports a motion-regressor checkpoint as ONNX for "
                        "predict_motion(..., model=...).")
    m.add_argument("checkpoint", help="RUN/checkpoint.pt")
    m.add_argument("-o", "--out", required=True, help="ONNX file to write")
    m.add_argument("--preset", default="gelsight_mini",
                   help="sensor preset the model was trained at: working size and default "
                        "marker grid (default: %(default)s)")
    m.set_defaults(run=run_motion)


def _check(args: argparse.Namespace) -> Path:
    """The checkpoint (and ``--preset``, ``-o``) checked before torch is looked for, so a
    mistake is named first; returns the checkpoint's path."""
    from tacswitch.cli.options import input_file, output_file, preset_option

    path = input_file(args.checkpoint, "checkpoint")
    if getattr(args, "preset", None) is not None:
        preset_option(args.preset)
    output_file(args.out, "--out")
    return path


def _torch() -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise ValueError('export needs torch: pip install "tacswitch[train]"') from None


def run_tacdiff(args: argparse.Namespace) -> int:
    path = _check(args)
    _torch()
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.train import load_network

    out = export_onnx(load_network(path), args.out, metadata={"exported_from": str(path)})
    print(out)
    return 0


def run_motion(args: argparse.Namespace) -> int:
    path = _check(args)
    _torch()
    import torch

    from tacswitch.motion.data import preset_grid
    from tacswitch.motion.export import export_onnx
    from tacswitch.motion.model import build_net
    from tacswitch.sim.presets import get_preset

    ck = torch.load(path, map_location="cpu", weights_only=False)
    if not isinstance(ck, dict) or "config" not in ck or "arch" not in ck["config"]:
        raise ValueError(f"checkpoint: {str(path)!r} is not a motion training checkpoint")
    net = build_net(ck["config"]["arch"], ck["config"]["use_ref"],
                    ck["config"].get("design", "plain"))
    net.load_state_dict(ck["model"])
    p = get_preset(args.preset)
    grid = [[round(float(x), 3), round(float(y), 3)] for x, y in preset_grid(args.preset)]
    out = export_onnx(net.eval(), args.out, height=p.height, width=p.width,
                      metadata={"work_width": p.width, "work_height": p.height,
                                "default_centres": grid, "exported_from": str(path)})
    print(out)
    return 0
