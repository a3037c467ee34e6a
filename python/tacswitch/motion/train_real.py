"""Training the consistent motion model on a marker sensor's own videos (torch; CPU or GPU).

The pairs come from :func:`tacswitch.motion.real_pairs.pairs_from_videos` (markers tracked for
the targets, removed for the inputs). Training is :mod:`tacswitch.motion.train_stream`'s on these
pairs instead of rendered ones: the same loss (pair output against the motion from reference to
image; both single-frame outputs against each frame's motion from rest), the same augmentation
(mirror flips, colour-channel permutation, gain and gamma, random crops), a cosine learning rate
over ``steps`` and the EMA of the weights as the result.

Validation: whole videos held out (``val_fraction`` of them, at least one; never trained on),
scored every ``eval_every`` steps against zero motion. A checkpoint (weights, EMA, optimiser,
step) is written atomically at every evaluation; rerunning the same call resumes from it.

Outputs in ``out``: ``model.onnx`` (pair and single frame: ``predict_motion(img, ref,
model=...)``), ``single.onnx`` (the single-frame graph alone), ``model.pt``, ``log.jsonl``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tacswitch.motion.real_pairs import RealPairs, gather_pairs


@dataclass
class RealTrainConfig:
    """One training run on real pairs (recorded in the checkpoint and the models' metadata)."""

    steps: int = 3000
    batch: int = 32
    crop: tuple[int, int] = (160, 128)
    lr: float = 2e-3
    warmup_fraction: float = 0.03
    weight_decay: float = 1e-4
    single_weight: float = 0.5
    ema: float = 0.999
    eval_every: int = 250
    val_fraction: float = 0.15
    seed: int = 0
    device: str = "auto"
    loss: str = "euclid"


def split_videos(n_videos: int, fraction: float, seed: int) -> tuple[list[int], list[int]]:
    """``(train, val)`` video indices: ``fraction`` of them (at least one when there are two or
    more) held out, drawn by ``seed``."""
    if n_videos < 2:
        return list(range(n_videos)), []
    order = np.random.default_rng([seed, 7]).permutation(n_videos)
    k = min(n_videos - 1, max(1, round(fraction * n_videos)))
    return sorted(order[k:].tolist()), sorted(order[:k].tolist())


def train_real(pairs: RealPairs, out: str | Path, cfg: RealTrainConfig, *,
               progress: bool = True) -> dict[str, Any]:
    """Trains (or resumes) a :class:`~tacswitch.motion.model.ConsistentMotionNet` on ``pairs``;
    writes the outputs listed in the module docstring and returns the last validation scores."""
    import torch

    from tacswitch._io import save_torch
    from tacswitch.motion.export import export_onnx
    from tacswitch.motion.model import ConsistentMotionNet, SingleFrameMotionNet, count_params
    from tacswitch.motion.train_stream import (
        _ema_fn,
        _lr_factor,
        augment,
        evaluate,
        resolve_device,
        stream_loss,
    )

    if cfg.steps < 1 or cfg.batch < 1:
        raise ValueError(f"steps, batch: must be >= 1; got {cfg.steps}, {cfg.batch}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    dev = resolve_device(cfg.device)
    train_v, val_v = split_videos(len(pairs.names), cfg.val_fraction, cfg.seed)
    train_p, val_p = pairs.subset(train_v), pairs.subset(val_v)
    if len(train_p) == 0:
        raise ValueError("videos: no training pair left after the validation split")
    torch.manual_seed(cfg.seed)
    net = ConsistentMotionNet().to(dev)
    for param in net.body.head.parameters():  # zero motion at the start
        torch.nn.init.zeros_(param)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    ema = torch.optim.swa_utils.AveragedModel(net, avg_fn=_ema_fn(cfg.ema), use_buffers=True)
    gen = torch.Generator(device=dev)
    gen.manual_seed(cfg.seed)
    frames = torch.from_numpy(pairs.frames).to(dev)
    motion = torch.from_numpy(pairs.motion).to(dev)
    rest = torch.from_numpy(pairs.rest).to(dev)
    video = torch.from_numpy(pairs.video).to(dev)
    train_pairs = torch.from_numpy(train_p.pairs).to(dev)

    def gather(p: Any) -> dict[str, Any]:
        return gather_pairs(frames, motion, rest, video, p)

    val = gather(torch.from_numpy(val_p.pairs).to(dev)) if len(val_p) else None
    ckpt = out / "checkpoint.pt"
    step, last = 0, {}
    if ckpt.is_file():
        state = torch.load(ckpt, map_location=dev, weights_only=False)
        if state["config"] != asdict(cfg) or state["videos"] != pairs.names:
            raise ValueError(f"out: {str(out)!r} holds a run with another configuration or "
                             "other videos; use another folder")
        net.load_state_dict(state["model"])
        ema.load_state_dict(state["ema"])
        opt.load_state_dict(state["optim"])
        gen.set_state(state["gen"].to(gen.get_state().device))
        step, last = state["step"], state["last"]
        if progress:
            print(f"resuming after step {step}", flush=True)
    elif progress:
        print(f"{count_params(net)} parameters on {dev}; {len(train_p)} training pairs from "
              f"{len(train_v)} videos, {len(val_p)} validation pairs from {len(val_v)}",
              flush=True)
    while True:
        done = step >= cfg.steps
        if done or (step and step % cfg.eval_every == 0):
            last = evaluate(ema.module, val) if val is not None else {}
            entry = {"step": step, **{k: round(v, 4) for k, v in last.items()}}
            with open(out / "log.jsonl", "a") as fh:
                fh.write(json.dumps(entry) + "\n")
            if progress:
                print(json.dumps(entry), flush=True)
            save_torch(ckpt, {"model": net.state_dict(), "ema": ema.state_dict(),
                              "optim": opt.state_dict(), "gen": gen.get_state(), "step": step,
                              "last": last, "config": asdict(cfg), "videos": pairs.names})
        if done:
            break
        for g in opt.param_groups:
            g["lr"] = cfg.lr * _lr_factor(step / cfg.steps, cfg.warmup_fraction)
        idx = torch.randint(0, len(train_pairs), (cfg.batch,), generator=gen, device=dev)
        b = augment(gather(train_pairs[idx]), gen)
        loss = stream_loss(net, b, cfg.loss, cfg.single_weight, (cfg.crop[0], cfg.crop[1]), gen)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        ema.update_parameters(net)
        step += 1
    h, w = pairs.frames.shape[1:3]
    model: ConsistentMotionNet = ema.module.to("cpu").eval()  # type: ignore[assignment]
    meta = {"work_width": int(w), "work_height": int(h), "seed": cfg.seed,
            "default_centres": [[round(float(x), 3), round(float(y), 3)]
                                for x, y in pairs.rest[0] if x or y],
            "trained_on": {"videos": len(pairs.names), "pairs": len(pairs),
                           "train_videos": len(train_v), "val_videos": len(val_v),
                           "config": asdict(cfg), "validation": last},
            "loss": cfg.loss, "epochs": 0}
    torch.save({"model": model.state_dict(), "config": asdict(cfg), "meta": meta},
               out / "model.pt")
    export_onnx(model, out / "model.onnx", metadata=meta, height=h, width=w)
    export_onnx(SingleFrameMotionNet(model), out / "single.onnx", metadata=meta, height=h,
                width=w)
    return last
