"""Training data of the TacDiff inpainter: paired frames and random crops (numpy; no torch).

Two sources, one format: a shard holds ``cond`` (``B x H x W x 3`` uint8 BGR, the frame the
network sees, markers included), ``target`` (the same frame's true pixels), ``mask`` (``B x H x W``
bool: pixels to fill at inference, what remove_markers would mask) and ``loss_mask``
(pixels whose ``target`` is real and may carry a loss).

- Simulated pairs (:func:`render_pairs`, :func:`render_pair`): ``cond`` = I_w through a random
  camera and recorder, ``target`` = I_wo through the same optics, ``loss_mask`` = mask.
  Presets are mixed (GelSight 640x480, GelSight Mini, DIGIT, a dense grid; grids varied) so the
  model meets 8-25 px dots of different darkness on both Taxim-calibrated and Phong optics.
- A user's sensor with markers only (:func:`marker_offset_pairs`, the paper's marker-offset
  strategy): holes placed about half a pitch away from the markers, on real gel. By default
  each real marker's measured appearance (its darkening, soft edge and codec ring included) is
  transplanted there (:mod:`~tacswitch.tacdiff.transplant`): ``cond`` = the frame with its own
  markers removed by TELEA and the moved markers painted in, ``target`` = the frame itself,
  ``mask`` = the moved markers' removal mask, ``loss_mask`` = its pixels off every original
  marker's footprint (real gel). ``transplant=False`` gives the paper's variant: clean
  shifted holes cut into the TELEA frame. Either way the loss is computed on real pixels
  only, never on TELEA's fill.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._io import atomic_open
from tacswitch.inpaint import inpaint_telea
from tacswitch.markers import AUTO, Markers, dilate_mask, extract_markers
from tacswitch.sim import capture
from tacswitch.sim.markers import paint_markers, sample_style
from tacswitch.sim.scene import Scene, render_sample
from tacswitch.tacdiff.prior import (
    DEFAULT_PRIOR,
    DEFAULT_PRIOR_RADIUS,
    PRIOR_RADIUS,
    check_prior,
    check_radius,
    combine,
    fills,
    has_spread,
)
from tacswitch.tacdiff.prior import to_net as prior_to_net
from tacswitch.tacdiff.transplant import DEFAULT_RING, default_offset, measure_appearance, shift
from tacswitch.tacdiff.transplant import transplant as move_markers
from tacswitch.tracking import estimate_pitch

#: Default mix of simulator presets (name, share of samples).
PRESET_MIX: tuple[tuple[str, float], ...] = (
    ("gelsight", 0.3), ("gelsight_mini", 0.4), ("digit", 0.15), ("dense", 0.15))
#: Dilations of the *true* marker mask of the 0.2 simulated pairs (it already holds the soft
#: edges; the paper dilates once with a 3x3 ellipse); realistic pairs use :func:`removal_markers`.
MASK_DILATE = 1
#: Share of realistic pairs captured losslessly and sharp (crisp markers must stay right).
CRISP_SHARE = 0.15
#: Share of realistic pairs whose markers are repainted in a random real look (pasted black or
#: painted grey, :func:`tacswitch.sim.markers.sample_style`) instead of the scene's own dots.
REPAINT_SHARE = 0.5


def render_pair(preset: str, seed: Any, *, realism: bool = True) -> dict[str, Any]:
    """One simulated contact as a training pair (see the module docstring).

    With ``realism`` (the default since 0.3) half of the pairs get their markers repainted in a
    random real look (:data:`REPAINT_SHARE`), and the frame WITH markers goes through a random
    camera and recorder (:func:`tacswitch.sim.capture.sample_profile`: blur, noise,
    exposure/white-balance drift, MJPEG or H.264; :data:`CRISP_SHARE` of the pairs lossless and
    sharp), the target is the markerless frame through the same optics and colour drift but
    without noise or codec (what the gel looks like through that camera), gel appearance is
    randomised half of the time, and the mask is the one inference will use
    (:func:`removal_markers` on the captured frame), so the soft edges and codec rings it
    covers are supervised against the clean target. Without ``realism``: the 0.2 data (the
    true markers dilated once, 15 % JPEG on the markers only).
    """
    rng = np.random.default_rng(seed)
    if not realism:
        s = render_sample(preset, rng, vary_grid=bool(rng.random() < 0.5),
                          jpeg_quality=int(rng.integers(80, 96)) if rng.random() < 0.15
                          else None)
        mask = dilate_mask(s.marker_mask, MASK_DILATE)
        return {"cond": s.image_markers, "target": s.image, "mask": mask, "loss_mask": mask,
                "contact": s.contact_mask}
    from dataclasses import replace

    scene, s = _render_contact(preset, rng)
    image_markers, footprint = s.image_markers, s.marker_mask
    if rng.random() < REPAINT_SHARE:
        # Pasted black or painted grey dots (tacswitch.sim.markers' looks fitted to real
        # frames) at the same moved positions, on the same noisy markerless frame.
        present = scene.present
        image_markers, footprint = paint_markers(
            s.image, scene.rest[present], sample_style(rng, diameter=float(
                np.median(scene.diameters[present]))),
            displacement=s.displacement[present], diameters=scene.diameters[present],
            rng=int(rng.integers(2**31)))
    crisp = rng.random() < CRISP_SHARE
    profile = capture.CRISP if crisp else capture.sample_profile(rng)
    cond = capture.apply(image_markers, profile, rng)
    target = capture.apply(s.image, replace(profile, read_noise=0.0, shot_noise=0.0,
                                            codec="none"), rng)
    mask = removal_markers(cond).mask
    return {"cond": cond, "target": target, "mask": mask, "loss_mask": mask.copy(),
            "contact": s.contact_mask, "footprint": footprint}


def _render_contact(preset: str, rng: np.random.Generator) -> Any:
    """``(scene, frame)``: one contact (:class:`tacswitch.sim.scene.Frame`); half the time a
    varied marker grid and randomised gel appearance, the load drawn as
    :func:`~tacswitch.sim.scene.render_sample` draws it; no reference frame is rendered
    (training pairs do not use it, and it would double the rendering time)."""
    scene = Scene(preset, rng, vary_grid=bool(rng.random() < 0.5),
                  appearance="random" if rng.random() < 0.5 else "preset")
    mag = scene.pitch * rng.uniform(0.0, 0.9) ** 1.5
    ang = rng.uniform(0, 2 * np.pi)
    frame = scene.render(rng, shear_px=(float(mag * np.cos(ang)), float(mag * np.sin(ang))),
                         load_ratio=float(rng.uniform(0.0, 0.95)),
                         twist_rad=float(rng.uniform(-0.08, 0.08)))
    return scene, frame


def remask(root: str | Path, progress: bool = True) -> int:
    """Recomputes ``mask`` and ``loss_mask`` of realistic shards under ``root`` (those with a
    ``footprint``) with the current :func:`removal_markers`, e.g. after the extraction changed;
    rewrites only shards whose mask changes. Returns the number of shards rewritten."""
    done = 0
    for path in sorted(Path(root).glob("pairs_*.npz")):
        arrays = dict(np.load(path))
        if "footprint" not in arrays:
            continue
        mask = np.stack([removal_markers(c).mask for c in arrays["cond"]])
        if np.array_equal(mask, arrays["mask"]):
            continue
        arrays["mask"], arrays["loss_mask"] = mask, mask.copy()
        for key in ("telea", "smooth", "fills_prior", "fills_radius"):  # fills of the old mask
            arrays.pop(key, None)
        with atomic_open(path, "wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]
        done += 1
        if progress:
            print(f"{path.name}: new masks", flush=True)
    return done


def render_pairs(out: str | Path, n: int, *, seed: int = 0,
                 mix: Sequence[tuple[str, float]] = PRESET_MIX, shard: int = 64,
                 progress: bool = True, realism: bool = True, workers: int = 1,
                 prior: str | None = None, prior_radius: float | None = None) -> list[Path]:
    """Renders ``n`` simulated pairs into ``out/pairs_{preset}_{k:03d}.npz`` (resumable: finished
    shards are skipped; writes are atomic). Sample ``i`` of a preset is seeded by
    ``SeedSequence([seed, preset_index, i])``, so a rerun (any ``workers``) renders the same
    pairs. ``workers`` processes render shards in parallel; with ``prior`` each shard also
    caches that prior's classical fills at TELEA ``prior_radius`` px (:func:`ensure_fills`)."""
    radius = render_options(workers, prior, prior_radius)
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    total = sum(w for _, w in mix)
    paths: list[Path] = []
    jobs: list[tuple[Any, ...]] = []
    for pi, (preset, share) in enumerate(mix):
        count = round(n * share / total)
        for k, start in enumerate(range(0, count, shard)):
            path = root / f"pairs_{preset}_{k:03d}.npz"
            paths.append(path)
            if not path.is_file():
                jobs.append((path, preset, [seed, pi], start, min(count, start + shard), count,
                             realism, prior, radius))
    run_shard_jobs(_sim_shard, jobs, workers,
                   (lambda job: f"{job[4]}/{job[5]} pairs") if progress else None)
    return paths


