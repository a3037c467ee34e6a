"""Frames of the downstream study: rendered contacts, each as every input type (no torch).

A sample is one simulated contact (:func:`tacswitch.sim.scene.render_sample`) seen six ways
(:data:`INPUTS`): the frame with markers, the same frame after each marker-removal method of
:func:`tacswitch.remove_markers` (markers extracted from the frame itself, as a user's pipeline
would; hybrid finds the contact against the scene's no-contact frame), and the true markerless
frame. Two tasks:

- ``texture``: fabric classes (:data:`tacswitch.sim.indenters.TEXTURES`), ``per_class`` samples
  each; label = class index;
- ``contact``: every contact class (shapes and textures, in turn); label = the contact mask.

Shards ``{task}_{k:03d}.npz`` (``img_{input}`` ``B x H x W x 3`` uint8 BGR, ``label`` ``B``,
``contact`` ``B x H x W`` bool) are written atomically; a rerun skips finished shards, so an
interrupted build resumes. ``manifest.json`` records what the folder holds (preset, seed,
counts, the TacDiff model's hash); a folder built with other settings is refused rather than
mixed, except for another TacDiff model: then the shards are rendered again (deterministically,
so only the TacDiff and hybrid images change).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.removal import remove_markers

#: Input types, in table order: raw marker frames, each removal method, the true markerless frame.
INPUTS: tuple[str, ...] = ("none", "ns", "telea", "tacdiff", "hybrid", "truth")
#: How each input type is described in reports.
INPUT_NAMES: dict[str, str] = {
    "none": "markers (none removed)", "ns": "NS (OpenCV)", "telea": "TELEA (tacswitch)",
    "tacdiff": "TacDiff", "hybrid": "hybrid (TacDiff near contact)",
    "truth": "true markerless (ceiling)"}
TASKS: tuple[str, ...] = ("texture", "contact")
#: Samples per shard file.
SHARD = 32


@dataclass(frozen=True)
class StudyScale:
    """Size of one study (data, models, seeds). The default finishes in under an hour on a
    2-core CPU; :data:`QUICK` is for tests.

    Attributes:
        preset: simulator preset of every frame.
        per_class: texture samples per fabric class (half train, half test).
        contact_samples: contact-segmentation samples (85 % train, 15 % test).
        seeds: seeds per (task, input); each seed fixes the split, initialisation and order.
        texture_epochs, contact_epochs: training epochs.
        texture_crop: side (px) of the classifier's input crops at full resolution (random crops
            in training, the centre crop at test: fabric detail is a few pixels wide).
        contact_scale: the segmenter sees frames downsampled by this factor (area).
        batch: training batch size.
        steps: TacDiff sampler steps for the ``tacdiff`` and ``hybrid`` inputs.
        dilate: dilations of each frame's extracted marker mask before inpainting
            (:data:`tacswitch.inpaint.DEFAULT_DILATE`).
    """

    preset: str = "gelsight_mini"
    per_class: int = 30
    contact_samples: int = 160
    seeds: int = 3
    texture_epochs: int = 40
    contact_epochs: int = 8
    texture_crop: int = 96
    contact_scale: int = 2
    batch: int = 16
    steps: int = 1
    dilate: int = 2

    def data_key(self) -> dict[str, Any]:
        """The settings that fix the rendered data (a data folder is built for one of these)."""
        return {"preset": self.preset, "per_class": self.per_class,
                "contact_samples": self.contact_samples, "steps": self.steps,
                "dilate": self.dilate}


#: A scale for tests and smoke runs (seconds, not minutes; numbers are meaningless).
QUICK = StudyScale(per_class=2, contact_samples=8, seeds=2, texture_epochs=1, contact_epochs=1,
                   texture_crop=64, contact_scale=4, batch=4)


def task_labels(task: str) -> tuple[str, ...]:
    """The object classes rendered for ``task``."""
    from tacswitch.sim.indenters import SHAPES, TEXTURES

    if task == "texture":
        return TEXTURES
    if task == "contact":
        return (*SHAPES, *TEXTURES)
    raise ValueError(f"task: expected one of {TASKS}; got {task!r}")


def task_size(task: str, scale: StudyScale) -> int:
    """Number of samples of ``task`` at ``scale``."""
    return scale.per_class * len(task_labels(task)) if task == "texture" else \
        scale.contact_samples


def model_hash(path: str | Path | None = None) -> str:
    """First 16 hex digits of the SHA-256 of the TacDiff ONNX file (default: the shipped one)."""
    from tacswitch.tacdiff.infer import default_model_path

    p = Path(path) if path is not None else default_model_path()
    return hashlib.sha256(p.read_bytes()).hexdigest()[:16]


def render_inputs(task: str, index: int, scale: StudyScale, seed: int = 0,
                  model: str | None = None) -> dict[str, Any]:
    """Sample ``index`` of ``task``: every input image, the class index and the contact mask.

    Deterministic: the scene is seeded by ``SeedSequence([seed, task index, index])``.
    """
    from tacswitch.sim.scene import render_sample

    labels = task_labels(task)
    cls = index % len(labels)
    rng = np.random.default_rng(np.random.SeedSequence([seed, TASKS.index(task), index]))
    s = render_sample(scale.preset, rng, label=labels[cls])
    frame = s.image_markers
    d = scale.dilate
    imgs = {
        "none": frame,
        "ns": remove_markers(frame, method="ns", dilate=d),
        "telea": remove_markers(frame, method="telea", dilate=d),
        "tacdiff": remove_markers(frame, method="tacdiff", dilate=d, steps=scale.steps,
                                     model=model),
        "hybrid": remove_markers(frame, method="hybrid", dilate=d, ref=s.reference,
                                    steps=scale.steps, model=model),
        "truth": s.image,
    }
    return {"images": imgs, "label": cls, "contact": s.contact_mask}


def build_dataset(root: str | Path, scale: StudyScale, *, seed: int = 0,
                  model: str | None = None,
                  progress: Callable[[str], None] | None = print) -> Path:
    """Renders every shard of both tasks into ``root`` (resumable, atomic per shard).

    Raises:
        ValueError: ``root`` holds a dataset built with other settings.
    """
    from tacswitch._io import atomic_open

    out = Path(root)
    out.mkdir(parents=True, exist_ok=True)
    manifest = {"version": 1, "seed": seed, **scale.data_key(), "inputs": list(INPUTS),
                "tacdiff_model": model_hash(model),
                "tasks": {t: {"n": task_size(t, scale), "classes": list(task_labels(t))}
                          for t in TASKS}}
    mpath = out / "manifest.json"
    if mpath.is_file():
        old = json.loads(mpath.read_text())
        changed = sorted(k for k in manifest if old.get(k) != manifest[k])
        if changed == ["tacdiff_model"]:
            for shard in out.glob("*.npz"):
                shard.unlink()
            if progress is not None:
                progress("another TacDiff model: rendering the frames again")
        elif changed:
            raise ValueError(f"data: {str(out)!r} holds a study dataset built with other "
                             f"settings ({', '.join(changed)}); use another folder")
    if not mpath.is_file() or json.loads(mpath.read_text()) != manifest:
        with atomic_open(mpath) as fh:
            json.dump(manifest, fh, indent=1)
    t0 = time.perf_counter()
    for task in TASKS:
        n = task_size(task, scale)
        for k, start in enumerate(range(0, n, SHARD)):
            path = out / f"{task}_{k:03d}.npz"
            if path.is_file():
                continue
            items = [render_inputs(task, i, scale, seed, model)
                     for i in range(start, min(n, start + SHARD))]
            arrays = {f"img_{name}": np.stack([it["images"][name] for it in items])
                      for name in INPUTS}
            arrays["label"] = np.array([it["label"] for it in items], np.int64)
            arrays["contact"] = np.stack([it["contact"] for it in items])
            with atomic_open(path, "wb") as fh:
                np.savez(fh, **arrays)  # type: ignore[arg-type]
            if progress is not None:
                progress(f"{path.name}: {min(n, start + SHARD)}/{n} {task} samples, "
                         f"{time.perf_counter() - t0:.0f} s")
    return out


def load_dataset(root: str | Path, task: str) -> dict[str, NDArray[Any]]:
    """Every shard of ``task`` under ``root``, concatenated: ``img_{input}``, ``label``,
    ``contact``; raises ``ValueError`` if the folder holds no (or an incomplete) dataset."""
    out = Path(root)
    mpath = out / "manifest.json"
    if not mpath.is_file():
        raise ValueError(f"data: no study dataset in {str(out)!r} (build it first)")
    n = json.loads(mpath.read_text())["tasks"][task]["n"]
    parts = [dict(np.load(p)) for p in sorted(out.glob(f"{task}_*.npz"))]
    if not parts or sum(len(p["label"]) for p in parts) != n:
        raise ValueError(f"data: the {task} shards in {str(out)!r} are incomplete; rerun to "
                         "finish them")
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def scale_dict(scale: StudyScale) -> dict[str, Any]:
    """``scale`` as a JSON-able dict (for result records)."""
    return asdict(scale)


def array_hash(*arrays: NDArray[Any]) -> str:
    """First 16 hex digits of the SHA-256 of the arrays' shapes and bytes."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(repr((a.shape, a.dtype.str)).encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]
