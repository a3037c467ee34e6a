"""Training pairs from real markerless frames: realistic markers painted on, then captured.

A sensor recorded before its markers were painted (or any real markerless gel) gives real
texture, lighting and noise that the simulator only approximates. Each pair paints a random
marker grid in a random real look (:func:`tacswitch.sim.markers.sample_style`: pasted black or
painted grey dots, soft rims, halo, mottling) on one real frame and captures it as a camera and
recorder would (:func:`tacswitch.sim.capture.sample_profile`: extra blur, noise, exposure and
white-balance drift, lossless / MJPEG / H.264). The target is the real frame through the same
blur and colour drift, without noise or codec; the mask is what ``remove_markers`` would fill
on the captured frame (:func:`~tacswitch.tacdiff.data.removal_markers`), supervised on all its
pixels: their truth is real.

Shards have the format of :mod:`tacswitch.tacdiff.data` (``cond``, ``target``, ``mask``,
``loss_mask``, ``contact``, ``footprint``), so ``tacswitch train tacdiff --data`` takes them
beside simulated ones. Images are uint8 BGR, points ``(x, y)`` px.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Relative jitter of the marker pitch and dot diameter between pairs (uniform, +-).
PITCH_JITTER = 0.15
#: Real frames already carry their camera's blur and noise: the sampled capture's blur and
#: noise are scaled by this before they are added on top.
REAL_OPTICS_SCALE = 0.5
#: Share of pairs painted crisp and captured losslessly (crisp markers must stay right).
CRISP_SHARE = 0.15

_FRAMES: list[NDArray[np.uint8]] = []
_CONTACTS: list[NDArray[np.bool_] | None] = []


def check_frames(frames: Sequence[NDArray[np.uint8]],
                 contacts: Sequence[NDArray[np.bool_] | None] | None = None
                 ) -> tuple[list[NDArray[np.uint8]], list[NDArray[np.bool_] | None]]:
    """``frames`` (``H x W x 3`` uint8 BGR, one size) and ``contacts`` (``H x W`` bool or None
    each; default all None) as lists, or ``ValueError``/``TypeError`` naming the argument."""
    out = list(frames)
    if not out:
        raise ValueError("frames: need at least one markerless frame")
    for i, f in enumerate(out):
        if not isinstance(f, np.ndarray) or f.dtype != np.uint8:
            raise TypeError(f"frames[{i}]: expected a uint8 numpy array")
        if f.ndim != 3 or f.shape[2] != 3:
            raise ValueError(f"frames[{i}]: expected H x W x 3 BGR; got shape {f.shape}")
        if f.shape != out[0].shape:
            raise ValueError(f"frames[{i}]: shape {f.shape} differs from frames[0]'s "
                             f"{out[0].shape}")
    cts = [None] * len(out) if contacts is None else list(contacts)
    if len(cts) != len(out):
        raise ValueError(f"contacts: expected {len(out)} (one per frame); got {len(cts)}")
    for i, c in enumerate(cts):
        if c is not None and (not isinstance(c, np.ndarray) or c.shape != out[0].shape[:2]):
            raise ValueError(f"contacts[{i}]: expected an H x W mask like the frames")
    return out, [None if c is None else c.astype(bool) for c in cts]


def source_key(frames: Sequence[NDArray[np.uint8]],
               contacts: Sequence[NDArray[np.bool_] | None] | None, **spec: Any) -> str:
    """An 8-hex-digit digest of the frames, contact masks and ``spec`` (pitch, diameter,
    seed, ...): names painted shards after what they are drawn from."""
    import hashlib

    h = hashlib.sha1(repr(sorted(spec.items())).encode())
    for i, f in enumerate(frames):
        h.update(np.ascontiguousarray(f).tobytes())
        c = None if contacts is None else contacts[i]
        h.update(b"-" if c is None else np.packbits(np.asarray(c, bool)).tobytes())
    return h.hexdigest()[:8]


def covering_grid(height: int, width: int, pitch: float, diameter: float,
                  rng: np.random.Generator) -> NDArray[np.float32]:
    """Marker centres ``(x, y)`` covering a ``height x width`` frame at ``pitch`` px: a square
    grid at a random sub-pitch phase with 0.5 px placement jitter, dots cut by a border kept
    (centres up to one radius outside the frame), so border slivers occur as on real gels."""
    from tacswitch.sim.markers import marker_grid

    rows, cols = int(np.ceil(height / pitch)) + 2, int(np.ceil(width / pitch)) + 2
    pts = marker_grid(height, width, rows, cols, pitch, jitter=0.5, seed=rng).astype(np.float64)
    pts += rng.uniform(-pitch / 2, pitch / 2, 2)
    r = diameter / 2
    keep = ((pts[:, 0] > -r) & (pts[:, 0] < width - 1 + r)
            & (pts[:, 1] > -r) & (pts[:, 1] < height - 1 + r))
    return pts[keep].astype(np.float32)


def painted_pair(clean: NDArray[np.uint8], *, pitch: float, diameter: float, seed: Any,
                 contact: NDArray[np.bool_] | None = None) -> dict[str, NDArray[Any]]:
    """One training pair from one real markerless frame (see the module docstring).

    Args:
        clean: ``H x W x 3`` uint8 BGR real markerless frame.
        pitch: nominal marker spacing, px (jittered by :data:`PITCH_JITTER`).
        diameter: nominal dot diameter, px (jittered likewise).
        seed: anything ``numpy.random.default_rng`` takes; the pair is deterministic given it.
        contact: ``H x W`` bool contact region, if known (training crops favour it).

    Returns:
        ``cond``, ``target`` (``H x W x 3`` uint8), ``mask``, ``loss_mask``, ``contact``,
        ``footprint`` (``H x W`` bool).
    """
    from tacswitch.sim import capture
    from tacswitch.sim.markers import MarkerStyle, paint_markers, sample_style
    from tacswitch.tacdiff.data import removal_markers

    if pitch <= 0 or diameter <= 0 or not diameter < pitch:
        raise ValueError(f"pitch, diameter: need 0 < diameter < pitch; got {pitch}, {diameter}")
    rng = np.random.default_rng(seed)
    h, w = clean.shape[:2]
    p = pitch * rng.uniform(1 - PITCH_JITTER, 1 + PITCH_JITTER)
    d = min(diameter * rng.uniform(1 - PITCH_JITTER, 1 + PITCH_JITTER), 0.8 * p)
    crisp = rng.random() < CRISP_SHARE
    style = (MarkerStyle(kind="pasted", diameter=d, darkness=0.95, edge_px=1.0, halo=0.0,
                         texture=0.0, level_jitter=0.0) if crisp else sample_style(rng, diameter=d))
    centres = covering_grid(h, w, p, style.diameter, rng)
    img, footprint = paint_markers(clean, centres, style, rng=int(rng.integers(2**31)))
    if crisp:
        profile = capture.CRISP
    else:
        drawn = capture.sample_profile(rng)
        profile = replace(drawn, blur_sigma=drawn.blur_sigma * REAL_OPTICS_SCALE,
                          read_noise=drawn.read_noise * REAL_OPTICS_SCALE,
                          shot_noise=drawn.shot_noise * REAL_OPTICS_SCALE)
    cond = capture.apply(img, profile, rng)
    target = capture.apply(clean, replace(profile, read_noise=0.0, shot_noise=0.0,
                                          codec="none"), rng)
    mask = removal_markers(cond).mask
    return {"cond": cond, "target": target, "mask": mask, "loss_mask": mask.copy(),
            "contact": np.zeros((h, w), bool) if contact is None else contact.copy(),
            "footprint": footprint}


def _init(frames: list[NDArray[np.uint8]], contacts: list[NDArray[np.bool_] | None]) -> None:
    _FRAMES[:], _CONTACTS[:] = frames, contacts


def _shard(path: Path, seeds: list[Any], pitch: float, diameter: float,
           prior: str | None, prior_radius: float) -> Path:
    from tacswitch.tacdiff.data import write_shard

    items = []
    for s in seeds:
        k = int(np.random.default_rng(s).integers(len(_FRAMES)))
        items.append(painted_pair(_FRAMES[k], pitch=pitch, diameter=diameter, seed=s,
                                  contact=_CONTACTS[k]))
    return write_shard(path, items, prior, prior_radius)


def render_painted_pairs(out: str | Path, frames: Sequence[NDArray[np.uint8]], n: int, *,
                         pitch: float, diameter: float,
                         contacts: Sequence[NDArray[np.bool_] | None] | None = None,
                         seed: int = 0, name: str = "painted", shard: int = 32,
                         workers: int = 1, prior: str | None = None,
                         prior_radius: float | None = None,
                         progress: bool = True) -> list[Path]:
    """Renders ``n`` painted pairs from real markerless ``frames`` into
    ``out/pairs_{name}_{k:03d}.npz`` (resumable: finished shards are skipped; writes are
    atomic). Pair ``i`` is seeded by ``SeedSequence([seed, i])``, which also picks its frame,
    so a rerun (any ``workers``) renders the same pairs.

    Args:
        frames: real markerless ``H x W x 3`` uint8 BGR frames, all one size.
        n: number of pairs.
        pitch, diameter: the sensor's nominal marker spacing and dot diameter, px.
        contacts: per frame an ``H x W`` bool contact region or None.
        workers: processes rendering shards in parallel.
        prior, prior_radius: also cache the classical fills of this prior
            (:func:`~tacswitch.tacdiff.data.ensure_fills`), so training skips computing them.
    """
    from tacswitch.tacdiff.data import render_options, run_shard_jobs

    fr, cts = check_frames(frames, contacts)
    for arg, v in (("n", n), ("shard", shard)):
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{arg}: must be an integer >= 1; got {v!r}")
    if not (np.isfinite(pitch) and np.isfinite(diameter) and 0 < diameter < pitch):
        raise ValueError(f"pitch, diameter: need 0 < diameter < pitch; got {pitch}, {diameter}")
    if not name or not all(c.isalnum() or c in "_-" for c in name):
        raise ValueError(f"name: letters, digits, '_' and '-' only; got {name!r}")
    radius = render_options(workers, prior, prior_radius)
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    paths = [root / f"pairs_{name}_{k:03d}.npz" for k in range(-(-n // shard))]
    jobs = [(path, [np.random.SeedSequence([seed, i]) for i in range(k * shard,
                                                                      min(n, (k + 1) * shard))],
             pitch, diameter, prior, radius)
            for k, path in enumerate(paths) if not path.is_file()]
    run_shard_jobs(_shard, jobs, workers,
                   (lambda job: f"{len(job[1])} pairs") if progress else None,
                   initializer=_init, initargs=(fr, cts))
    return paths