def _sim_shard(path: Path, preset: str, key: list[int], start: int, stop: int, count: int,
               realism: bool, prior: str | None, radius: float) -> Path:
    """Renders samples ``start .. stop`` of one preset into the shard ``path`` (atomically)."""
    items = [render_pair(preset, np.random.SeedSequence([*key, i]), realism=realism)
             for i in range(start, stop)]
    return write_shard(path, items, prior, radius)


def render_options(workers: int, prior: str | None, prior_radius: float | None) -> float:
    """Checks the options shared by the pair renderers (``workers`` >= 1, ``prior`` known) and
    returns the TELEA radius (px) of the fills to cache (default: the library's)."""
    if not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers: must be an integer >= 1; got {workers!r}")
    radius = check_radius(DEFAULT_PRIOR_RADIUS if prior_radius is None else prior_radius)
    if prior is not None:
        check_prior(prior)
    return radius


def write_shard(path: Path, items: Sequence[dict[str, NDArray[Any]]], prior: str | None,
                radius: float) -> Path:
    """Stacks ``items`` (one pair each) into a shard, caches ``prior``'s classical fills at
    TELEA ``radius`` px when ``prior`` is given (:func:`ensure_fills`), and writes it to ``path``
    atomically."""
    arrays = {k: np.stack([it[k] for it in items]) for k in items[0]}
    if prior is not None:
        ensure_fills(arrays, prior, radius)
    with atomic_open(path, "wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]
    return path


def run_shard_jobs(fn: Callable[..., Path], jobs: Sequence[tuple[Any, ...]], workers: int,
                   describe: Callable[[tuple[Any, ...]], str] | None, *,
                   initializer: Callable[..., None] | None = None,
                   initargs: tuple[Any, ...] = ()) -> None:
    """Runs ``fn(*job)`` (which writes the shard ``job[0]``) for every job: in this process, or
    in ``workers`` spawned processes (each first running ``initializer(*initargs)``); with
    ``describe`` a progress line per finished shard. A failure stops the jobs not yet started."""
    t0 = time.perf_counter()

    def report(job: tuple[Any, ...]) -> None:
        if describe is not None:
            print(f"{job[0].name}: {describe(job)}, {time.perf_counter() - t0:.0f} s",
                  flush=True)

    if workers == 1 or len(jobs) <= 1:
        if initializer is not None:
            initializer(*initargs)
        for job in jobs:
            fn(*job)
            report(job)
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=mp.get_context("spawn"),
                             initializer=initializer, initargs=initargs) as pool:
        futures = [pool.submit(fn, *job) for job in jobs]
        try:
            for job, f in zip(jobs, futures, strict=True):
                f.result()
                report(job)
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # do not render the rest first
            raise


