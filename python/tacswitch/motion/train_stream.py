"""Training of the consistent motion regressor on a stream of simulated pairs (torch).

:func:`tacswitch.motion.train.train` trains on shards written to disk, which caps a run at what
a disk and a few CPU cores can hold. Here worker processes render
:func:`~tacswitch.motion.data.render_gel_pair_sample` pairs without end while the network trains
on a buffer that grows as they arrive (kept on the training device: a GPU holds tens of thousands
of 320x240 pairs), so a run is bounded by time, not by a data set. Each batch is augmented on the
device: mirror flips (the motion's sign follows), a colour-channel permutation shared by the two
frames (sensors differ in which channel carries which light), a per-channel gain and gamma, and
random crops of the whole-normalised frames.

The loss is the consistent design's (:func:`tacswitch.motion.train.consistent_loss`) plus the
current frame's own single-frame term, so both single-frame outputs are trained: the pair output
``G(x, x - r) - G(r, 0)`` against the motion from ``ref`` to ``img``, and ``G(r, 0)``, ``G(x, 0)``
against each frame's motion from rest. The learning rate follows a cosine over the run's time
budget (``seconds``), so one command fits a lease of a given length on any machine; the EMA of
the weights is what is exported. Several networks (``variants``) can train on the same batches,
which costs little on a GPU and compares them on identical data.

Validation: a fixed set of held-out pairs (unseen indenters and unseen depths), rendered first,
scored every ``eval_every`` steps against zero motion (pair and single-frame e_rmse, direction
cosine). Outputs in ``out``: ``log.jsonl``, per variant ``{name}.pt`` (EMA weights and config)
and ``{name}.onnx``.
"""

from __future__ import annotations

import json
import math
import queue
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Keys of a rendered pair kept in the buffer.
_KEYS = ("image", "reference", "rest", "displacement", "disp_image", "disp_reference")


@dataclass
class StreamConfig:
    """One streaming run (recorded in every output's metadata)."""

    preset: str = "mixed"
    seed: int = 0
    max_shear: float = 0.6
    workers: int = 2
    capacity: int = 60_000
    warm: int = 512
    seconds: float = 300.0
    max_steps: int = 0  # 0: until ``seconds`` run out
    batch: int = 64
    crop: tuple[int, int] = (160, 128)
    lr: float = 2e-3
    warmup_fraction: float = 0.03
    weight_decay: float = 1e-4
    single_weight: float = 0.5
    ema: float = 0.999
    n_val: int = 256
    eval_every: int = 500
    device: str = "auto"
    #: name -> {"widths": [...], "loss": "euclid" | "mse", "augment": bool, "init": path of
    #: a ``{name}.pt`` of an earlier run (its weights; "" or absent: from scratch)}
    variants: dict[str, dict[str, Any]] = field(
        default_factory=lambda: {"base": {"widths": [32, 64, 96, 128], "loss": "euclid",
                                          "augment": True}})


def resolve_device(device: str) -> Any:
    """``"auto"``: CUDA when torch sees a GPU, else the CPU; otherwise ``torch.device(device)``."""
    import torch

    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except RuntimeError as exc:
        raise ValueError(f"device: not a torch device: {device!r}") from exc
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device: {device!r} asked for, but torch sees no CUDA GPU")
    return dev


def _one_thread() -> None:
    """Rendering workers use one thread each (the pool is the parallelism)."""
    import cv2

    cv2.setNumThreads(1)


def _render(job: tuple[str, int, int, str, float]) -> dict[str, Any]:
    from tacswitch.motion.data import SPLITS, render_gel_pair_sample, split_spec

    preset, seed, i, split, max_shear = job
    classes, frac = split_spec(split)
    s = render_gel_pair_sample(preset, np.random.SeedSequence([seed, 200 + SPLITS.index(split), i]),
                               classes=classes, depth_frac=frac, max_shear=max_shear)
    return {k: s[k] for k in _KEYS}


def _jobs(cfg: StreamConfig) -> Any:
    i = 0
    while True:
        yield (cfg.preset, cfg.seed, i, "train", cfg.max_shear)
        i += 1


