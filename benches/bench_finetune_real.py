"""Does ``tacswitch finetune`` help on the sensor it was tuned on? Measured on real gel.

The real-frame proxy (issue 14, :mod:`tacswitch.realproxy`): taxim's real markerless GelSight
(640x480, 49 frames) or GelSight Mini (320x240, 25 frames) presses, one marker grid painted on
all of them (the proxy's styles; the grid and the capture noise drawn from ``--seeds``) and each
frame captured as the proxy does (lossless, MJPEG q75, H.264 CRF 26), so the clean real frame
is the ground truth under every marker. The presses :func:`tacswitch.realproxy.held_out_indices`
names are scored (``--split last``: the last ``--test`` frames, the protocol before 0.6, whose
test presses the 0.6 models trained on); all other frames are the "user's raw frames" (markers
only, never their ground truth): :func:`tacswitch.tacdiff.finetune.finetune`
runs on them exactly as ``tacswitch finetune`` does (transplanted real markers; its own
ground-truth-free validation on held-out frames and gel; it returns the best checkpoint, or the
starting model if none beats it beyond noise). Then the held-out frames are scored: masked MAE
(grey levels) over the true marker footprint (every pixel the painting changed by more than
half a grey level), each method with the mask ``remove_markers`` extracts, for the zero-shot
model, the fine-tune's last weights, the model it chose, and our TELEA default pipeline.

``--fots DIR``: also fine-tune on the real FOTS GelSight Mini frames with markers (no ground
truth at all) and report its validation (start vs chosen).

    python benches/bench_finetune_real.py [--sensors gelsight,gelsight_mini] [--codecs h264]
        [--seeds 0,1] [--steps 1200] [--shifts 4] [--model default|fast|PATH] [--fots DIR]

A benchmark, not a test: it needs the ``train`` extra and a few CPU minutes per fine-tune.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

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


def test_frames(sensor: str, n: int, args: argparse.Namespace) -> list[int]:
    """Indices (into the recording: frame 0 is the no-contact frame, press ``i`` is frame
    ``i + 1``) of the frames scored: the held-out presses, or the last ``args.test``."""
    if args.split == "last":
        return list(range(n - args.test, n))
    from tacswitch.realproxy import held_out_indices

    return sorted(i + 1 for i in held_out_indices(sensor))


def score(out: np.ndarray, truth: np.ndarray, where: np.ndarray) -> tuple[float, float]:
    """Masked MAE and mean signed error (grey levels) of ``out`` against ``truth``."""
    d = out[where].astype(np.float64) - truth[where].astype(np.float64)
    return float(np.abs(d).mean()), float(d.mean())


def finetune_case(frames: np.ndarray, run: Path, args: argparse.Namespace, seed: int
                  ) -> tuple[Any, Path]:
    """``tacswitch finetune`` on ``frames``: its result and the ONNX of its last weights."""
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.finetune import finetune
    from tacswitch.tacdiff.train import load_network

    res = finetune(list(frames), run, init=args.model, steps=args.steps, batch=args.batch,
                   crop=args.crop, lr=args.lr, seed=seed, ring=args.ring,
                   val_every=args.val_every, threads=int(os.environ.get("BENCH_THREADS", "0")),
                   progress=bool(os.environ.get("BENCH_PROGRESS")), loss=args.loss,
                   terminal_fraction=args.terminal_fraction, recompress=args.recompress,
                   pseudo=args.pseudo, mask_originals=args.mask_originals,
                   shifts=args.shifts, trust_dense=args.trust_dense)
    if res.skipped:  # a dense grid, not trusted: nothing trained, the start is the last too
        return res, res.model
    last = export_onnx(load_network(run / "model.safetensors"), run / "last.onnx")
    return res, last


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sensors", default="gelsight",
                    help="gelsight, gelsight_mini (comma list; '' none, e.g. with --fots)")
    ap.add_argument("--style", default="painted", choices=("painted", "pasted", "crisp"))
    ap.add_argument("--codecs", default="h264",
                    help="the proxy's captures (realproxy.CAPTURES), comma-separated")
    ap.add_argument("--seeds", default="0", help="marker grids / capture noise / training seeds")
    ap.add_argument("--test", type=int, default=8,
                    help="with --split last: held-out frames scored (the last ones)")
    ap.add_argument("--split", default="heldout", choices=("heldout", "last"),
                    help="frames scored: heldout = the presses realproxy.held_out_indices "
                         "names (never in the 0.6 models' training), the rest fine-tune; "
                         "last = the last --test frames (the protocol before 0.6)")
    from tacswitch.tacdiff.finetune import DEFAULT_SHIFTS, DEFAULT_STEPS

    ap.add_argument("--steps", type=int, default=DEFAULT_STEPS)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--crop", type=int, default=96)
    ap.add_argument("--lr", type=float, default=2e-4)
    ap.add_argument("--ring", type=int, default=3)
    ap.add_argument("--shifts", type=int, default=DEFAULT_SHIFTS,
                    help="training shifts (default: %(default)s)")
    ap.add_argument("--val-every", type=int, default=100)
    ap.add_argument("--model", default="fast",
                    help="the starting model: default, fast or a weights/ONNX path")
    ap.add_argument("--loss", default=None,
                    help="training loss (default: the starting model's recorded one)")
    ap.add_argument("--terminal-fraction", type=float, default=None,
                    help="share of crops at t = 1 (default: the starting model's)")
    ap.add_argument("--recompress", default="auto",
                    help="the fine-tune's re-compression of its transplants (auto, none, "
                         "jpeg:Q, h264:CRF)")
    ap.add_argument("--pseudo", default="model", choices=("model", "telea"),
                    help="pseudo-markerless fill of the transplants (finetune(pseudo=...))")
    ap.add_argument("--mask-originals", action=argparse.BooleanOptionalAction, default=True,
                    help="finetune(mask_originals=...): every original marker a hole too "
                         "(default; --no-mask-originals: the moved markers only)")
    ap.add_argument("--trust-dense", action="store_true",
                    help="train on dense grids too (finetune(trust_dense=True))")
    ap.add_argument("--fots", default=None, help="folder of real marker frames (FOTS) too")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="ftbench_"))
    rows: list[dict[str, Any]] = []
    for sensor in [v for v in args.sensors.split(",") if v]:
        for codec in args.codecs.split(","):
            for seed in (int(v) for v in args.seeds.split(",")):
                rec, clean, footprint = sensor_recording(sensor, args.style, codec, seed)
                test = test_frames(sensor, len(rec), args)
                train_idx = [i for i in range(len(rec)) if i not in test]
                n_train = len(train_idx)
                t0 = time.perf_counter()
                res, last = finetune_case(rec[train_idx], work / f"{sensor}_{codec}_{seed}",
                                          args, seed)
                took = time.perf_counter() - t0
                methods: dict[str, Any] = {"zero-shot": args.model, "last": last,
                                           "chosen": res.model}
                row: dict[str, Any] = {"sensor": sensor, "codec": codec, "seed": seed,
                                       "train": n_train, "seconds": round(took)}
                for name, model in (("TELEA", None), *methods.items()):
                    vals = []
                    for i in test:
                        out = (ts.remove_markers(rec[i]) if model is None else
                               ts.remove_markers(rec[i], method="tacdiff", model=model))
                        vals.append(score(out, clean[i], footprint[i]))
                    row[name] = [float(v) for v in np.mean(vals, axis=0)]
                row["recompress"] = res.recompress
                row["skipped"] = res.skipped
                row["validation"] = {"start": res.start_score, "scores": res.scores,
                                     "chosen_step": res.chosen_step, "noise": res.noise,
                                     "markers": res.val_markers, "frames": res.val_frames,
                                     "offset": res.val_offset, "overlap": res.val_overlap}
                rows.append(row)
                print(json.dumps(row), flush=True)
    own = "the start model's"
    print(f"\nFine-tune from '{args.model}' ({args.steps} steps, batch {args.batch}, lr "
          f"{args.lr}, ring {args.ring}, loss {args.loss or own}, terminal fraction "
          f"{own if args.terminal_fraction is None else args.terminal_fraction}), "
          f"{args.style} markers; masked MAE over the true footprint of the held-out frames "
          f"({'the held-out presses' if args.split == 'heldout' else f'the last {args.test}'};"
          " grey levels)\n")
    print("| sensor | capture | seed | TELEA default | zero-shot | fine-tuned (last) | "
          "chosen by validation | validation start -> chosen |\n|---|---|---|---|---|---|---|---|")
    for r in rows:
        v = r["validation"]
        pick = ("start kept, not trained (dense grid)" if r["skipped"] else
                "start kept" if v["chosen_step"] == 0 else
                f"step {v['chosen_step']}: {v['scores'][v['chosen_step']]:.3f}")
        print(f"| {r['sensor']} | {r['codec']} | {r['seed']} | {r['TELEA'][0]:.3f} | "
              f"{r['zero-shot'][0]:.3f} | {r['last'][0]:.3f} | {r['chosen'][0]:.3f} | "
              f"{v['start']:.3f} -> {pick} |")
    result: dict[str, Any] = {"rows": rows}
    if args.fots:
        from tacswitch._io import read_image

        frames = np.stack([read_image(p) for p in sorted(Path(args.fots).glob("*.png"))])
        res, _ = finetune_case(frames, work / "fots", args, 0)
        result["fots"] = {"start": res.start_score, "scores": res.scores,
                          "chosen_step": res.chosen_step, "noise": res.noise,
                          "markers": res.val_markers, "offset": res.val_offset,
                          "overlap": res.val_overlap}
        print("\nFOTS real GelSight Mini frames (no ground truth):", res.summary())
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
