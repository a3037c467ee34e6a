"""Does ``tacswitch finetune`` help on the sensor it was tuned on? Measured on real gel.

The real-frame proxy (issue 14, :mod:`tacswitch.realproxy`): taxim's real markerless GelSight
(640x480) or GelSight Mini (320x240) presses, one marker grid painted on all of them (the proxy's
styles) and each frame captured as the proxy does (lossless, MJPEG q75, H.264 CRF 26), so the
clean real frame is the ground truth under every marker. The first ``--train`` frames
are the "user's raw frames" (markers only, never their ground truth): the model is fine-tuned on
them with :func:`tacswitch.tacdiff.data.marker_offset_pairs` (transplanted real markers, the
default, or the paper's clean shifted holes), then every method is scored on the held-out
frames: masked MAE and mean signed error (grey levels) over the true marker footprint (every
pixel the painting changed by more than half a grey level), each method with the mask
``remove_markers`` extracts. Also the ground-truth-free check on the real FOTS GelSight Mini
frames with markers (``--fots DIR``): the error on held-out shifted-mask pixels (markers moved
by half a pitch onto real gel), before and after a fine-tune on those frames.

    python benches/bench_finetune_real.py [--sensor gelsight|gelsight_mini] [--codec h264]
        [--steps 400] [--modes transplant,paper] [--model default|fast|PATH]

A benchmark, not a test: it needs the ``train`` extra and a few CPU minutes per fine-tune.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

import tacswitch as ts
from tacswitch.sim import capture


def sensor_recording(sensor: str, style: str, codec: str, seed: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One sensor's frames: taxim's real presses of ``sensor`` (:mod:`tacswitch.realproxy`)
    with ONE marker grid painted on all of them (a sensor's markers do not move between
    presses here) in the proxy's ``style``, each frame captured with the proxy's ``codec``.
    Returns ``(frames, clean, footprints)`` (``T x H x W [x 3]``)."""
    from tacswitch.realproxy import CAPTURES, grid_for, load_presses, styles_for
    from tacswitch.sim.markers import paint_markers

    rng = np.random.default_rng(seed)
    f0, presses = load_presses(sensor)
    clean = np.stack([f0] + [p for p, _ in presses])
    centres = grid_for(sensor, rng)
    look = styles_for(sensor)[style]
    frames, footprints = [], []
    for i, c in enumerate(clean):
        img, fp = paint_markers(c, centres, look, rng=seed)
        frames.append(capture.apply(img, CAPTURES[codec], (seed, i)))
        footprints.append(fp)
    return np.stack(frames), clean, np.stack(footprints)


def score(out: np.ndarray, truth: np.ndarray, where: np.ndarray) -> tuple[float, float]:
    """Masked MAE and mean signed error (grey levels) of ``out`` against ``truth``."""
    d = out[where].astype(np.float64) - truth[where].astype(np.float64)
    return float(np.abs(d).mean()), float(d.mean())