def _val_jobs(cfg: StreamConfig) -> list[tuple[str, int, int, str, float]]:
    half = cfg.n_val // 2
    return ([(cfg.preset, cfg.seed + 1000, i, "test_indenter", cfg.max_shear)
             for i in range(half)]
            + [(cfg.preset, cfg.seed + 1000, i, "test_depth", cfg.max_shear)
               for i in range(cfg.n_val - half)])


class _Buffer:
    """Pairs on the training device, filled as they arrive (oldest overwritten when full)."""

    def __init__(self, capacity: int, first: dict[str, Any], device: Any) -> None:
        import torch

        self.capacity, self.n, self.next, self.total = capacity, 0, 0, 0
        self.data = {k: torch.empty((capacity, *np.shape(first[k])),
                                    dtype=torch.uint8 if k in ("image", "reference")
                                    else torch.float32, device=device) for k in _KEYS}

    def add(self, item: dict[str, Any]) -> None:
        import torch

        for k in _KEYS:
            self.data[k][self.next] = torch.from_numpy(np.asarray(item[k]))
        self.next = (self.next + 1) % self.capacity
        self.n = min(self.n + 1, self.capacity)
        self.total += 1

    def batch(self, idx: Any) -> dict[str, Any]:
        return {k: v[idx] for k, v in self.data.items()}


def augment(b: dict[str, Any], gen: Any, *, colour: bool = True) -> dict[str, Any]:
    """Random mirror flips (centres mirrored, motion signs flipped), and with ``colour`` one
    channel permutation per pair plus a per-channel gain (0.8-1.25) and gamma (0.8-1.25) applied
    alike to both frames. Frames ``B x H x W x 3`` uint8; motions ``B x N x 2``."""
    import torch

    img, ref = b["image"], b["reference"]
    bsz, h, w = img.shape[:3]
    dev = img.device
    out = dict(b)
    flips = torch.rand(bsz, 2, generator=gen, device=dev) < 0.5
    for axis, size, dim in ((0, w, 2), (1, h, 1)):
        f = flips[:, axis]
        if not bool(f.any()):
            continue
        img = torch.where(f[:, None, None, None], img.flip(dim), img)
        ref = torch.where(f[:, None, None, None], ref.flip(dim), ref)
        rest = out["rest"].clone()
        rest[..., axis] = torch.where(f[:, None], (size - 1) - rest[..., axis], rest[..., axis])
        out["rest"] = rest
        for k in ("displacement", "disp_image", "disp_reference"):
            m = out[k].clone()
            m[..., axis] = torch.where(f[:, None], -m[..., axis], m[..., axis])
            out[k] = m
    if colour:
        perm = torch.argsort(torch.rand(bsz, 3, generator=gen, device=dev), dim=1)
        gain = torch.exp(torch.empty(bsz, 1, 1, 3, device=dev).uniform_(-0.22, 0.22,
                                                                          generator=gen))
        gamma = torch.exp(torch.empty(bsz, 1, 1, 3, device=dev).uniform_(-0.22, 0.22,
                                                                           generator=gen))
        idx = perm[:, None, None, :].expand(-1, h, w, -1)

        def look(x: Any) -> Any:
            x = torch.gather(x, 3, idx).float() / 255.0
            x = (x.clamp(min=0.0) ** gamma) * gain
            return (x * 255.0).round().clamp(0, 255).to(torch.uint8)

        img, ref = look(img), look(ref)
    out["image"], out["reference"] = img, ref
    return out