def load_pairs(root: str | Path) -> list[dict[str, NDArray[Any]]]:
    """Every shard under ``root`` (``pairs_*.npz``), one dict of arrays per shard (shards of
    different presets have different frame sizes, so they are not concatenated)."""
    paths = sorted(Path(root).glob("pairs_*.npz"))
    if not paths:
        raise ValueError(f"data: no pairs_*.npz shards in {str(root)!r}")
    return [dict(np.load(p)) for p in paths]


def removal_markers(frame: NDArray[np.uint8], **extract_opts: Any) -> Markers:
    """The markers :func:`tacswitch.remove_markers` would find on ``frame``; their ``mask`` is
    what it fills (grown adaptively per marker as its default does, ``dilate="auto"``,
    border-cut markers included). ``extract_opts`` override the defaults."""
    extract_opts.setdefault("exclude_border", False)
    extract_opts.setdefault("dilate", AUTO)
    return extract_markers(frame, **extract_opts)


def marker_offset_pairs(frames: Sequence[NDArray[np.uint8]], *,
                        offset: tuple[int, int] | Sequence[tuple[int, int]] | None = None,
                        radius: int = 3, transplant: bool = True,
                        ring: int = DEFAULT_RING,
                        recompress: Callable[[NDArray[np.uint8]], NDArray[np.uint8]] | None
                        = None,
                        pseudo_fill: Callable[[NDArray[np.uint8], NDArray[np.bool_]],
                                              NDArray[np.uint8]] | None = None,
                        mask_originals: bool = False, per_frame: int | None = None,
                        **extract_opts: Any) -> dict[str, NDArray[Any]]:
    """Training pairs from a sensor with markers only (the paper's marker-offset strategy).

    Args:
        frames: ``H x W x 3`` uint8 BGR frames with markers, all the same size.
        offset: mask shift ``(dx, dy)`` px, or a list of shifts (one pair per frame and shift,
            see ``per_frame``); default: half the marker pitch estimated from the
            first frame, on both axes (the paper: (+36, +36) px on its 83 px-pitch GelSight),
            rounded to a multiple of 8 px when ``transplant`` (codec block phase, see
            :mod:`~tacswitch.tacdiff.transplant`).
        radius: TELEA radius of the pseudo-markerless frames.
        transplant: move each frame's real markers (their measured darkening, ring and codec
            artefacts included) to the shifted holes, so the network sees what it meets at
            inference (default); False: the paper's clean shifted holes in the TELEA frame.
        ring: px beyond the removal mask over which a marker's darkening is measured
            (``transplant`` only).
        mask_originals: also mark every original marker's removal mask as a hole
            (``transplant`` only; the loss stays on the moved markers' real pixels), so the
            network fills each moved marker among neighbours that are holes too, as at
            inference, not among pseudo-filled gel; the moved mask alone is returned as
            ``moved``.
        pseudo_fill: the pseudo-markerless fill the transplants are measured against and
            carried on (``transplant`` only; default: TELEA of ``radius``), e.g. the start
            model's own fill (``tacswitch finetune --pseudo model``). Made once per frame,
            whatever the number of shifts.
        recompress: applied to each transplanted input frame (``transplant`` only), so the gel
            around a moved marker is quantised with the marker as on the source recording
            (:mod:`~tacswitch.tacdiff.recompress`); the target stays the frame itself.
        per_frame: with a list of ``k`` shifts, how many each frame gets (None: all): frame
            ``i`` takes shifts ``i, i + 1, ...`` (mod ``k``), so a long recording still sees
            every shift while its pairs stay within memory (a frame's shifts keep the list's
            order).
        **extract_opts: passed to :func:`tacswitch.extract_markers` (see :func:`removal_markers`).

    Returns:
        arrays ``cond``, ``target``, ``mask``, ``loss_mask`` (``B x H x W [x 3]``, frame by frame,
        its shifts in order) as in the module docstring; with ``transplant``, ``target`` is the
        frame itself (its pixels under the moved markers are real gel) and ``mask`` holds the
        moved markers only.
    """
    if len(frames) == 0:
        raise ValueError("frames: need at least one frame")
    shifts = _offsets(offset)
    if per_frame is not None and (isinstance(per_frame, bool) or not isinstance(
            per_frame, (int, np.integer)) or per_frame < 1):
        raise ValueError(f"per_frame: expected an int >= 1 (shifts per frame); got {per_frame!r}")
    shape = frames[0].shape
    conds, targets, masks, losses, moveds = [], [], [], [], []
    for i, f in enumerate(frames):
        if f.shape != shape or f.dtype != np.uint8 or f.ndim != 3 or f.shape[2] != 3:
            raise ValueError(f"frames[{i}]: expected {shape} uint8 BGR like frames[0]; got "
                             f"{f.shape} {f.dtype}")
        found = removal_markers(f, **extract_opts)
        mask = found.mask
        if not shifts:
            pitch = estimate_pitch(found.centres)
            if pitch is None:
                raise ValueError("frames: too few markers found to estimate the pitch; pass "
                                 "offset=(dx, dy)")
            half = round(pitch / 2)
            shifts = [default_offset(pitch) if transplant else (half, half)]
        k = len(shifts)
        mine = [shifts[j] for j in sorted({(i + m) % k for m in range(min(k, per_frame or k))})]
        if transplant:
            app = measure_appearance(f, mask, ring=ring, radius=radius, pseudo_fill=pseudo_fill)
            for sh in mine:
                cond, moved, real, _ = move_markers(f, mask, sh, appearance=app)
                conds.append(cond if recompress is None else recompress(cond))
                targets.append(f)
                if mask_originals:
                    moveds.append(moved)
                    moved = moved | mask
                masks.append(moved)
                losses.append(real)
            continue
        pseudo = inpaint_telea(f, mask, radius)
        for sh in mine:
            moved = _shift(mask, sh)
            conds.append(pseudo)
            targets.append(pseudo)
            masks.append(moved)
            # Real pixels only: the shifted hole must not land on an original (TELEA-filled)
            # marker.
            losses.append(moved & ~mask)
    out = {"cond": np.stack(conds), "target": np.stack(targets), "mask": np.stack(masks),
           "loss_mask": np.stack(losses)}
    if moveds:
        out["moved"] = np.stack(moveds)
    return out


