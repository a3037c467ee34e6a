"""Training of the motion regressor (torch): sparse supervision at marker centres.

The loss is computed at the marker centres only (the paper's sparse supervision), from the
prediction read out bilinearly at the sub-pixel centres: the squared error (the paper's) or the
Euclidean error (``loss="euclid"``, see :func:`sparse_loss`). Markers without ground truth
(NaN motion: lost by the tracker on a user's sensor) are left out of the loss.

Runs are resumable and deterministic by seed: a checkpoint (model, optimiser, schedule, epoch,
log) is written atomically after every epoch to ``out/checkpoint.pt``; rerunning the same command
continues from it. ``out/log.jsonl`` has one line per epoch (train loss, validation e_rmse, time).
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._io import save_torch


@dataclass
class TrainConfig:
    """Hyper-parameters of one run (recorded in the checkpoint and the model's metadata)."""

    arch: str = "unet"
    use_ref: bool = False
    loss: str = "mse"  # "mse": the paper's; "euclid": the mean per-marker Euclidean error
    epochs: int = 12
    batch: int = 16
    lr: float = 2e-3
    weight_decay: float = 1e-4
    seed: int = 0
    val_fraction: float = 0.05
    threads: int = 0  # 0: os.cpu_count()
    max_steps_per_epoch: int = 0  # 0: the whole training set (smoke tests use 1-2)
    extra: dict[str, Any] = field(default_factory=dict)


def _batches(n: int, batch: int, rng: np.random.Generator) -> list[NDArray[np.int64]]:
    order = rng.permutation(n)
    return [order[i:i + batch] for i in range(0, n, batch)]


def _tensors(data: dict[str, NDArray[Any]], idx: NDArray[np.int64], use_ref: bool) -> tuple:
    import torch

    img = torch.from_numpy(np.ascontiguousarray(data["image"][idx]))
    ref = torch.from_numpy(np.ascontiguousarray(data["reference"][idx])) if use_ref else None
    cen = torch.from_numpy(data["rest"][idx].astype(np.float32))
    tgt = torch.from_numpy(data["displacement"][idx].astype(np.float32))
    return img, ref, cen, tgt


LOSSES = ("mse", "euclid")


def sparse_loss(pred: Any, target: Any, kind: str = "mse") -> Any:
    """Loss over the markers with finite ground truth only.

    ``"mse"``: mean squared Euclidean error (px², the paper's). ``"euclid"``: mean Euclidean error
    (px), the quantity e_rmse reports; its optimum is a median, not a mean, so the part of the
    motion a markerless frame cannot show (in the simulator: the stuck-zone shear) pulls the
    prediction less than under MSE, where a few large unpredictable motions dominate the gradient.
    """
    import torch

    if kind not in LOSSES:
        raise ValueError(f"kind: must be one of {LOSSES}; got {kind!r}")
    ok = torch.isfinite(target).all(dim=-1)
    if not bool(ok.any()):
        return pred.sum() * 0.0
    sq = ((pred[ok] - target[ok]) ** 2).sum(dim=-1)
    # 1e-6 px² keeps the gradient of the norm finite at zero error.
    return sq.mean() if kind == "mse" else torch.sqrt(sq + 1e-6).mean()


def evaluate_arrays(net: Any, data: dict[str, NDArray[Any]], idx: NDArray[np.int64],
                    use_ref: bool, batch: int = 32) -> dict[str, float]:
    """Mean per-marker Euclidean error (px) and loss of ``net`` on ``data[idx]``."""
    import torch

    errs = []
    net.eval()
    with torch.no_grad():
        for i in range(0, len(idx), batch):
            img, ref, cen, tgt = _tensors(data, idx[i:i + batch], use_ref)
            e = torch.linalg.norm(net(img, cen, ref) - tgt, dim=-1)
            errs.append(e[torch.isfinite(e)].numpy())
    allerr = np.concatenate(errs) if errs else np.zeros(0)
    return {"e_rmse_mean": float(allerr.mean()) if allerr.size else float("nan"),
            "e_rmse_median": float(np.median(allerr)) if allerr.size else float("nan")}


def train(data: dict[str, NDArray[Any]], out: str | Path, cfg: TrainConfig,
          *, progress: bool = True) -> Any:
    """Trains (or resumes) a :class:`~tacswitch.motion.model.MotionNet` on ``data``.

    Args:
        data: arrays ``image`` (``B x H x W x 3`` uint8 BGR, markerless), ``rest`` (``B x N x 2``
            (x, y) px), ``displacement`` (``B x N x 2`` (dx, dy) px, NaN = no ground truth) and,
            for ``use_ref``, ``reference`` (markerless no-contact frames).
        out: run folder (checkpoint, log, final weights).
        cfg: hyper-parameters.

    Returns:
        the trained network (eval mode).
    """
    import torch

    from tacswitch.motion.model import MotionNet, count_params

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads or os.cpu_count() or 1)
    n = len(data["image"])
    split_rng = np.random.default_rng([cfg.seed, 1])
    perm = split_rng.permutation(n)
    n_val = max(1, round(cfg.val_fraction * n)) if n > 1 else 0
    val_idx, train_idx = np.sort(perm[:n_val]), np.sort(perm[n_val:])
    net = MotionNet(cfg.arch, cfg.use_ref)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    steps_per_epoch = -(-len(train_idx) // cfg.batch)
    if cfg.max_steps_per_epoch:
        steps_per_epoch = min(steps_per_epoch, cfg.max_steps_per_epoch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, pct_start=0.1,
                                                total_steps=max(1, cfg.epochs * steps_per_epoch))
    ckpt_path = out / "checkpoint.pt"
    start, log = 0, []
    if ckpt_path.is_file():
        ck = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        if ck["config"] != asdict(cfg):
            raise ValueError(f"out: {str(out)!r} holds a run with another configuration; "
                             "use another folder")
        net.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optim"])
        sched.load_state_dict(ck["sched"])
        start, log = ck["epoch"], ck["log"]
        if progress:
            print(f"resuming after epoch {start}", flush=True)
    if progress and start == 0:
        print(f"{cfg.arch} (use_ref={cfg.use_ref}): {count_params(net)} parameters, "
              f"{len(train_idx)} train / {len(val_idx)} val samples", flush=True)
    for epoch in range(start, cfg.epochs):
        t0 = time.perf_counter()
        net.train()
        # Shuffle from (seed, epoch): a resumed run sees the batches an uninterrupted one would.
        rng = np.random.default_rng([cfg.seed, 2, epoch])
        torch.manual_seed(cfg.seed * 1000 + epoch)
        losses = []
        for b in _batches(len(train_idx), cfg.batch, rng)[:steps_per_epoch]:
            img, ref, cen, tgt = _tensors(data, train_idx[b], cfg.use_ref)
            loss = sparse_loss(net(img, cen, ref), tgt, cfg.loss)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
        val = evaluate_arrays(net, data, val_idx, cfg.use_ref) if len(val_idx) else {}
        entry = {"epoch": epoch + 1, f"train_{cfg.loss}": float(np.mean(losses)), **val,
                 "lr": float(sched.get_last_lr()[0]), "seconds": time.perf_counter() - t0}
        log.append(entry)
        save_torch(ckpt_path, {"model": net.state_dict(), "optim": opt.state_dict(),
                                     "sched": sched.state_dict(), "epoch": epoch + 1,
                                     "log": log, "config": asdict(cfg)})
        with open(out / "log.jsonl", "a") as fh:
            fh.write(json.dumps(entry) + "\n")
        if progress:
            print(json.dumps({k: round(v, 4) if isinstance(v, float) else v
                              for k, v in entry.items()}), flush=True)
    return net.eval()