def finetune(frames: np.ndarray, run: Path, *, steps: int, transplant: bool, seed: int,
             base_model: str, batch: int, crop: int) -> Path:
    """Fine-tunes the shipped weights on ``frames`` (markers only) and exports the ONNX."""
    from tacswitch.tacdiff.data import marker_offset_pairs
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.infer import default_weights_path, model_path
    from tacswitch.tacdiff.train import TrainConfig, load_network, train

    # A shipped model by name: its ONNX (float32 weights); the default's safetensors otherwise.
    init = default_weights_path() if base_model == "default" else model_path(base_model)
    pairs = marker_offset_pairs(list(frames), transplant=transplant)
    arch = load_network(init).cfg
    cfg = TrainConfig(base=arch.base, mults=arch.mults, attention=arch.attention,
                      prior=arch.prior, steps=steps, batch=batch, crop=crop, lr=2e-4,
                      warmup=min(100, steps // 10), seed=seed, log_every=50,
                      threads=int(os.environ.get("BENCH_THREADS", "0")))
    net = train([pairs], run, cfg, progress=bool(os.environ.get("BENCH_PROGRESS")), init=init)
    return export_onnx(net, run / "model.onnx")


def held_out_offset(frames: np.ndarray) -> tuple[int, int]:
    """The check's shift: half a pitch like the fine-tune's, mirrored in x ((-d, +d) where the
    fine-tune uses (+d, +d)), so the checked holes are pixels the fine-tune never had as a
    target."""
    from tacswitch.tacdiff.data import removal_markers
    from tacswitch.tacdiff.transplant import default_offset

    d = default_offset(ts.estimate_pitch(removal_markers(frames[0]).centres))[0]
    return -d, d


def held_out_shifted(frames: np.ndarray, model: str | Path | None) -> dict[str, float]:
    """Ground-truth-free check on frames WITH markers: their real markers moved half a pitch
    onto real gel (:func:`held_out_offset`), each method fills them (the moved markers' removal
    mask), error on their real-gel pixels."""
    from tacswitch.tacdiff.data import marker_offset_pairs

    pairs = marker_offset_pairs(list(frames), offset=held_out_offset(frames), transplant=True)
    errs: dict[str, list[float]] = {"TELEA r=3 (ours)": [], "TacDiff K=1": []}
    for cond, target, mask, loss in zip(pairs["cond"], pairs["target"], pairs["mask"],
                                        pairs["loss_mask"], strict=True):
        outs = {"TELEA r=3 (ours)": ts.remove_markers(cond, mask, method="telea"),
                "TacDiff K=1": ts.remove_markers(cond, mask, method="tacdiff", model=model)}
        for k, o in outs.items():
            errs[k].append(score(o, target, loss)[0])
    return {k: float(np.mean(v)) for k, v in errs.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sensor", default="gelsight", choices=("gelsight", "gelsight_mini"))
    ap.add_argument("--style", default="painted", choices=("painted", "pasted", "crisp"))
    ap.add_argument("--codec", default="h264", choices=("lossless", "mjpeg", "h264"),
                    help="the proxy's capture (realproxy.CAPTURES)")
    ap.add_argument("--train", type=int, default=32, help="frames to fine-tune on (first ones)")
    ap.add_argument("--test", type=int, default=8, help="held-out frames scored (last ones)")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--crop", type=int, default=96)
    ap.add_argument("--modes", default="transplant,paper",
                    help="fine-tune variants: transplant, paper (comma-separated; '' none)")
    ap.add_argument("--model", default="default",
                    help="the zero-shot model: default, fast or an ONNX path; fine-tunes start "
                         "from the shipped weights")
    ap.add_argument("--fots", default=None, help="folder of real marker frames (FOTS) too")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    rec, clean, footprint = sensor_recording(args.sensor, args.style, args.codec, args.seed)
    train_frames = rec[: args.train]
    test = range(max(args.train, len(rec) - args.test), len(rec))
    models: dict[str, str | Path | None] = {"TacDiff K=1 (zero-shot)": args.model}
    work = Path(tempfile.mkdtemp(prefix="ftbench_"))
    for mode in [m for m in args.modes.split(",") if m]:
        t0 = time.perf_counter()
        path = finetune(train_frames, work / mode, steps=args.steps, seed=args.seed,
                        transplant=mode == "transplant", base_model=args.model,
                        batch=args.batch, crop=args.crop)
        print(f"fine-tune {mode}: {args.steps} steps in {time.perf_counter() - t0:.0f} s",
              flush=True)
        models[f"TacDiff K=1 (fine-tuned, {mode})"] = path
    rows: dict[str, list[tuple[float, float]]] = {}
    for i in test:
        frame, truth = rec[i], clean[i]
        outs = {"TELEA r=3 (ours, default pipeline)": ts.remove_markers(frame)}
        for name, model in models.items():
            outs[name] = ts.remove_markers(frame, method="tacdiff", model=model)
        outs["hybrid K=1 (zero-shot)"] = ts.remove_markers(frame, method="hybrid",
                                                           model=args.model)
        for name, out in outs.items():
            rows.setdefault(name, []).append(score(out, truth, footprint[i]))
    print(f"\n{args.sensor} real frames, {args.style} markers, {args.codec}: fine-tune on "
          f"{args.train} frames ({args.steps} steps), test on {len(test)} held-out frames\n")
    print("| method | masked MAE | mean signed error |\n|---|---|---|")
    result = {}
    for name, vals in rows.items():
        mae, bias = np.mean(vals, axis=0)
        result[name] = {"mae": float(mae), "signed": float(bias)}
        print(f"| {name} | {mae:.3f} | {bias:+.3f} |")
    if args.fots:
        frames = np.stack([cv2.imread(str(p)) for p in sorted(Path(args.fots).glob("*.png"))])
        fots = {"zero-shot": held_out_shifted(frames, args.model)}
        if args.modes:
            path = finetune(frames, work / "fots", steps=args.steps, seed=args.seed,
                            transplant=True, base_model=args.model, batch=args.batch,
                            crop=args.crop)
            fots["fine-tuned on these frames"] = held_out_shifted(frames, path)
        print("\nFOTS real GelSight Mini frames, held-out shifted-mask MAE:", json.dumps(fots))
        result["fots"] = fots  # type: ignore[assignment]
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