def _offsets(offset: Any) -> list[tuple[int, int]]:
    """``offset`` of :func:`marker_offset_pairs` as a list of ``(dx, dy)`` int shifts (empty:
    None, estimate one); ``ValueError`` naming it unless it is one or more pairs of ints."""
    if offset is None:
        return []
    try:
        raw = np.asarray(offset)
    except (TypeError, ValueError):  # ragged lists
        raw = np.empty(0, object)
    a = raw.astype(np.float64) if raw.dtype.kind in "iuf" else np.empty(0)
    if a.ndim == 1:
        a = a[None]
    if (a.ndim != 2 or a.shape[1] != 2 or a.shape[0] == 0 or not np.isfinite(a).all()
            or (a != np.round(a)).any()):
        raise ValueError(f"offset: expected (dx, dy) whole px or a list of them; got {offset!r}")
    if not np.abs(a).max(axis=1).all():
        raise ValueError(f"offset: (0, 0) moves no marker; got {offset!r}")
    return [(int(x), int(y)) for x, y in a]


def _shift(mask: NDArray[np.bool_], offset: tuple[int, int]) -> NDArray[np.bool_]:
    """``mask`` moved by ``(dx, dy)`` px; pixels shifted out of the frame are dropped."""
    return shift(mask, offset, False)


