"""``tacswitch evaluate downstream``: does removing markers help perception? (needs torch)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from tacswitch.cli.options import UsageError, input_file, preset_option


def add_evaluate_parser(what: argparse._SubParsersAction) -> None:
    """Registers ``evaluate downstream``."""
    from tacswitch.downstream.data import INPUTS, TASKS

    m = what.add_parser(
        "downstream", help="texture classification and contact segmentation on every input type",
        description="Renders simulated contacts into --data (resumable), removes their markers "
        "with every method, then trains ResNet-18 (texture classes) and DeepLabV3 (contact "
        "area) per input type and seed, and writes OUT/report.md with mean ± spread and the "
        "paired difference from the raw marker frames. Finished runs are kept in "
        "OUT/results.jsonl; rerunning the command resumes. The default scale takes under an "
        "hour on a 2-core CPU; --quick runs every step at a tiny scale, a smoke test of a few "
        "minutes (about 5 on a 2-core CPU; numbers meaningless).")
    m.add_argument("--data", required=True, help="folder of the rendered frames (built if "
                   "missing, resumable)")
    m.add_argument("--out", default=None,
                   help="results folder (default: DATA itself: DATA/report.md, "
                        "DATA/results.jsonl)")
    m.add_argument("--quick", action="store_true",
                   help="tiny scale for smoke tests (a few minutes; numbers meaningless)")
    m.add_argument("--seeds", type=int, default=None, help="seeds per run (default: 3)")
    m.add_argument("--per-class", type=int, default=None,
                   help="texture samples per class (default: 30)")
    m.add_argument("--contact-samples", type=int, default=None,
                   help="contact-segmentation samples (default: 160)")
    m.add_argument("--epochs", type=int, default=None,
                   help="epochs of both tasks (default: 40 texture, 8 contact)")
    m.add_argument("--preset", default=None, help="simulator preset (default: gelsight_mini)")
    m.add_argument("--tasks", default=",".join(TASKS),
                   help="comma-separated (default: %(default)s)")
    m.add_argument("--inputs", default=",".join(INPUTS),
                   help="comma-separated input types (default: %(default)s)")
    m.add_argument("--model", default=None, help="TacDiff ONNX model (default: shipped)")
    m.add_argument("--threads", type=int, default=None, help="torch threads (default: all)")
    m.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    m.set_defaults(run=run)


def _check(args: argparse.Namespace) -> tuple[dict[str, object], list[str], list[str]]:
    """The option values checked before torch is looked for (a mistake is named first):
    the scale changes, the tasks and the input types."""
    from tacswitch.downstream.data import INPUTS, TASKS

    changes: dict[str, object] = {}
    for flag, field in (("seeds", "seeds"), ("per_class", "per_class"),
                        ("contact_samples", "contact_samples")):
        value = getattr(args, flag)
        if value is not None:
            if value < 2:
                raise UsageError(f"--{flag.replace('_', '-')}: must be >= 2; got {value}")
            changes[field] = value
    if args.epochs is not None:
        if args.epochs < 1:
            raise UsageError(f"--epochs: must be >= 1; got {args.epochs}")
        changes |= {"texture_epochs": args.epochs, "contact_epochs": args.epochs}
    if args.preset is not None:
        preset_option(args.preset)
        changes["preset"] = args.preset
    if args.threads is not None and args.threads < 1:
        raise UsageError(f"--threads: must be >= 1; got {args.threads}")
    if args.model is not None:
        from tacswitch.tacdiff.infer import model_path  # onnxruntime only, no torch

        input_file(model_path(args.model), "--model")
    if Path(args.data).is_file():
        raise UsageError(f"--data: {args.data!r} is a file; give a folder")
    tasks = _choices(args.tasks, TASKS, "--tasks")
    inputs = _choices(args.inputs, INPUTS, "--inputs")
    return changes, tasks, inputs


def run(args: argparse.Namespace) -> int:
    changes, tasks, inputs = _check(args)
    try:
        import torch  # noqa: F401
        import torchvision  # noqa: F401
    except ImportError:
        raise ValueError('the downstream study needs torch: pip install "tacswitch[train]"'
                         ) from None
    from tacswitch._io import atomic_open
    from tacswitch.downstream.data import QUICK, StudyScale, build_dataset
    from tacswitch.downstream.study import markdown, run_study, summarise

    scale = dataclasses.replace(QUICK if args.quick else StudyScale(),
                                **changes)  # type: ignore[arg-type]
    say = None if args.quiet else print
    build_dataset(args.data, scale, model=args.model, progress=say)
    # The report goes next to the frames it was made from (DATA/study/ read as study/study/
    # with the documented `--data study/`).
    out = Path(args.out) if args.out else Path(args.data)
    records = run_study(args.data, out, scale, tasks=tasks, inputs=inputs, threads=args.threads,
                        progress=say)
    report = markdown(summarise(records))
    with atomic_open(out / "report.md") as fh:
        fh.write(report + "\n")
    if say:
        say(f"\n{report}\n\nwritten: {out / 'report.md'}")
    return 0


def _choices(text: str, allowed: tuple[str, ...], flag: str) -> list[str]:
    items = [t.strip() for t in text.split(",") if t.strip()]
    bad = [t for t in items if t not in allowed]
    if bad or not items:
        raise UsageError(f"{flag}: expected some of {','.join(allowed)}; got {text!r}")
    return items