def stream_loss(net: Any, b: dict[str, Any], kind: str, single_weight: float,
                crop: tuple[int, int], gen: Any) -> Any:
    """Pair loss plus ``single_weight`` times each frame's single-frame loss (one batch of three
    through ``G``); frames normalised whole, then one random crop (stride-4 offsets)."""
    import torch

    from tacswitch.motion.model import sample_at
    from tacswitch.motion.train import crop_frames, sparse_loss

    x, r = net.norm(b["image"]), net.norm(b["reference"])
    cen = b["rest"]
    tgt, d_img, d_ref = b["displacement"], b["disp_image"], b["disp_reference"]
    h, w = x.shape[-2:]
    cw, ch = crop
    if cw and ch and (cw < w or ch < h):
        x0 = 4 * int(torch.randint(0, (w - cw) // 4 + 1, (1,), generator=gen, device=gen.device))
        y0 = 4 * int(torch.randint(0, (h - ch) // 4 + 1, (1,), generator=gen, device=gen.device))
        x, r, cen, (tgt, d_img, d_ref) = crop_frames(x, r, cen, (tgt, d_img, d_ref), x0, y0,
                                                      (cw, ch))
        h, w = ch, cw
    n = x.shape[0]
    f = net._g(torch.cat([r, x, x]), torch.cat([torch.zeros_like(r), x - r, torch.zeros_like(x)]))
    s_ref, s_img = f[:n], f[2 * n:]
    pair = f[n:2 * n] - s_ref
    loss = sparse_loss(sample_at(pair, cen, h, w), tgt, kind)
    loss = loss + single_weight * (sparse_loss(sample_at(s_ref, cen, h, w), d_ref, kind)
                                   + sparse_loss(sample_at(s_img, cen, h, w), d_img, kind))
    return loss


def evaluate(net: Any, val: dict[str, Any], batch: int = 64) -> dict[str, float]:
    """Pair and single-frame e_rmse (px) and mean direction cosine over markers moving >= 1 px,
    with zero motion's e_rmse beside them."""
    import torch

    errs: dict[str, list[Any]] = {"pair": [], "single": [], "zero_pair": [], "zero_single": []}
    cos: dict[str, list[Any]] = {"pair": [], "single": []}
    net.eval()
    with torch.no_grad():
        for i in range(0, len(val["image"]), batch):
            b = {k: v[i:i + batch] for k, v in val.items()}
            for name, pred, tgt in (("pair", net(b["image"], b["rest"], b["reference"]),
                                     b["displacement"]),
                                    ("single", net(b["image"], b["rest"]), b["disp_image"])):
                ok = torch.isfinite(tgt).all(-1)
                errs[name].append(torch.linalg.norm(pred - tgt, dim=-1)[ok])
                errs["zero_" + name].append(torch.linalg.norm(tgt, dim=-1)[ok])
                mag = torch.linalg.norm(tgt, dim=-1)
                moved = ok & (mag >= 1.0)
                c = (pred * tgt).sum(-1) / (torch.linalg.norm(pred, dim=-1) * mag + 1e-9)
                cos[name].append(c[moved])
    net.train()
    out = {f"{k}_e_rmse": float(torch.cat(v).mean()) for k, v in errs.items()}
    out.update({f"{k}_cos": float(torch.cat(v).mean()) for k, v in cos.items()})
    return out


def _ema_fn(decay: float) -> Any:
    """EMA update whose decay ramps up as ``(1 + n) / (10 + n)`` to ``decay``: early weights
    are not frozen into the average."""

    def fn(avg: Any, cur: Any, n: Any) -> Any:
        d = ((1.0 + n) / (10.0 + n)).clamp(max=decay)  # a tensor: no device sync
        return d * avg + (1.0 - d) * cur

    return fn


def _lr_factor(t: float, warmup: float) -> float:
    if t < warmup:
        return max(t / warmup, 1e-3)
    return 0.5 * (1.0 + math.cos(math.pi * min(1.0, (t - warmup) / max(1e-9, 1.0 - warmup))))


def train_stream(out: str | Path, cfg: StreamConfig, *, progress: bool = True
                 ) -> dict[str, Any]:
    """Runs one streaming training (see the module docstring); returns the last validation
    scores per variant. Rendering workers are spawned processes (safe beside CUDA and torch's
    thread pools)."""
    import multiprocessing as mp

    import torch

    from tacswitch.motion.export import export_onnx
    from tacswitch.motion.model import ConsistentMotionNet, count_params

    if cfg.workers < 1:
        raise ValueError(f"workers: must be >= 1; got {cfg.workers}")
    if cfg.capacity < max(cfg.warm, cfg.batch):
        raise ValueError(f"capacity: must hold at least warm and one batch; got {cfg.capacity}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    from tacswitch.motion.data import MIXED_PRESETS
    from tacswitch.sim.presets import PRESETS

    if cfg.preset not in (*MIXED_PRESETS, *PRESETS):
        raise ValueError(f"preset: one of {(*MIXED_PRESETS, *PRESETS)}; got {cfg.preset!r}")
    # Spawned, not forked: a fork of a process whose torch / OpenMP threads already ran can
    # deadlock in the child.
    pool = mp.get_context("spawn").Pool(cfg.workers, initializer=_one_thread)
    t_start = time.perf_counter()
    try:
        val_items = pool.map(_render, _val_jobs(cfg), chunksize=4)
        arrivals: queue.Queue[dict[str, Any]] = queue.Queue(maxsize=4 * cfg.workers)
        stop = threading.Event()

        def feed() -> None:
            for item in pool.imap_unordered(_render, _jobs(cfg), chunksize=2):
                if stop.is_set():
                    return
                while not stop.is_set():
                    try:
                        arrivals.put(item, timeout=0.5)
                        break
                    except queue.Full:
                        continue

        feeder = threading.Thread(target=feed, daemon=True)
        feeder.start()
        dev = resolve_device(cfg.device)
        torch.manual_seed(cfg.seed)
        gen = torch.Generator(device=dev)
        gen.manual_seed(cfg.seed)
        val = {k: torch.from_numpy(np.stack([v[k] for v in val_items])).to(dev) for k in _KEYS}
        first = arrivals.get()
        buf = _Buffer(cfg.capacity, first, dev)
        buf.add(first)
        nets, opts, emas = {}, {}, {}
        for name, spec in cfg.variants.items():
            net = ConsistentMotionNet(tuple(spec.get("widths", (32, 64, 96, 128)))).to(dev)
            nets[name] = net
            opts[name] = torch.optim.AdamW(net.parameters(), lr=cfg.lr,
                                           weight_decay=cfg.weight_decay)
            if spec.get("init"):
                state = torch.load(spec["init"], map_location="cpu", weights_only=False)
                net.load_state_dict(state["model"])
            else:
                # Zero motion at the start (the head's output), as an untrained consistent
                # model should predict.
                for param in net.body.head.parameters():
                    torch.nn.init.zeros_(param)
            emas[name] = torch.optim.swa_utils.AveragedModel(
                net, avg_fn=_ema_fn(cfg.ema), use_buffers=True)
            if progress:
                print(f"{name}: {count_params(net)} parameters on {dev}", flush=True)
        log_path = out / "log.jsonl"
        t_train: float | None = None
        budget, step = cfg.seconds, 0
        last: dict[str, Any] = {}
        while True:
            while True:
                try:
                    buf.add(arrivals.get_nowait())
                except queue.Empty:
                    break
            if buf.n < cfg.warm:
                buf.add(arrivals.get())
                continue
            if t_train is None:
                t_train = time.perf_counter()
                budget = cfg.seconds - (t_train - t_start)
                if progress:
                    print(f"training from {buf.n} pairs, {budget:.0f} s left", flush=True)
            frac = (time.perf_counter() - t_train) / max(1.0, budget)
            done = frac >= 1.0 or (cfg.max_steps and step >= cfg.max_steps)
            if done or (step and step % cfg.eval_every == 0):
                entry: dict[str, Any] = {"step": step, "pairs": buf.total,
                                         "seconds": round(time.perf_counter() - t_start, 1)}
                for name in nets:
                    last[name] = evaluate(emas[name].module, val)
                    entry[name] = {k: round(v, 4) for k, v in last[name].items()}
                with open(log_path, "a") as fh:
                    fh.write(json.dumps(entry) + "\n")
                if progress:
                    print(json.dumps(entry), flush=True)
            if done:
                break
            lr = cfg.lr * _lr_factor(frac, cfg.warmup_fraction)
            idx = torch.randint(0, buf.n, (cfg.batch,), generator=gen, device=dev)
            raw = buf.batch(idx)
            for name, net in nets.items():
                spec = cfg.variants[name]
                b = augment(raw, gen, colour=bool(spec.get("augment", True)))
                loss = stream_loss(net, b, spec.get("loss", "euclid"), cfg.single_weight,
                                   (cfg.crop[0], cfg.crop[1]), gen)
                for g in opts[name].param_groups:
                    g["lr"] = lr
                opts[name].zero_grad(set_to_none=True)
                loss.backward()
                opts[name].step()
                emas[name].update_parameters(net)
            step += 1
        stop.set()
    finally:
        pool.terminate()
    from tacswitch.motion.data import MIXED_PRESETS, preset_grid

    h, w = first["image"].shape[:2]
    grid = preset_grid("gelsight_mini" if cfg.preset in MIXED_PRESETS else cfg.preset)
    meta = {"work_width": int(w), "work_height": int(h), "seed": cfg.seed,
            "default_centres": [[round(float(x), 3), round(float(y), 3)] for x, y in grid],
            "trained_on": {"stream": asdict(cfg), "steps": step, "pairs_rendered": buf.total},
            "loss": "", "epochs": 0}
    nets_cpu: dict[str, Any] = {}
    for name, ema in emas.items():
        nets_cpu[name] = ema.module.to("cpu").eval()
        torch.save({"model": nets_cpu[name].state_dict(), "config": asdict(cfg), "variant": name,
                    "steps": step, "meta": meta}, out / f"{name}.pt")
    for name, net in nets_cpu.items():
        export_onnx(net, out / f"{name}.onnx", height=h, width=w,
                    metadata={**meta, "loss": cfg.variants[name].get("loss", "euclid"),
                              "variant": {name: cfg.variants[name]}})
    return last


def main(argv: list[str] | None = None) -> int:
    """``python -m tacswitch.motion.train_stream --out DIR [--seconds S] ...``"""
    import argparse

    d = StreamConfig()
    ap = argparse.ArgumentParser(prog="python -m tacswitch.motion.train_stream",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="run folder")
    ap.add_argument("--seconds", type=float, default=d.seconds, help="time budget of the run")
    ap.add_argument("--max-steps", type=int, default=d.max_steps)
    ap.add_argument("--workers", type=int, default=d.workers, help="rendering processes")
    ap.add_argument("--capacity", type=int, default=d.capacity, help="pairs kept in the buffer")
    ap.add_argument("--warm", type=int, default=d.warm, help="pairs before the first step")
    ap.add_argument("--batch", type=int, default=d.batch)
    ap.add_argument("--lr", type=float, default=d.lr)
    ap.add_argument("--max-shear", type=float, default=d.max_shear)
    ap.add_argument("--seed", type=int, default=d.seed)
    ap.add_argument("--preset", default=d.preset, help="mixed, mixed_moving or a simulator preset")
    ap.add_argument("--single-weight", type=float, default=d.single_weight)
    ap.add_argument("--n-val", type=int, default=d.n_val)
    ap.add_argument("--eval-every", type=int, default=d.eval_every)
    ap.add_argument("--device", default=d.device, help="auto (default), cpu, cuda, cuda:1, ...")
    ap.add_argument("--variants", default=None,
                    help='JSON: {"name": {"widths": [32, 64, 96, 128], "loss": "euclid", '
                         '"augment": true}, ...}')
    a = ap.parse_args(argv)
    try:
        variants = json.loads(a.variants) if a.variants else d.variants
    except json.JSONDecodeError as exc:
        raise SystemExit(f"--variants: not JSON: {exc}") from None
    cfg = StreamConfig(seconds=a.seconds, max_steps=a.max_steps, workers=a.workers,
                       capacity=a.capacity, warm=a.warm, batch=a.batch, lr=a.lr,
                       max_shear=a.max_shear, seed=a.seed, preset=a.preset,
                       single_weight=a.single_weight, n_val=a.n_val,
                       eval_every=a.eval_every, device=a.device, variants=variants)
    train_stream(a.out, cfg)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