class CropSampler:
    """Random ``size x size`` training crops from shards (numpy only, deterministic by seed).

    Crops are centred (with jitter) on a loss pixel in contact with probability ``contact_share``
    (where a shard has a ``contact`` mask and the sample has such a pixel: that is where TELEA
    is weakest and the network has something to learn), on any loss pixel with probability
    ``hole_share`` (so crops of sparse grids are not mostly empty), and uniformly otherwise.
    Augmentation: flips, 90-degree turns (square crops), and a per-crop colour gain/offset applied
    identically to ``cond``, ``target`` and the classical fills (both are linear in the image) so
    the model does not learn one sensor's lighting. ``prior`` names the classical fill the
    residual is taken over (:mod:`~tacswitch.tacdiff.prior`) and ``prior_radius`` its TELEA
    radius (px); the fills are computed once per shard (``telea``, ``smooth`` arrays added to
    it, see :func:`ensure_fills`).
    """

    def __init__(self, shards: Sequence[dict[str, NDArray[Any]]], size: int = 64,
                 augment: bool = True, *, prior: str = DEFAULT_PRIOR,
                 prior_radius: float = DEFAULT_PRIOR_RADIUS,
                 contact_share: float = 0.0, hole_share: float = 0.5) -> None:
        self.prior = check_prior(prior)
        self.prior_radius = check_radius(prior_radius)
        if not (0 <= contact_share and 0 <= hole_share and contact_share + hole_share <= 1):
            raise ValueError("contact_share, hole_share: need shares >= 0 summing to <= 1; got "
                             f"{contact_share}, {hole_share}")
        self.contact_share, self.hole_share = contact_share, hole_share
        self.shards = [s for s in shards if len(s["cond"]) > 0]
        if not self.shards:
            raise ValueError("shards: no samples")
        for s in self.shards:
            h, w = s["cond"].shape[1:3]
            if h < size or w < size:
                raise ValueError(f"size: crop {size} larger than a {h}x{w} frame")
        self.size = size
        self.augment = augment
        for sh in self.shards:
            ensure_fills(sh, self.prior, self.prior_radius)
        weights = np.array([len(s["cond"]) for s in self.shards], np.float64)
        self.shard_p = weights / weights.sum()
        # Loss pixels per sample (all, and those in contact), for centred crops (computed once).
        self._hits = [[np.argwhere(m) for m in s["loss_mask"]] for s in self.shards]
        self._contact_hits = [
            [np.argwhere(m & c) for m, c in zip(s["loss_mask"], s["contact"], strict=True)]
            if "contact" in s else [np.empty((0, 2), np.int64)] * len(s["loss_mask"])
            for s in self.shards]

    def batch(self, n: int, rng: np.random.Generator) -> dict[str, NDArray[Any]]:
        """``n`` crops: ``cond``/``target``/``prior`` (and ``spread`` for two-fill priors)
        ``n x 3 x S x S`` float32 in [-1, 1] (BGR), ``mask``/``loss_mask`` ``n x 1 x S x S``
        float32 in {0, 1}."""
        s = self.size
        two = has_spread(self.prior)
        planes = 4 if two else 3  # cond, target, telea[, smooth]
        # Crops are gathered as uint8 and converted in one go: the same float32 arithmetic per
        # pixel as crop by crop (orientation is a permutation), with less Python overhead.
        imgs = np.empty((planes, n, s, s, 3), np.uint8)
        masks = np.empty((2, n, s, s), np.uint8)
        gain = np.ones((n, 1, 1, 3), np.float32)
        bias = np.zeros((n, 1, 1, 3), np.float32)
        for b in range(n):
            k = int(rng.choice(len(self.shards), p=self.shard_p))
            shard = self.shards[k]
            i = int(rng.integers(len(shard["cond"])))
            h, w = shard["cond"].shape[1:3]
            u = rng.random()
            hits = self._contact_hits[k][i]
            if not (len(hits) and u < self.contact_share):
                hits = self._hits[k][i] if u < self.contact_share + self.hole_share else hits[:0]
            if len(hits):
                cy, cx = hits[int(rng.integers(len(hits)))]
                y0 = int(np.clip(cy - s // 2 + rng.integers(-s // 4, s // 4 + 1), 0, h - s))
                x0 = int(np.clip(cx - s // 2 + rng.integers(-s // 4, s // 4 + 1), 0, w - s))
            else:
                y0, x0 = int(rng.integers(h - s + 1)), int(rng.integers(w - s + 1))
            win = (i, slice(y0, y0 + s), slice(x0, x0 + s))
            keys = ("cond", "target", "telea", "smooth")[:planes]
            crops = [shard[key][win] for key in keys] + [shard["mask"][win],
                                                         shard["loss_mask"][win]]
            if self.augment:
                gain[b] = rng.uniform(0.75, 1.25, 3).astype(np.float32)
                bias[b] = rng.uniform(-20, 20, 3).astype(np.float32)
                turns, flip = int(rng.integers(4)), bool(rng.random() < 0.5)
                crops = [_orient(a, turns, flip) for a in crops]
            imgs[:, b] = crops[:planes]
            masks[:, b] = crops[planes:]
        x = imgs.astype(np.float32)
        if self.augment:
            x = np.clip(x * gain + bias, 0, 255)
        to_net = lambda a: np.ascontiguousarray(prior_to_net(a).transpose(0, 3, 1, 2))  # noqa: E731
        prior, spread = combine(to_net(x[2]), to_net(x[3]) if two else None)
        m = masks.astype(np.float32)
        out = {"cond": to_net(x[0]), "target": to_net(x[1]), "prior": prior,
               "mask": m[0][:, None], "loss_mask": m[1][:, None]}
        if spread is not None:
            out["spread"] = spread
        return out


def fills_radius(shard: dict[str, NDArray[Any]]) -> float:
    """The TELEA radius (px) ``shard``'s cached ``telea`` fill was computed with (``fills_radius``;
    absent: :data:`~tacswitch.tacdiff.prior.PRIOR_RADIUS`, the caches of models before 0.4)."""
    return float(shard.get("fills_radius", PRIOR_RADIUS))


def has_fills(shard: dict[str, NDArray[Any]], prior: str,
              radius: float = DEFAULT_PRIOR_RADIUS) -> bool:
    """Whether ``shard`` carries the classical fills of ``prior`` at TELEA ``radius`` px
    (``telea``, ``smooth``), recorded as computed for them (``fills_prior``, ``fills_radius``),
    e.g. by :func:`cache_fills`."""
    kind = shard.get("fills_prior")
    return (kind is not None and str(kind) == prior and "telea" in shard
            and fills_radius(shard) == float(radius)
            and (not has_spread(prior) or "smooth" in shard))


def ensure_fills(shard: dict[str, NDArray[Any]], prior: str,
                 radius: float = DEFAULT_PRIOR_RADIUS) -> bool:
    """Adds (or replaces) ``shard``'s classical fills of ``prior`` at TELEA ``radius`` px unless
    it has them; returns whether it computed any. Where only the radius differs the biharmonic
    ``smooth`` fill (which has no radius) is kept and only TELEA is solved again."""
    check_prior(prior)
    radius = check_radius(radius)
    if has_fills(shard, prior, radius):
        return False
    kind = shard.get("fills_prior")
    if (kind is not None and str(kind) == prior and has_spread(prior) and "smooth" in shard):
        shard["telea"] = classical_fills(shard["cond"], shard["mask"], "telea", radius)[0]
    else:
        shard.pop("smooth", None)
        shard["telea"], smooth = classical_fills(shard["cond"], shard["mask"], prior, radius)
        if smooth is not None:
            shard["smooth"] = smooth
    shard["fills_prior"] = np.array(prior)
    shard["fills_radius"] = np.array(radius)
    return True


def cache_fills(root: str | Path, prior: str = DEFAULT_PRIOR, progress: bool = True,
                radius: float = DEFAULT_PRIOR_RADIUS) -> int:
    """Stores the classical fills of ``prior`` at TELEA ``radius`` px in every shard under
    ``root`` that lacks them, so training runs (and resumed runs) on those shards skip computing
    them. Returns the number of shards written. :func:`remask` drops them again when a mask
    changes."""
    check_prior(prior)
    radius = check_radius(radius)
    done = 0
    for path in sorted(Path(root).glob("pairs_*.npz")):
        arrays = dict(np.load(path))
        if not ensure_fills(arrays, prior, radius):
            continue
        with atomic_open(path, "wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]
        done += 1
        if progress:
            print(f"{path.name}: fills of {prior}, TELEA r = {radius:g}", flush=True)
    return done


def classical_fills(frames: NDArray[np.uint8], masks: NDArray[np.bool_], prior: str,
                    radius: float = DEFAULT_PRIOR_RADIUS
                    ) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None]:
    """``B x H x W x 3`` frames with their holes filled by TELEA of ``radius`` px, and by the
    biharmonic fill when ``prior`` uses it (:func:`tacswitch.tacdiff.prior.fills`, as at
    inference)."""
    pairs = [fills(f, m, prior, radius) for f, m in zip(frames, masks, strict=True)]
    telea = np.stack([p[0] for p in pairs])
    smooth = np.stack([p[1] for p in pairs]) if has_spread(prior) else None  # type: ignore[misc]
    return telea, smooth


def _orient(a: NDArray[Any], turns: int, flip: bool) -> NDArray[Any]:
    a = np.rot90(a, turns, axes=(0, 1))
    return a[:, ::-1] if flip else a
