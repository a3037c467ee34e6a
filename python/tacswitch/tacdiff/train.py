"""Training of the TacDiff denoiser (torch).

Each step draws random crops (:class:`~tacswitch.tacdiff.data.CropSampler`), a time ``t`` per
crop (uniform, with a share of exactly ``t = 1`` so the pure-noise first step of few-step
sampling is trained directly), noises the target's residual over the TELEA prior (see
:mod:`~tacswitch.tacdiff.model`), and regresses v on the pixels of
``loss_mask`` only (Palette's masked loss; on a user's sensor these are real pixels, never
TELEA's). The loss (``TrainConfig.loss``, :data:`LOSSES`) is the squared v error
(``"v_mse"``) or the absolute error of the network's x0 estimate (``"x0_l1"``): at ``t = 1``,
the whole output of the default one-step sampler, MSE pulls that output to the conditional
mean and L1 to the median, which codec outliers pull less (masked MAE, the judge, is L1).
Adam with a warm-up and cosine decay; the weights' exponential moving average (EMA) is kept
and is what gets exported (the paper trained EMA weights and never used them).

Resumable and deterministic by seed: ``out/checkpoint.pt`` (model, EMA, optimiser, step, log,
config) is replaced atomically every ``save_every`` steps and at the end; rerunning the same
command continues from it. ``out/log.jsonl`` has one line per logged interval;
``out/model.safetensors`` holds the final EMA weights.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._io import save_torch
from tacswitch.tacdiff.prior import DEFAULT_PRIOR, DEFAULT_PRIOR_RADIUS, PRIOR_RADIUS, check_radius
from tacswitch.tacdiff.schedule import alpha_sigma

#: Training losses (``TrainConfig.loss``): squared v error, or absolute x0 error
#: (``sigma * |v_pred - v|``: full weight at ``t = 1``, little at low noise).
LOSSES: tuple[str, ...] = ("v_mse", "x0_l1")


@dataclass
class TrainConfig:
    """Hyper-parameters of one run (recorded in the checkpoint and the model's metadata)."""

    base: int = 24
    mults: tuple[int, ...] = (1, 2, 3, 4)
    attention: bool = False
    prior: str = DEFAULT_PRIOR  # classical fill the residual is taken over (tacdiff.prior)
    prior_radius: float = DEFAULT_PRIOR_RADIUS  # that fill's TELEA radius, px
    steps: int = 3000
    batch: int = 12
    crop: int = 96
    lr: float = 5e-4
    warmup: int = 200
    ema: float = 0.999
    terminal_fraction: float = 0.2  # share of crops trained at t = 1 exactly
    loss: str = "v_mse"  # one of LOSSES
    contact_share: float = 0.0  # share of crops centred on a hole in contact (CropSampler)
    hole_share: float = 0.5  # share of crops centred on any hole
    seed: int = 0
    threads: int = 0  # 0: os.cpu_count()
    save_every: int = 250
    log_every: int = 50
    # Seconds of training after which the run ends (0: none). The cosine decay then follows
    # whichever of steps or seconds runs out first, so such a run is not reproducible step
    # for step (the time a step takes varies); for a fixed share of a rented GPU.
    time_budget: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def sample_times(n: int, rng: np.random.Generator, terminal_fraction: float) -> NDArray[np.float32]:
    """``n`` training times in (0, 1]: uniform, a share set to exactly 1 (pure noise)."""
    t = rng.uniform(1e-3, 1.0, n)
    t[rng.random(n) < terminal_fraction] = 1.0
    return t.astype(np.float32)


def check_loss(loss: object, name: str = "loss") -> str:
    """``loss`` if it names one of :data:`LOSSES`, else ``ValueError`` naming ``name``."""
    if loss not in LOSSES:
        raise ValueError(f"{name}: expected one of {LOSSES}; got {loss!r}")
    return str(loss)


def masked_v_loss(net: Any, batch: dict[str, NDArray[Any]], t: NDArray[np.float32],
                  rng: np.random.Generator, loss: str = "v_mse") -> Any:
    """Mean loss over the ``loss_mask`` pixels of a batch (all channels): squared v error
    (``"v_mse"``) or absolute error of the x0 estimate ``alpha * x_t - sigma * v_pred``
    (``"x0_l1"``; equal to ``sigma * |v_pred - v|``). The diffused quantity is the scaled
    residual of the target over the classical prior."""
    import torch

    from tacswitch.tacdiff.model import RESIDUAL_SCALE, network_input

    # The network's device (a module's first parameter); plain callables run on the CPU.
    params = getattr(net, "parameters", None)
    dev = next(iter(params())).device if params is not None else torch.device("cpu")
    to = lambda a: torch.from_numpy(a).to(dev, non_blocking=True)  # noqa: E731
    cond, target, prior = to(batch["cond"]), to(batch["target"]), to(batch["prior"])
    mask, lmask = to(batch["mask"]), to(batch["loss_mask"])
    a, s = (to(u.astype(np.float32))[:, None, None, None] for u in alpha_sigma(t))
    r0 = RESIDUAL_SCALE * (target - prior) * mask
    # The noise is drawn here unless the batch carries it (drawn from rng at the same point).
    noise = batch["eps"] if "eps" in batch else draw_noise(batch, rng)
    eps = to(noise)
    x_t = a * r0 + s * eps
    v = a * eps - s * r0
    spread = to(batch["spread"]) if "spread" in batch else None
    pred = net(network_input(cond, mask, x_t, eps, prior, spread), s.flatten())
    denom = lmask.sum() * 3
    if float(denom) == 0:
        return pred.sum() * 0.0
    if check_loss(loss) == "x0_l1":
        # x0_pred - r0 = (a * x_t - s * pred) - r0 = -s * (pred - v), exactly.
        return ((s * (pred - v)).abs() * lmask).sum() / denom
    return (((pred - v) ** 2) * lmask).sum() / denom


def draw_noise(batch: dict[str, NDArray[Any]], rng: np.random.Generator) -> NDArray[np.float32]:
    """The diffusion noise of ``batch`` (standard normal, shaped like its ``target``)."""
    # float64 draws cast down: the stream of every run before the GPU options, so their
    # checkpoints resume on the same noise.
    return rng.standard_normal(batch["target"].shape).astype(np.float32)


def step_batches(sampler: Any, cfg: TrainConfig, start: int, workers: int = 0
                 ) -> Iterator[tuple[dict[str, NDArray[Any]], NDArray[np.float32],
                                     np.random.Generator]]:
    """``(batch, t, rng)`` of every step from ``start`` on: the crops, times and noise
    (``batch["eps"]``) drawn from ``default_rng([seed, step])`` in a fixed order, so a resumed
    or prefetched run draws what a plain one would. ``workers`` > 0 threads prepare batches
    ahead of the training step (NumPy releases the GIL in its array loops)."""
    def make(step: int) -> tuple[dict[str, NDArray[Any]], NDArray[np.float32],
                                 np.random.Generator]:
        rng = np.random.default_rng([cfg.seed, step])
        batch = sampler.batch(cfg.batch, rng)
        t = sample_times(cfg.batch, rng, cfg.terminal_fraction)
        batch["eps"] = draw_noise(batch, rng)
        return batch, t, rng

    if workers <= 0:
        yield from (make(step) for step in range(start, cfg.steps))
        return
    from collections import deque
    from concurrent.futures import Future, ThreadPoolExecutor

    with ThreadPoolExecutor(workers) as pool:
        pending: deque[Future[Any]] = deque()
        step = start
        try:
            while step < cfg.steps or pending:
                while step < cfg.steps and len(pending) < 2 * workers:
                    pending.append(pool.submit(make, step))
                    step += 1
                yield pending.popleft().result()
        finally:
            for f in pending:
                f.cancel()


def pick_device(device: str, name: str = "device") -> str:
    """``"cpu"``, ``"cuda"`` (``"cuda:N"``) or ``"auto"`` (CUDA when torch sees a GPU) ->
    a torch device name; ``ValueError`` naming ``name`` if it is unknown or absent."""
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cpu":
        return device
    if device == "cuda" or device.startswith("cuda:"):
        if not torch.cuda.is_available():
            raise ValueError(f"{name}: {device!r} asked for, but torch sees no CUDA GPU")
        index = device.partition(":")[2]
        if index and not (index.isdigit() and int(index) < torch.cuda.device_count()):
            raise ValueError(f"{name}: no GPU {index!r}; torch sees "
                             f"{torch.cuda.device_count()} (cuda:0 ..)")
        return device
    raise ValueError(f"{name}: expected 'cpu', 'cuda', 'cuda:N' or 'auto'; got {device!r}")


def train(shards: list[dict[str, NDArray[Any]]], out: str | Path, cfg: TrainConfig,
          *, progress: bool = True, init: str | Path | None = None,
          callback: Callable[[int, Any], None] | None = None, callback_every: int = 0,
          device: str = "cpu", workers: int = 0) -> Any:
    """Trains (or resumes) a denoiser on ``shards`` and returns the EMA network (eval mode).

    Args:
        shards: arrays as :mod:`tacswitch.tacdiff.data` describes (``cond``, ``target``, ``mask``,
            ``loss_mask``).
        out: run folder (checkpoint, log, weights).
        cfg: hyper-parameters.
        init: a checkpoint or ``.safetensors`` file to start from (fine-tuning); ignored when
            resuming.
        callback: called as ``callback(step, ema)`` every ``callback_every`` steps and after
            the last one, before that step's checkpoint is written (a validation: see
            :mod:`~tacswitch.tacdiff.finetune`); the EMA network is in eval mode, do not train it.
        device: torch device of the training (:func:`pick_device`; the data stays in NumPy).
            The result does not depend on it beyond floating-point rounding.
        workers: threads preparing batches ahead (:func:`step_batches`; 0: none).
    """
    import torch

    from tacswitch.tacdiff.data import CropSampler
    from tacswitch.tacdiff.model import DenoiserUNet, UNetConfig, count_params

    radius = check_radius(cfg.prior_radius)
    check_loss(cfg.loss)
    if not (np.isfinite(cfg.time_budget) and cfg.time_budget >= 0):
        raise ValueError(f"time_budget: must be seconds >= 0; got {cfg.time_budget!r}")
    if not 0 <= cfg.terminal_fraction <= 1:  # also refuses NaN
        raise ValueError(f"terminal_fraction: must be in [0, 1]; got {cfg.terminal_fraction!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads or os.cpu_count() or 1)
    ucfg = UNetConfig(base=cfg.base, mults=tuple(cfg.mults), attention=cfg.attention,
                      prior=cfg.prior, prior_radius=radius)
    dev = pick_device(device)
    net = DenoiserUNet(ucfg).to(dev)
    ema = DenoiserUNet(ucfg).to(dev)
    sampler = CropSampler(shards, cfg.crop, prior=cfg.prior, prior_radius=radius,
                          contact_share=cfg.contact_share, hole_share=cfg.hole_share)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)

    def lr_at(step: int, time_frac: float = 0.0) -> float:
        if step < cfg.warmup:
            return cfg.lr * (step + 1) / cfg.warmup
        frac = max((step - cfg.warmup) / max(1, cfg.steps - cfg.warmup), time_frac)
        return cfg.lr * 0.5 * (1 + np.cos(np.pi * min(1.0, frac)))

    ckpt_path = out / "checkpoint.pt"
    start, log, elapsed = 0, [], 0.0
    if ckpt_path.is_file():
        ck = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        # Checkpoints written before the loss was recorded trained v_mse.
        if {"loss": "v_mse", "time_budget": 0.0, **ck["config"]} != config_dict(cfg):
            raise ValueError(f"out: {str(out)!r} holds a run with another configuration; "
                             "use another folder")
        net.load_state_dict(ck["model"])
        ema.load_state_dict(ck["ema"])
        opt.load_state_dict(ck["optim"])
        start, log, elapsed = ck["step"], ck["log"], float(ck.get("elapsed", 0.0))
        if progress:
            print(f"resuming after step {start}", flush=True)
    else:
        if init is not None:
            net.load_state_dict(load_weights(init))
        ema.load_state_dict(net.state_dict())
        if progress:
            print(f"TacDiff U-Net base {cfg.base}: {count_params(net)} parameters, "
                  f"{sum(len(s['cond']) for s in shards)} frames, crops {cfg.crop}", flush=True)
    ema.eval()
    for p in ema.parameters():
        p.requires_grad_(False)
    losses: list[float] = []
    t0 = time.perf_counter()

    def time_frac() -> float:
        spent = elapsed + time.perf_counter() - t0
        return spent / cfg.time_budget if cfg.time_budget > 0 else 0.0

    # Randomness from (seed, step): a resumed run draws what an uninterrupted one would.
    # A run that already spent its time budget is finished, like one at cfg.steps.
    end = start if cfg.time_budget > 0 and elapsed >= cfg.time_budget else cfg.steps
    batches = step_batches(sampler, cfg, start, workers)
    for step, (batch, t, rng) in zip(range(start, end), batches, strict=False):
        net.train()
        for g in opt.param_groups:
            g["lr"] = lr = lr_at(step, time_frac())
        loss = masked_v_loss(net, batch, t, rng, cfg.loss)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        with torch.no_grad():
            decay = min(cfg.ema, (1 + step) / (10 + step))
            for pe, pn in zip(ema.parameters(), net.parameters(), strict=True):
                pe.lerp_(pn, 1 - decay)
        losses.append(float(loss.detach()))
        done = step + 1
        last = done == cfg.steps or time_frac() >= 1.0
        if done % cfg.log_every == 0 or last:
            entry = {"step": done, "loss": float(np.mean(losses)), "lr": lr,
                     "seconds": round(time.perf_counter() - t0, 2)}
            log.append(entry)
            losses = []
            with open(out / "log.jsonl", "a") as fh:
                fh.write(json.dumps(entry) + "\n")
            if progress:
                print(json.dumps(entry), flush=True)
        if callback is not None and ((callback_every and done % callback_every == 0)
                                     or last):
            callback(done, ema)
        if done % cfg.save_every == 0 or last:
            save_torch(ckpt_path, {"model": net.state_dict(), "ema": ema.state_dict(),
                              "optim": opt.state_dict(), "step": done, "log": log,
                              "config": config_dict(cfg),
                              "elapsed": elapsed + time.perf_counter() - t0})
        if last:
            break
    save_weights(ema, out / "model.safetensors", config_dict(cfg))
    return ema.cpu()


def config_dict(cfg: TrainConfig) -> dict[str, Any]:
    """``cfg`` as the JSON-able dict recorded in checkpoints and weight files."""
    d = asdict(cfg)
    d["mults"] = list(cfg.mults)
    return d


def save_weights(net: Any, path: str | Path, config: dict[str, Any], *,
                 half: bool = False) -> Path:
    """Writes ``net``'s weights as safetensors (atomically) with its config as metadata;
    ``half``: floating tensors in float16 (half the size; :func:`load_weights` restores
    float32)."""
    from safetensors.torch import save_file

    target = Path(path)
    tmp = target.with_name(f".{target.name}.tmp")
    state = {k: (v.half() if half and v.is_floating_point() else v).detach().cpu().contiguous()
             for k, v in net.state_dict().items()}
    save_file(state, str(tmp), metadata={"tacswitch.config": json.dumps(config)})
    # safetensors creates the file private (0600); give it the mode a plain open() would have.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, target)
    return target


def load_weights(path: str | Path) -> dict[str, Any]:
    """A state dict from a ``.safetensors`` file, a training checkpoint (its EMA weights) or a
    TacDiff ``.onnx`` file (:func:`~tacswitch.tacdiff.export.network_from_onnx`)."""
    import torch

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"init: no file at {str(p)!r}")
    if p.suffix == ".onnx":
        from tacswitch.tacdiff.export import network_from_onnx

        return dict(network_from_onnx(p).state_dict())
    if p.suffix == ".safetensors":
        from safetensors.torch import load_file

        return {k: v.float() if v.is_floating_point() else v
                for k, v in load_file(str(p)).items()}
    ck = torch.load(p, map_location="cpu", weights_only=False)
    return ck["ema"] if "ema" in ck else ck


