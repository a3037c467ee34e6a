"""Synthetic training/evaluation data for the motion regressor (numpy + the simulator, no torch).

A sample is a markerless contact frame ``I_wo``, the markerless no-contact reference of the same
scene, the marker centres at rest and their true motion ``(dx, dy)`` px. Samples come from
:class:`tacswitch.sim.Scene` under the load distribution of :func:`tacswitch.sim.render_sample`
(stuck-zone shear up to 0.9 pitch, partial slip, twist), with two controls the paper's held-out
splits need: the object classes allowed and the fraction of each class's depth range drawn from.

Splits (as in the paper: unseen depth, unseen indenter):

- ``train``: classes other than :data:`HELDOUT_CLASSES`, depth in the lower 80 % of the range;
- ``test_depth``: the same classes, depth in the top 20 % (deeper presses than any in training);
- ``test_indenter``: :data:`HELDOUT_CLASSES` only, any depth;
- ``test_press``: seen classes, any depth, pure presses (no shear, no twist) — a diagnostic: the
  simulator renders the markerless image from the gel's height alone, so the stuck-zone shear and
  twist leave no trace in it and no markerless predictor can recover them; what it can recover is
  the press (dilation) field, measured here.

Shards are ``.npz`` files written atomically, one per block of samples, so generation resumes.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.removal import remove_markers
from tacswitch.tracking import MarkerTracker

#: Object classes never seen in training (one shape, one texture).
HELDOUT_CLASSES = ("star", "knit")
#: Depth fraction (of the class's range) that separates training from the unseen-depth split.
DEPTH_SPLIT = 0.8
SPLITS = ("train", "test_depth", "test_indenter", "test_press")


def split_spec(split: str) -> tuple[tuple[str, ...], tuple[float, float]]:
    """``(classes, depth_fraction_range)`` of a split."""
    from tacswitch.sim.indenters import CLASSES

    seen = tuple(c for c in CLASSES if c not in HELDOUT_CLASSES)
    if split == "train":
        return seen, (0.0, DEPTH_SPLIT)
    if split == "test_depth":
        return tuple(c for c in seen if c != "none"), (DEPTH_SPLIT, 1.0)
    if split == "test_indenter":
        return HELDOUT_CLASSES, (0.0, 1.0)
    if split == "test_press":
        return tuple(c for c in seen if c != "none"), (0.0, 1.0)
    raise ValueError(f"split: must be one of {SPLITS}; got {split!r}")


def render_motion_sample(preset: str, seed: Any, *, classes: tuple[str, ...],
                         depth_frac: tuple[float, float] = (0.0, 1.0),
                         markers: bool = False, shear: bool = True) -> dict[str, Any]:
    """One sample (see the module docstring); deterministic given ``seed``. ``shear=False``:
    a pure press (no shear, no twist, load ratio 0).

    Returns a dict: ``image`` / ``reference`` (markerless, uint8 BGR), ``rest``, ``displacement``
    (``N x 2`` float32 px), ``present`` (``N`` bool), ``depth_mm``, ``label``; with
    ``markers=True`` also ``image_markers`` / ``reference_markers`` (the same frames with markers,
    for the tracking baseline).
    """
    from tacswitch.sim.indenters import depth_range
    from tacswitch.sim.scene import Scene

    rng = np.random.default_rng(seed)
    label = classes[int(rng.integers(len(classes)))]
    scene = Scene(preset, rng, label=label)
    lo, hi = depth_range(label)
    scene.depth = float(lo + (hi - lo) * rng.uniform(*depth_frac))
    # Load as in sim.render_sample.
    mag = scene.pitch * rng.uniform(0.0, 0.9) ** 1.5
    ang = rng.uniform(0, 2 * np.pi)
    shear_px = (float(mag * np.cos(ang)), float(mag * np.sin(ang)))
    load = float(rng.uniform(0.0, 0.95))
    twist = float(rng.uniform(-0.08, 0.08))
    if not shear:
        shear_px, load, twist = (0.0, 0.0), 0.0, 0.0
    ref = scene.render(rng, depth=0.0)
    f = scene.render(rng, shear_px=shear_px, load_ratio=load, twist_rad=twist)
    out: dict[str, Any] = {
        "image": f.image, "reference": ref.image, "rest": scene.rest,
        "displacement": f.displacement.astype(np.float32), "present": scene.present.copy(),
        "depth_mm": scene.depth, "label": label,
    }
    if markers:
        out["image_markers"] = f.image_markers
        out["reference_markers"] = ref.image_markers
    return out


def render_pair_sample(preset: str, seed: Any, *, classes: tuple[str, ...],
                       depth_frac: tuple[float, float] = (0.0, 1.0),
                       no_contact_fraction: float = 0.1,
                       slide_fraction: float = 0.0) -> dict[str, Any]:
    """Two loads of one contact: ``reference`` (markerless, the contact at a first load, or the
    no-contact frame in ``no_contact_fraction`` of the samples) and ``image`` (a second load,
    sliding in ``slide_fraction`` of the samples), with ``displacement`` = the markers' motion
    from the first frame to the second.

    Motion since an earlier frame is what shear and slip control use (the slip rule measures it
    from the grasp start), and unlike the absolute motion it is visible in markerless frames: a
    stuck contact carries its imprint with the gel. Arrays as :func:`render_motion_sample`.
    """
    from tacswitch.sim.indenters import depth_range
    from tacswitch.sim.scene import Scene

    rng = np.random.default_rng(seed)
    label = classes[int(rng.integers(len(classes)))]
    scene = Scene(preset, rng, label=label)
    lo, hi = depth_range(label)
    scene.depth = float(lo + (hi - lo) * rng.uniform(*depth_frac))

    def load() -> dict[str, Any]:
        mag = scene.pitch * rng.uniform(0.0, 0.5) ** 1.5
        ang = rng.uniform(0, 2 * np.pi)
        return {"shear_px": (float(mag * np.cos(ang)), float(mag * np.sin(ang))),
                "load_ratio": float(rng.uniform(0.0, 0.95)),
                "twist_rad": float(rng.uniform(-0.05, 0.05))}

    first = scene.render(rng, depth=0.0) if rng.random() < no_contact_fraction else \
        scene.render(rng, **load())
    second = load()
    # A sliding object moves on while the gel stays saturated: its imprint's motion is then not
    # the markers' (training on it teaches the net to doubt the imprint; off by default).
    if rng.random() < slide_fraction:
        second["load_ratio"] = 1.0
        second["offset"] = tuple(np.add(second["shear_px"], rng.normal(0, 0.15 * scene.pitch, 2)))
    f = scene.render(rng, **second)
    return {"image": f.image, "reference": first.image, "rest": scene.rest,
            "displacement": (f.displacement - first.displacement).astype(np.float32),
            "present": scene.present.copy(), "depth_mm": scene.depth, "label": label}


#: Marker slots of a ``gel_`` sample: the largest grid :data:`tacswitch.sim.scene.GRIDS` draws
#: (10 x 14); smaller grids are padded with NaN motion and ``present=False``.
MAX_MARKERS = 140


#: Gel-pair presets beyond the simulator's own: two real optics at the Mini's size and scale.
MIXED_PRESETS = ("mixed", "mixed_moving")


def _gel_preset(name: str, rng: np.random.Generator) -> Any:
    """``name``, or for ``"mixed"`` the Mini preset or the GelSight calibration at the Mini's
    size and scale (320 x 240, 0.059 mm/px, pitch 40 px), half each: two real optics, each with
    its own gel's measured press law (the Mini's gel barely moves under a press). For
    ``"mixed_moving"`` the same two optics, both with the GelSight gel's press law: a gel's
    press gain is a property of the unit (a real GelSight Mini's gel moves like the GelSight's,
    taxim's does not), so a model trained on it cannot tie the gain to a sensor's look."""
    import dataclasses

    from tacswitch.sim.presets import (
        GELSIGHT_PRESS_DECAY_MM,
        GELSIGHT_PRESS_DILATION,
        get_preset,
    )

    if name not in MIXED_PRESETS:
        return get_preset(name)
    if rng.random() < 0.5:
        mini = get_preset("gelsight_mini")
        if name == "mixed_moving":
            mini = dataclasses.replace(mini, press_dilation=GELSIGHT_PRESS_DILATION,
                                       press_decay_mm=GELSIGHT_PRESS_DECAY_MM)
        return mini
    return dataclasses.replace(get_preset("gelsight"), name="gelsight_320", height=240,
                               width=320, mm_per_px=0.059, pitch=40.0, diameter=11.5,
                               edge_px=1.5)


def render_gel_pair_sample(preset: str, seed: Any, *, classes: tuple[str, ...],
                           depth_frac: tuple[float, float] = (0.0, 1.0),
                           capture: bool = True, max_shear: float = 0.6) -> dict[str, Any]:
    """A pair of frames of one contact with the simulator's full realism and both frames'
    absolute motions (what a reference-consistent model trains on).

    The scene has a random sensor look (``appearance="random"``) and the gel-attached grain and
    dust that move with the gel; ``reference`` is the no-contact frame (30 %), the same contact
    at another depth and load (60 %), or the same load with fresh noise (10 %: zero motion);
    ``image`` is the contact at a second depth and load (15 % sliding: the object moves on while
    the gel stays saturated). Each load's stuck shear is up to ``max_shear`` marker pitches
    (``pitch * U(0, max_shear) ** 1.5``: mostly small). With ``capture`` both frames go through
    one camera
    (:mod:`tacswitch.sim.capture`: blur, noise, white balance, none/MJPEG), the second with its
    own small exposure drift. Marker grids vary (half the samples draw from
    :data:`tacswitch.sim.scene.GRIDS`); arrays are padded to :data:`MAX_MARKERS`.

    Returns:
        ``image`` / ``reference`` (markerless uint8 BGR), ``rest`` (``MAX_MARKERS x 2``),
        ``displacement`` (motion from ``reference`` to ``image``), ``disp_image`` /
        ``disp_reference`` (motion of each frame from rest), ``present``, ``depth_mm``, ``label``.
    """
    import dataclasses

    from tacswitch.sim import capture as cap
    from tacswitch.sim.indenters import depth_range
    from tacswitch.sim.scene import Scene

    rng = np.random.default_rng(seed)
    label = classes[int(rng.integers(len(classes)))]
    p = _gel_preset(preset, rng)
    scene = Scene(p, rng, label=label, appearance="random", vary_grid=bool(rng.random() < 0.5))
    lo, hi = depth_range(label)
    depth = float(lo + (hi - lo) * rng.uniform(*depth_frac))
    scene.depth = depth
    if capture:
        # The capture profile brings the camera's noise; the scene's own stays small.
        scene.noise_sigma = rng.uniform(0.2, 0.8, 3)

    def load() -> dict[str, Any]:
        mag = scene.pitch * rng.uniform(0.0, max_shear) ** 1.5
        ang = rng.uniform(0, 2 * np.pi)
        return {"shear_px": (float(mag * np.cos(ang)), float(mag * np.sin(ang))),
                "load_ratio": float(rng.uniform(0.0, 0.95)),
                "twist_rad": float(rng.uniform(-0.06, 0.06)),
                "depth": depth * float(rng.uniform(0.6, 1.0))}

    second = load()
    u = rng.random()
    if u < 0.3:
        first = scene.render(rng, depth=0.0, markers=False)
    elif u < 0.9:
        first = scene.render(rng, **load(), markers=False)
    else:
        first = scene.render(rng, **second, markers=False)
    if rng.random() < 0.15:
        second["load_ratio"] = 1.0
        second["offset"] = tuple(np.add(second["shear_px"], rng.normal(0, 0.15 * scene.pitch, 2)))
    f = scene.render(rng, **second, markers=False)
    ref_img, img = first.image, f.image
    if capture:
        prof = cap.sample_profile(rng, codec=str(rng.choice(["none", "mjpeg"])))  # type: ignore[arg-type]
        g0, g1, g2 = (float(g * rng.normal(1.0, 0.02)) for g in prof.gain)
        drift = (g0, g1, g2)
        ref_img = cap.apply(ref_img, prof, rng)
        img = cap.apply(img, dataclasses.replace(prof, gain=drift), rng)
    n = len(scene.rest)
    if n > MAX_MARKERS:
        raise ValueError(f"preset: {n} markers exceed MAX_MARKERS={MAX_MARKERS}")

    def pad(a: NDArray[Any], fill: Any) -> NDArray[Any]:
        out = np.full((MAX_MARKERS, *a.shape[1:]), fill, a.dtype)
        out[:n] = a
        return out

    d_ref = first.displacement.astype(np.float32)
    d_img = f.displacement.astype(np.float32)
    return {"image": img, "reference": ref_img, "rest": pad(scene.rest, 0.0),
            "displacement": pad(d_img - d_ref, np.nan), "disp_image": pad(d_img, np.nan),
            "disp_reference": pad(d_ref, np.nan), "present": pad(scene.present, False),
            "depth_mm": depth, "label": label}


def generate_split(out: str | Path, split: str, n: int, *, preset: str = "gelsight_mini",
                   seed: int = 0, shard: int = 250, markers: bool = False,
                   progress: bool = True, options: dict[str, Any] | None = None) -> list[Path]:
    """Writes ``n`` samples of ``split`` as shards ``out/{split}_{k:03d}.npz``; skips finished
    shards (resume). Sample ``i`` uses ``SeedSequence([seed, SPLITS.index(base), i])`` (+100 for
    ``pair_`` splits, +200 for ``gel_`` splits: :func:`render_gel_pair_sample`; ``preset``
    may then be ``"mixed"``; ``options`` are passed on to it, e.g. ``max_shear``)."""
    from tacswitch._io import atomic_open

    pair = split.startswith("pair_")
    gel = split.startswith("gel_")
    base = split.removeprefix("pair_").removeprefix("gel_")
    classes, frac = split_spec(base)
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    paths = []
    t0 = time.perf_counter()
    for k, start in enumerate(range(0, n, shard)):
        path = root / f"{split}_{k:03d}.npz"
        paths.append(path)
        if path.is_file():
            continue
        sid = SPLITS.index(base) + (100 if pair else 200 if gel else 0)
        items = [render_gel_pair_sample(preset, np.random.SeedSequence([seed, sid, i]),
                                        classes=classes, depth_frac=frac,
                                        **(options or {})) if gel else
                 render_pair_sample(preset, np.random.SeedSequence([seed, sid, i]),
                                    classes=classes, depth_frac=frac) if pair else
                 render_motion_sample(preset, np.random.SeedSequence([seed, sid, i]),
                                      classes=classes, depth_frac=frac, markers=markers,
                                      shear=split != "test_press")
                 for i in range(start, min(n, start + shard))]
        arrays = {key: np.stack([it[key] for it in items])
                  for key in items[0] if key not in ("label",)}
        arrays["label"] = np.array([it["label"] for it in items])
        with atomic_open(path, "wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]
        if progress:
            print(f"{path.name}: {min(n, start + shard)}/{n} samples, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    return paths


def load_split(root: str | Path, split: str) -> dict[str, NDArray[Any]]:
    """Concatenates the shards of ``split`` in ``root`` (arrays keyed as in the shards)."""
    paths = sorted(Path(root).glob(f"{split}_*.npz"))
    if not paths:
        raise ValueError(f"root: no {split}_*.npz shards in {str(root)!r}")
    parts = [dict(np.load(p)) for p in paths]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def preset_grid(preset: str) -> NDArray[np.float32]:
    """Ideal rest grid of a simulator preset, ``N x 2`` (x, y) px, row-major from the top left."""
    from tacswitch.sim.presets import get_preset

    p = get_preset(preset)
    xs = (p.width - 1) / 2 + (np.arange(p.cols) - (p.cols - 1) / 2) * p.pitch
    ys = (p.height - 1) / 2 + (np.arange(p.rows) - (p.rows - 1) / 2) * p.pitch
    gx, gy = np.meshgrid(xs, ys)
    return np.stack([gx.ravel(), gy.ravel()], 1).astype(np.float32)


def pairs_from_marker_frames(frames: str | Path, reference: str | Path, *, radius: int = 3,
                             progress: bool = True) -> dict[str, NDArray[Any]]:
    """Training pairs from a user's own marker sensor (no simulator, no ground truth needed).

    The reference image's markers are the rest centres; every frame is tracked with
    :class:`tacswitch.MarkerTracker` (frames in name order, so a recorded press is followed
    through), lost markers get NaN motion (left out of the loss), and the markerless inputs are
    the frames with their markers removed by TELEA (``radius`` px). Arrays as :func:`load_split`.
    """
    from tacswitch._io import read_image
    from tacswitch.cli.sources import collect_images

    ref = read_image(reference)
    tracker = MarkerTracker(ref)
    rest = tracker.reference.astype(np.float32)
    ref_clean = remove_markers(ref, radius=radius)
    images, motions = [], []
    paths = collect_images([str(frames)])
    for k, path in enumerate(paths):
        img = read_image(path)
        if img.shape != ref.shape:
            raise ValueError(f"frames: {path} has shape {img.shape}, the reference {ref.shape}")
        motion, valid = tracker.update(img)
        motion = np.where(valid[:, None], motion, np.nan).astype(np.float32)
        images.append(remove_markers(img, radius=radius))
        motions.append(motion)
        if progress and (k + 1) % 100 == 0:
            print(f"{k + 1}/{len(paths)} frames tracked and inpainted", flush=True)
    if not images:
        raise ValueError(f"frames: no images in {str(frames)!r}")
    n = len(images)
    return {"image": np.stack(images), "reference": np.repeat(ref_clean[None], n, 0),
            "rest": np.repeat(rest[None], n, 0), "displacement": np.stack(motions),
            "present": np.ones((n, len(rest)), bool)}
