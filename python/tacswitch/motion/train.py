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
    #: 0: one pass over the training set per epoch. Otherwise exactly this many steps per
    #: epoch (passes repeat if the set is smaller), so the schedule's length does not depend on
    #: the data size (smoke tests use 1-2).
    max_steps_per_epoch: int = 0
    extra: dict[str, Any] = field(default_factory=dict)
    #: "plain": MotionNet; "consistent": ConsistentMotionNet, trained on its pair output and on
    #: its single-frame output for both frames (needs ``disp_image`` / ``disp_reference``).
    design: str = "plain"
    single_weight: float = 0.5
    #: Consistent design: train on random ``(width, height)`` crops of the frames (normalised
    #: whole first); (0, 0): whole frames. Crops cut the cost of a step on 2 CPU cores.
    crop: tuple[int, int] = (0, 0)
    #: Cap on validation samples (0: no cap).
    max_val: int = 0
    #: Start from the model weights of this training checkpoint ("" : random initialisation).
    init: str = ""


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


def _absolute(data: dict[str, NDArray[Any]], idx: NDArray[np.int64]) -> tuple:
    """Both frames' motions from rest (targets of the consistent design's single-frame output)."""
    import torch

    for key in ("disp_image", "disp_reference"):
        if key not in data:
            raise ValueError(f"data: the consistent design needs {key!r} (gel_ splits have it)")
    return (torch.from_numpy(data["disp_image"][idx].astype(np.float32)),
            torch.from_numpy(data["disp_reference"][idx].astype(np.float32)))