def load_network(path: str | Path) -> Any:
    """A :class:`DenoiserUNet` (eval mode) from a ``.safetensors`` file written by :func:`train`
    or :func:`save_weights`, a training checkpoint (its EMA weights) or a TacDiff ``.onnx``
    file; the architecture comes from the file's recorded configuration."""
    import torch

    from tacswitch.tacdiff.model import DenoiserUNet, UNetConfig

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"path: no file at {str(p)!r}")
    if p.suffix == ".onnx":
        from tacswitch.tacdiff.export import network_from_onnx

        return network_from_onnx(p)
    if p.suffix == ".safetensors":
        from safetensors import safe_open

        with safe_open(str(p), "pt") as fh:
            meta = fh.metadata() or {}
        cfg = json.loads(meta.get("tacswitch.config", "{}"))
    else:
        ck = torch.load(p, map_location="cpu", weights_only=False)
        if not isinstance(ck, dict) or "ema" not in ck or "config" not in ck:
            raise ValueError(f"path: {str(p)!r} is not a TacDiff training checkpoint")
        cfg = ck["config"]
    defaults = UNetConfig()
    net = DenoiserUNet(UNetConfig(base=cfg.get("base", defaults.base),
                                  mults=tuple(cfg.get("mults", defaults.mults)),
                                  attention=cfg.get("attention", defaults.attention),
                                  # Files written before the prior was recorded used TELEA,
                                  # those before its radius was recorded r = 3.
                                  prior=cfg.get("prior", "telea"),
                                  prior_radius=check_radius(
                                      cfg.get("prior_radius", PRIOR_RADIUS), "path")))
    net.load_state_dict(load_weights(p))
    return net.eval()
