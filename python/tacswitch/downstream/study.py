"""Training and scoring of the downstream models, and the comparison table (torch).

One *run* trains one model on one input type with one seed and scores it on that seed's test
split:

- ``texture``: ResNet-18 (torchvision, ``weights=None``: nothing is downloaded) on
  ``texture_crop``-px crops at full resolution centred on the contact (its centroid, as a
  pipeline would find it against the no-contact frame; the same crop for every input type),
  jittered by up to 1/8 of the crop and flipped in training. Split 50/50 per class.
  Metrics: accuracy, and the number of classes with a misclassified test sample (the paper's
  table).
- ``contact``: DeepLabV3 with a MobileNetV3-Large backbone (torchvision, ``weights=None,
  weights_backbone=None``; the ResNet-50 DeepLabV3 does not train in the time budget on a CPU)
  on frames area-downsampled by ``contact_scale``, two classes, flips. Split 85/15. Metrics:
  pixel accuracy and the contact class's IoU over the whole test split.

Frames enter the networks as BGR, the order they are stored and served in (the paper's scripts
mixed BGR and RGB between training and deployment). A seed fixes the split, the initialisation
and the batch order, identically for every input type, so differences between inputs are
paired. Results are appended to ``results.jsonl`` one run at a time; a rerun skips finished runs.
A run is identified by its task, input, seed, scale and a hash of the very frames and labels it
saw, so a new TacDiff model (or TELEA change) redoes exactly the runs whose frames changed.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.downstream.data import (
    INPUT_NAMES,
    INPUTS,
    TASKS,
    StudyScale,
    array_hash,
    load_dataset,
    scale_dict,
)

#: Per-channel normalisation of uint8 frames: (x / 255 - 0.5) / 0.25.
MEAN, STD = 0.5, 0.25
#: Share of each class (texture) or of the samples (contact) used for training.
TRAIN_SHARE = {"texture": 0.5, "contact": 0.85}
#: AdamW settings of every run.
LR, WEIGHT_DECAY = 1e-3, 1e-4
#: Fewer seeds than this give no verdict (a standard error from two runs means little).
MIN_SEEDS_FOR_VERDICT = 3
#: Metrics of each task, in table order; the first is the headline.
METRICS = {"texture": ("accuracy", "classes_with_errors"),
           "contact": ("iou", "pixel_accuracy")}


def split(labels: NDArray[np.int64], task: str, seed: int) -> tuple[NDArray[np.int64],
                                                                      NDArray[np.int64]]:
    """Train and test indices for ``seed``: stratified per class for ``texture``."""
    rng = np.random.default_rng([seed, 17])
    share = TRAIN_SHARE[task]
    if task == "texture":
        train, test = [], []
        for c in np.unique(labels):
            idx = rng.permutation(np.flatnonzero(labels == c))
            k = max(1, round(len(idx) * share))
            train.append(idx[:k])
            test.append(idx[k:])
        return np.sort(np.concatenate(train)), np.sort(np.concatenate(test))
    idx = rng.permutation(len(labels))
    k = min(len(idx) - 1, max(1, round(len(idx) * share)))
    return np.sort(idx[:k]), np.sort(idx[k:])


def to_tensor(imgs: NDArray[np.uint8]) -> Any:
    """``B x H x W x 3`` uint8 BGR -> normalised float32 ``B x 3 x H x W`` tensor."""
    import torch

    x = torch.from_numpy(np.ascontiguousarray(imgs)).permute(0, 3, 1, 2).float()
    return (x / 255.0 - MEAN) / STD


def contact_centres(contact: NDArray[np.bool_]) -> NDArray[np.int64]:
    """``B x 2`` (y, x) centroid of each frame's contact mask (the frame centre if empty)."""
    b, h, w = contact.shape
    out = np.empty((b, 2), np.int64)
    for i, c in enumerate(contact):
        ys, xs = np.nonzero(c)
        out[i] = (round(ys.mean()), round(xs.mean())) if len(ys) else (h // 2, w // 2)
    return out


def crop_at(img: NDArray[np.uint8], cy: int, cx: int, side: int) -> NDArray[np.uint8]:
    """The ``side x side`` crop of ``img`` centred at (cy, cx), shifted inside the frame."""
    h, w = img.shape[:2]
    y = min(max(0, cy - side // 2), h - side)
    x = min(max(0, cx - side // 2), w - side)
    return img[y:y + side, x:x + side]


def _schedule(opt: Any, total: int) -> Callable[[int], None]:
    warm = max(1, total // 20)

    def set_lr(step: int) -> None:
        f = (step + 1) / warm if step < warm else \
            0.5 * (1 + math.cos(math.pi * (step - warm) / max(1, total - warm)))
        for g in opt.param_groups:
            g["lr"] = LR * f
    return set_lr


def _fit(net: Any, train: NDArray[np.int64], epochs: int, batch: int,
         rng: np.random.Generator, loss_of: Callable[[NDArray[np.int64]], Any], *,
         drop_last: bool = False) -> None:
    """Trains ``net`` with AdamW on the warm-up + cosine schedule: every epoch visits ``train``
    in a new random order, in batches of ``batch`` indices; ``loss_of(indices)`` returns the
    batch loss (it may draw from ``rng`` for augmentation). ``drop_last`` skips a short last
    batch (BatchNorm needs two frames)."""
    import torch

    opt = torch.optim.AdamW(net.parameters(), lr=LR, weight_decay=WEIGHT_DECAY)
    per_epoch = max(1, len(train) // batch) if drop_last else math.ceil(len(train) / batch)
    set_lr = _schedule(opt, per_epoch * epochs)
    step = 0
    net.train()
    for _ in range(epochs):
        order = rng.permutation(train)
        for b in range(per_epoch):
            set_lr(step)
            loss = loss_of(order[b * batch:(b + 1) * batch])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1


def recalibrate_bn(net: Any, batches: Iterable[NDArray[np.uint8]]) -> None:
    """Recomputes every BatchNorm layer's running statistics as the plain average over
    ``batches`` (uint8 frames) with the trained weights, then leaves ``net`` in eval mode.

    Needed because torchvision's MobileNetV3 keeps BatchNorm momentum at 0.01: after a few
    hundred CPU training steps its running statistics are still mostly their initial values,
    and in eval mode the segmenter then predicts background everywhere (IoU 0). The same
    recalibration is applied to every model and input, so the comparison stays fair.
    """
    import torch

    for mod in net.modules():
        if isinstance(mod, torch.nn.modules.batchnorm._BatchNorm):
            mod.reset_running_stats()
            mod.momentum = None  # cumulative average
    net.train()
    with torch.no_grad():
        for b in batches:
            net(to_tensor(b))
    net.eval()


def run_texture(data: dict[str, NDArray[Any]], input_type: str, seed: int,
                scale: StudyScale) -> dict[str, float]:
    """Trains ResNet-18 on ``input_type`` frames with ``seed``; test accuracy and the number of
    classes with an error."""
    import torch
    import torch.nn.functional as F
    import torchvision

    imgs, labels = data[f"img_{input_type}"], data["label"]
    n_classes = int(labels.max()) + 1
    train, test = split(labels, "texture", seed)
    torch.manual_seed(seed)
    net = torchvision.models.resnet18(weights=None, num_classes=n_classes)
    rng = np.random.default_rng([seed, 23])
    h, w = imgs.shape[1:3]
    side = min(scale.texture_crop, h, w)
    centres = contact_centres(data["contact"])
    jitter = side // 8

    def loss_of(idx: NDArray[np.int64]) -> Any:
        crops = np.empty((len(idx), side, side, 3), np.uint8)
        for j, i in enumerate(idx):
            dy, dx = rng.integers(-jitter, jitter + 1, 2)
            c = crop_at(imgs[i], int(centres[i, 0] + dy), int(centres[i, 1] + dx), side)
            if rng.random() < 0.5:
                c = c[:, ::-1]
            if rng.random() < 0.5:
                c = c[::-1]
            crops[j] = c
        return F.cross_entropy(net(to_tensor(crops)), torch.from_numpy(labels[idx]))

    _fit(net, train, scale.texture_epochs, scale.batch, rng, loss_of)
    recalibrate_bn(net, (np.stack([crop_at(imgs[i], int(centres[i, 0]), int(centres[i, 1]),
                                           side) for i in train[k:k + scale.batch]])
                         for k in range(0, len(train), scale.batch)))
    with torch.no_grad():
        crops = np.stack([crop_at(imgs[i], int(centres[i, 0]), int(centres[i, 1]), side)
                          for i in test])
        pred = np.concatenate([net(to_tensor(crops[k:k + 32])).argmax(1).numpy()
                               for k in range(0, len(crops), 32)])
    truth = labels[test]
    wrong = pred != truth
    return {"accuracy": float(1 - wrong.mean()),
            "classes_with_errors": float(len(np.unique(truth[wrong])))}


def downsample(imgs: NDArray[np.uint8], contact: NDArray[np.bool_], factor: int
               ) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Area-downsampled frames and majority-vote contact masks (``factor`` x ``factor`` blocks;
    edges that do not fill a block are cropped)."""
    if factor == 1:
        return imgs, contact
    b, h, w = contact.shape
    hh, ww = h // factor, w // factor
    f = imgs[:, :hh * factor, :ww * factor].reshape(b, hh, factor, ww, factor, 3)
    small = (f.mean(axis=(2, 4)) + 0.5).astype(np.uint8)
    c = contact[:, :hh * factor, :ww * factor].reshape(b, hh, factor, ww, factor)
    return small, c.mean(axis=(2, 4)) >= 0.5


def run_contact(data: dict[str, NDArray[Any]], input_type: str, seed: int,
                scale: StudyScale) -> dict[str, float]:
    """Trains DeepLabV3-MobileNetV3 on ``input_type`` frames with ``seed``; test IoU of the
    contact class and pixel accuracy over the whole test split."""
    import torch
    import torch.nn.functional as F
    from torchvision.models.segmentation import deeplabv3_mobilenet_v3_large

    imgs, masks = downsample(data[f"img_{input_type}"], data["contact"], scale.contact_scale)
    train, test = split(data["label"], "contact", seed)
    torch.manual_seed(seed)
    net = deeplabv3_mobilenet_v3_large(weights=None, weights_backbone=None, num_classes=2,
                                       aux_loss=False)
    rng = np.random.default_rng([seed, 29])
    batch = max(2, scale.batch // 2)  # BatchNorm needs at least two frames per batch

    def loss_of(idx: NDArray[np.int64]) -> Any:
        x, y = imgs[idx], masks[idx]
        if rng.random() < 0.5:
            x, y = x[:, :, ::-1], y[:, :, ::-1]
        if rng.random() < 0.5:
            x, y = x[:, ::-1], y[:, ::-1]
        out = net(to_tensor(x))["out"]
        target = torch.from_numpy(np.ascontiguousarray(y))
        # Cross-entropy plus a soft Dice term: contact is a minority of the pixels.
        prob = out.softmax(1)[:, 1]
        dice = 1 - (2 * (prob * target).sum() + 1) / (prob.sum() + target.sum() + 1)
        return F.cross_entropy(out, target.long()) + dice

    _fit(net, train, scale.contact_epochs, batch, rng, loss_of, drop_last=True)
    recalibrate_bn(net, (imgs[train[k:k + batch]] for k in range(0, len(train) - 1, batch)
                         if len(train[k:k + batch]) > 1))
    inter = union = correct = total = 0
    with torch.no_grad():
        for i in test:
            pred = net(to_tensor(imgs[i:i + 1]))["out"][0].argmax(0).numpy().astype(bool)
            truth = masks[i]
            inter += int((pred & truth).sum())
            union += int((pred | truth).sum())
            correct += int((pred == truth).sum())
            total += truth.size
    return {"iou": inter / union if union else 1.0, "pixel_accuracy": correct / total}


RUNNERS = {"texture": run_texture, "contact": run_contact}


def run_study(data_root: str | Path, out: str | Path, scale: StudyScale, *,
              tasks: Sequence[str] = TASKS, inputs: Sequence[str] = INPUTS,
              threads: int | None = None,
              progress: Callable[[str], None] | None = print) -> list[dict[str, Any]]:
    """Every (task, input, seed) run not yet in ``out/results.jsonl``; returns all records of
    this scale and dataset (finished earlier or now)."""
    import torch

    for t in tasks:
        if t not in TASKS:
            raise ValueError(f"tasks: expected some of {TASKS}; got {t!r}")
    for i in inputs:
        if i not in INPUTS:
            raise ValueError(f"inputs: expected some of {INPUTS}; got {i!r}")
    torch.set_num_threads(threads or os.cpu_count() or 1)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    contexts = {}
    for task in tasks:
        data = load_dataset(data_root, task)
        for inp in inputs:
            contexts[task, inp] = {"scale": scale_dict(scale), "frames": array_hash(
                data[f"img_{inp}"], data["label"], data["contact"])}
        del data
    path = out / "results.jsonl"
    records = [r for r in _read_records(path)
               if contexts.get((r["task"], r["input"])) == r["context"]]
    done = {(r["task"], r["input"], r["seed"]) for r in records}
    todo = [(t, i, s) for t in tasks for s in range(scale.seeds) for i in inputs
            if (t, i, s) not in done]
    t0 = time.perf_counter()
    for n, (task, inp, seed) in enumerate(todo, 1):
        data = _cached(data_root, task)
        start = time.perf_counter()
        metrics = RUNNERS[task](data, inp, seed, scale)
        rec = {"task": task, "input": inp, "seed": seed, "metrics": metrics,
               "seconds": round(time.perf_counter() - start, 2),
               "context": contexts[task, inp]}
        with open(path, "a") as fh:  # one complete line per run: a crash loses at most one run
            fh.write(json.dumps(rec) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
        records.append(rec)
        if progress is not None:
            head = METRICS[task][0]
            eta = (time.perf_counter() - t0) / n * (len(todo) - n)
            progress(f"[{n}/{len(todo)}] {task} {inp} seed {seed}: {head} "
                     f"{metrics[head]:.4f} ({rec['seconds']:.0f} s; about {eta / 60:.0f} min "
                     "left)")
    return records


_CACHE: dict[tuple[str, str], dict[str, NDArray[Any]]] = {}


def _cached(root: str | Path, task: str) -> dict[str, NDArray[Any]]:
    key = (str(Path(root).resolve()), task)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = load_dataset(root, task)
    return _CACHE[key]


def _read_records(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    records = []
    for line in path.read_text().splitlines():
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            continue  # a line cut by a crash: that run is redone
    return records


def summarise(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (task, input): mean and standard deviation of each metric over seeds, and the
    headline metric's paired difference from ``none`` (same seeds) with its standard error."""
    rows = []
    for task in TASKS:
        base = {r["seed"]: r["metrics"] for r in records
                if r["task"] == task and r["input"] == "none"}
        for inp in INPUTS:
            rs = sorted((r for r in records if r["task"] == task and r["input"] == inp),
                        key=lambda r: r["seed"])
            if not rs:
                continue
            row: dict[str, Any] = {"task": task, "input": inp, "seeds": len(rs)}
            for m in METRICS[task]:
                v = np.array([r["metrics"][m] for r in rs], np.float64)
                row[m] = float(v.mean())
                row[f"{m}_std"] = float(v.std(ddof=1)) if len(v) > 1 else float("nan")
            head = METRICS[task][0]
            d = np.array([r["metrics"][head] - base[r["seed"]][head] for r in rs
                          if r["seed"] in base], np.float64)
            row["delta"] = float(d.mean()) if len(d) else float("nan")
            row["delta_se"] = float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 \
                else float("nan")
            rows.append(row)
    return rows


def verdict(row: dict[str, Any]) -> str:
    """Whether ``row``'s paired difference from ``none`` exceeds twice its standard error."""
    d, se = row["delta"], row["delta_se"]
    if row["input"] == "none":
        return "baseline"
    if row["seeds"] < MIN_SEEDS_FOR_VERDICT or not np.isfinite(se):
        return "too few seeds"
    if se == 0 and d == 0:
        return "identical"
    if abs(d) <= 2 * se:
        return "within noise"
    return "better" if d > 0 else "worse"


def markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The summary as two Markdown tables (classification, segmentation)."""
    out = []
    for task, title, cols in (
            ("texture", "Texture classification (ResNet-18)",
             "| input | accuracy % | classes with errors | Δ accuracy vs none (pp) | verdict |"),
            ("contact", "Contact segmentation (DeepLabV3-MobileNetV3)",
             "| input | IoU % | pixel accuracy % | Δ IoU vs none (pp) | verdict |")):
        rs = [r for r in rows if r["task"] == task]
        if not rs:
            continue
        a, b = METRICS[task]
        out += [f"{title}, {rs[0]['seeds']} seeds (mean ± standard deviation)", "", cols,
                "|---|---|---|---|---|"]
        for r in rs:
            second = f"{r[b]:.1f} ± {r[b + '_std']:.1f}" if task == "texture" else \
                f"{100 * r[b]:.2f} ± {100 * r[b + '_std']:.2f}"
            delta = "—" if r["input"] == "none" else \
                f"{100 * r['delta']:+.2f} ± {100 * r['delta_se']:.2f}"
            out.append(f"| {INPUT_NAMES[r['input']]} | {100 * r[a]:.2f} ± "
                       f"{100 * r[a + '_std']:.2f} | {second} | {delta} | {verdict(r)} |")
        out.append("")
    out.append("Δ: paired difference from the marker frames over the same seeds ± its standard "
               "error; 'better'/'worse' only when it exceeds two standard errors.")
    return "\n".join(out)