def consistent_loss(net: Any, img: Any, ref: Any, cen: Any, tgt: Any, d_ref: Any, kind: str,
                    single_weight: float, crop: tuple[int, int] = (0, 0),
                    rng: np.random.Generator | None = None) -> Any:
    """Loss of a :class:`~tacswitch.motion.model.ConsistentMotionNet`: the pair output against
    the motion from ``ref`` to ``img``, plus ``single_weight`` times the reference's single-frame
    loss against its motion from rest (the pair output is ``G(x, x - r) - single(ref)``, so the
    single-frame term costs no extra pass; references are contact frames 70 % of the time).

    With ``crop = (w, h)`` the frames are normalised whole, then one random crop (offsets on
    the stride-4 grid) is taken for the batch; markers outside it are left out."""

    from tacswitch.motion.model import sample_at

    x, r = net.norm(img), net.norm(ref)
    h, w = img.shape[1], img.shape[2]
    cw, ch = crop
    if cw and ch and (cw < w or ch < h):
        rng = rng if rng is not None else np.random.default_rng()
        x0 = 4 * int(rng.integers(0, (w - cw) // 4 + 1))
        y0 = 4 * int(rng.integers(0, (h - ch) // 4 + 1))
        x, r, cen, (tgt, d_ref) = crop_frames(x, r, cen, (tgt, d_ref), x0, y0, (cw, ch))
        h, w = ch, cw
    s_ref, pair = net.pair_fields(x, r)
    lp = sparse_loss(sample_at(pair, cen, h, w), tgt, kind)
    ls = sparse_loss(sample_at(s_ref, cen, h, w), d_ref, kind)
    return lp + single_weight * ls


def crop_frames(x: Any, r: Any, cen: Any, targets: tuple[Any, ...], x0: int, y0: int,
                size: tuple[int, int]) -> tuple[Any, Any, Any, tuple[Any, ...]]:
    """The ``size = (w, h)`` crop at ``(x0, y0)`` of normalised frames ``x``, ``r``
    (``B x C x H x W``): centres shifted into it, and each target (``B x N x 2``) NaN for the
    markers outside it (they leave the loss)."""
    import torch

    cw, ch = size
    x, r = x[..., y0:y0 + ch, x0:x0 + cw], r[..., y0:y0 + ch, x0:x0 + cw]
    cen = cen - cen.new_tensor([x0, y0])
    out = ((cen[..., 0] < 1) | (cen[..., 0] > cw - 2) | (cen[..., 1] < 1)
           | (cen[..., 1] > ch - 2))[..., None]
    return x, r, cen, tuple(torch.where(out, torch.nan, t) for t in targets)


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
    """Mean per-marker Euclidean error (px) of ``net`` on ``data[idx]``; for the consistent
    design also its single-frame error against the motion from rest (``single_``)."""
    import torch

    consistent = getattr(net, "design", "plain") == "consistent"
    errs, single = [], []
    net.eval()
    with torch.no_grad():
        for i in range(0, len(idx), batch):
            img, ref, cen, tgt = _tensors(data, idx[i:i + batch], use_ref or consistent)
            e = torch.linalg.norm(net(img, cen, ref) - tgt, dim=-1)
            errs.append(e[torch.isfinite(e)].numpy())
            if consistent and "disp_image" in data:
                d_img, _ = _absolute(data, idx[i:i + batch])
                e = torch.linalg.norm(net(img, cen) - d_img, dim=-1)
                single.append(e[torch.isfinite(e)].numpy())
    out = {}
    for name, part in (("", errs), ("single_", single)):
        if not part:
            continue
        allerr = np.concatenate(part)
        out[f"{name}e_rmse_mean"] = float(allerr.mean()) if allerr.size else float("nan")
        out[f"{name}e_rmse_median"] = float(np.median(allerr)) if allerr.size else float("nan")
    return out


def train(data: dict[str, NDArray[Any]], out: str | Path, cfg: TrainConfig,
          *, progress: bool = True, until_epoch: int | None = None) -> Any:
    """Trains (or resumes) a :class:`~tacswitch.motion.model.MotionNet` on ``data``.

    Args:
        data: arrays ``image`` (``B x H x W x 3`` uint8 BGR, markerless), ``rest`` (``B x N x 2``
            (x, y) px), ``displacement`` (``B x N x 2`` (dx, dy) px, NaN = no ground truth) and,
            for ``use_ref``, ``reference`` (markerless no-contact frames).
        out: run folder (checkpoint, log, final weights).
        cfg: hyper-parameters.
        until_epoch: stop after this epoch (the run resumes from there; the data may grow in
            between when ``cfg.max_steps_per_epoch`` fixes the schedule's length).

    Returns:
        the trained network (eval mode).
    """
    import torch

    from tacswitch.motion.model import build_net, count_params

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads or os.cpu_count() or 1)
    n = len(data["image"])
    split_rng = np.random.default_rng([cfg.seed, 1])
    perm = split_rng.permutation(n)
    n_val = max(1, round(cfg.val_fraction * n)) if n > 1 else 0
    val_idx, train_idx = np.sort(perm[:n_val]), np.sort(perm[n_val:])
    if cfg.max_val:
        val_idx = val_idx[:cfg.max_val]
    net = build_net(cfg.arch, cfg.use_ref, cfg.design)
    consistent = cfg.design == "consistent"
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    steps_per_epoch = cfg.max_steps_per_epoch or -(-len(train_idx) // cfg.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, pct_start=0.1,
                                                total_steps=max(1, cfg.epochs * steps_per_epoch))
    ckpt_path = out / "checkpoint.pt"
    start, log = 0, []
    if cfg.init and not ckpt_path.is_file():
        net.load_state_dict(torch.load(cfg.init, map_location="cpu", weights_only=False)["model"])
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
        print(f"{cfg.arch} ({cfg.design}, use_ref={cfg.use_ref}): {count_params(net)} parameters, "
              f"{len(train_idx)} train / {len(val_idx)} val samples", flush=True)
    for epoch in range(start, min(cfg.epochs, until_epoch or cfg.epochs)):
        t0 = time.perf_counter()
        net.train()
        # Shuffle from (seed, epoch): a resumed run sees the batches an uninterrupted one would.
        rng = np.random.default_rng([cfg.seed, 2, epoch])
        torch.manual_seed(cfg.seed * 1000 + epoch)
        losses = []
        order = _batches(len(train_idx), cfg.batch, rng)
        while len(order) < steps_per_epoch:
            order += _batches(len(train_idx), cfg.batch, rng)
        for b in order[:steps_per_epoch]:
            img, ref, cen, tgt = _tensors(data, train_idx[b], cfg.use_ref or consistent)
            if consistent:
                _, d_ref = _absolute(data, train_idx[b])
                loss = consistent_loss(net, img, ref, cen, tgt, d_ref, cfg.loss,
                                       cfg.single_weight, (cfg.crop[0], cfg.crop[1]), rng)
            else:
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
