"""``tacswitch finetune`` as a library call: fine-tune TacDiff on a sensor's own marker frames,
validated without ground truth, and keep whichever model is best (torch).

A fine-tune on a user's frames can help, do nothing or hurt (too few frames, a learning rate
too high, markers the transplant misrepresents), and the user has no ground truth to tell which.
On a dense marker grid (one training shift fits, e.g. a GelSight Mini's) the check below has
passed models that were worse on held-out frames and never found a real gain, so there nothing
is trained unless ``trust_dense=True``.
So the fine-tune checks itself on pixels it never trains on:

- **held-out frames**: with at least :data:`MIN_FRAMES_TO_SPLIT` frames, every k-th frame
  (``val_share`` of them, at most ``val_frames``) is kept out of training;
- **held-out gel**: on those frames the real markers are transplanted by another offset than
  the training ones (:func:`validation_offset`: the candidate half-pitch shift whose holes
  overlap the training holes least), so the scored gel pixels were never a training target
  even where every frame must be used (fewer than :data:`MIN_FRAMES_TO_SPLIT`).

Each training frame's markers are moved by several shifts (:func:`training_shifts`: the
half-pitch diagonal, its opposite and its axis parts, where they land on gel clear of the
originals and off the validation gel): more gel
and more marker arrangements from the same few frames. On taxim's real GelSight presses (39
training frames, H.264, a start that never saw that sensor) four shifts and 1200 steps took the
held-out error from -1.7 % to -2.8 % of the start's (BENCHMARKS.md, "TacDiff fine-tune: four
training shifts, 1200 steps, a per-frame noise test").

Both the training and the validation transplants are re-compressed like the source recording
(``recompress``, :mod:`~tacswitch.tacdiff.recompress`: a JPEG/MJPEG source's quality is
recognised; H.264 is named by the user): on a compressed recording the gel around a real
marker is quantised together with it, and a fine-tune on transplants without that distortion
improved its own validation while making held-out frames worse.

The score is the masked MAE (grey levels) of the model's fill, as
:func:`~tacswitch.tacdiff.infer.inpaint_tacdiff` runs it (ONNX, K=1) in one orientation (the
default averages four at inference; one keeps the check at a quarter of the cost; the
returned model is then run with four), on the moved markers' real-gel pixels, per moved
marker. The starting model is scored first; every ``val_every`` steps the EMA weights are
exported and scored. The best checkpoint is kept only if it beats the
starting model *beyond noise* (:func:`beats`: with at least :data:`MIN_CLUSTER_FRAMES`
validation frames, the mean of the per-frame improvements exceeds Student's t 97.5 % quantile
times their standard error, since the markers of one frame are not independent; with fewer,
the mean per-marker improvement exceeds :data:`NOISE_Z` standard errors); otherwise
``OUT/model.onnx`` is the starting model itself and the summary says so. ``OUT/finetune.json``
records every score and the choice.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.tacdiff.recompress import Recompress
from tacswitch.tacdiff.transplant import DEFAULT_RING

#: Below this many frames every frame trains and validates (held-out gel only).
MIN_FRAMES_TO_SPLIT = 5
#: Standard errors of the per-marker improvement a checkpoint needs to replace the start model
#: (validation on fewer than :data:`MIN_CLUSTER_FRAMES` frames).
NOISE_Z = 2.0
#: From this many validation frames the noise test works on per-frame means (markers of one
#: frame share its capture and contact, so they are not independent evidence): Student's t.
MIN_CLUSTER_FRAMES = 3
#: Two-sided 95 % quantiles of Student's t for 1-30 degrees of freedom (beyond: the normal
#: quantile with its first two Cornish-Fisher terms).
_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179,
         2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
         2.060, 2.056, 2.052, 2.048, 2.045, 2.042)
#: Pseudo-markerless fills the transplants can be built on (``finetune(pseudo=...)``).
PSEUDO_FILLS: tuple[str, ...] = ("telea", "model")
#: Training steps of a fine-tune (600 before 0.7: with four shifts the held-out error kept
#: falling to about step 800 of 1200).
DEFAULT_STEPS = 1200
#: Training shifts per fine-tune (:func:`training_shifts`; 1: the single half-pitch diagonal
#: of every release before 0.7).
DEFAULT_SHIFTS = 4
#: Most training pairs (frames x shifts) held at once; past it each frame gets fewer shifts,
#: in rotation (``marker_offset_pairs(per_frame=...)``): ~2.4 MB a pair at 640 x 480.
MAX_PAIRS = 256


@dataclass
class FinetuneResult:
    """What :func:`finetune` chose and why.

    Attributes:
        model: the ONNX file to use (``OUT/model.onnx``).
        chosen_step: the step of the exported weights; 0: the starting model was kept.
        start_score: validation masked MAE of the starting model (grey levels).
        scores: ``{step: masked MAE}`` of every validated checkpoint.
        noise: the improvement over the starting model (grey levels) the chosen (or best)
            checkpoint had to exceed (:func:`beats`).
        train_frames, val_frames: indices of the frames used for each.
        val_offset: ``(dx, dy)`` px of the validation transplant; ``val_markers``: markers
            scored; ``val_overlap``: share of their pixels that were training targets too (0
            unless the grid is too dense for any other shift; held-out frames still differ).
        recompress: how the transplanted frames were re-compressed (``"none"``, ``"jpeg:Q"``,
            ``"h264:CRF"``).
        train_offsets: the training shifts used (:func:`training_shifts`).
        dense: the grid allows one training shift only (dense markers, such as the GelSight
            Mini's): there the check has been seen to improve while held-out frames got worse,
            and :meth:`summary` says so.
        skipped: a dense grid without ``trust_dense``: no training ran and ``model`` is the
            starting model (:func:`finetune`).
    """

    model: Path
    chosen_step: int
    start_score: float
    scores: dict[int, float] = field(default_factory=dict)
    noise: float = 0.0
    train_frames: list[int] = field(default_factory=list)
    val_frames: list[int] = field(default_factory=list)
    val_offset: tuple[int, int] = (0, 0)
    val_markers: int = 0
    val_overlap: float = 0.0
    recompress: str = "none"
    train_offsets: list[tuple[int, int]] = field(default_factory=list)
    dense: bool = False
    skipped: bool = False

    @property
    def kept_start(self) -> bool:
        """Whether no checkpoint beat the starting model (``model`` is the start model)."""
        return self.chosen_step == 0

    def summary(self) -> str:
        """One line for the user."""
        head = (f"validation (held-out transplanted markers: {self.val_markers} on "
                f"{len(self.val_frames)} frame(s)"
                + (f", {100 * self.val_overlap:.0f} % on training gel" if self.val_overlap
                   else "") + f", re-compressed: {self.recompress}"
                f"; masked MAE in grey levels): start {self.start_score:.3f}")
        if self.skipped:
            return (head + "; a dense marker grid (one training shift fits), where this check "
                    "has passed models that were worse on held-out frames: no training ran, "
                    f"{self.model} is the starting model (trust_dense=True, --trust-dense: "
                    "train and let the check choose)")
        if not self.scores:
            return head + "; no checkpoint validated"
        best = min(self.scores, key=lambda k: self.scores[k])
        g = len(set(self.val_frames))
        test = (f"per-frame test over {g} frames" if g >= MIN_CLUSTER_FRAMES
                else "per-marker test: fewer than 3 validation frames")
        if self.kept_start:
            note = ("; a dense marker grid (one training shift fits), where this check has "
                    "improved while held-out frames got worse" if self.dense else "")
            return (head + f", best step {best} {self.scores[best]:.3f}; no checkpoint beat the "
                    f"start beyond noise ({self.noise:.3f}, {test}): {self.model} is the "
                    "starting model" + note)
        s = self.scores[self.chosen_step]
        caution = ("; caution: a dense marker grid (one training shift fits), where this check "
                   "has improved while held-out frames got worse: compare with the start model "
                   "on frames you know" if self.dense else "")
        return (head + f", chosen step {self.chosen_step} {s:.3f} "
                f"({100 * (s / self.start_score - 1):+.1f} %, noise {self.noise:.3f}, {test})"
                + caution)


def split_frames(n: int, val_share: float = 0.2, val_frames: int = 8
                 ) -> tuple[list[int], list[int]]:
    """``(train, val)`` frame indices: every k-th frame held out (``val_share`` of ``n``, at
    least 1, at most ``val_frames``) when ``n >= MIN_FRAMES_TO_SPLIT``; otherwise all frames
    in both (validation then relies on :func:`validation_offset` alone)."""
    if n < 1:
        raise ValueError(f"frames: need at least one frame; got {n}")
    if not 0 < val_share < 1:
        raise ValueError(f"val_share: expected a share in (0, 1); got {val_share}")
    if val_frames < 1:
        raise ValueError(f"val_frames: must be >= 1; got {val_frames}")
    if n < MIN_FRAMES_TO_SPLIT:
        return list(range(n)), list(range(n))
    k = min(val_frames, max(1, round(n * val_share)))
    # Evenly spread (not the last k): a recording drifts, both sets should span it.
    val = sorted({int(i) for i in np.linspace(0, n - 1, k + 2)[1:-1].round()})
    return [i for i in range(n) if i not in val], val


def _footprint_appearance(mask: NDArray[np.bool_], ring: int) -> Any:
    """An :class:`~tacswitch.tacdiff.transplant.Appearance` holding only the labels and
    footprint of ``mask``'s markers: all :func:`~tacswitch.tacdiff.transplant.movable` reads."""
    import cv2

    from tacswitch.markers import dilate_mask
    from tacswitch.tacdiff.transplant import Appearance

    footprint = dilate_mask(mask, ring) if ring else mask.astype(bool)
    labels = cv2.connectedComponents(footprint.view(np.uint8), connectivity=8)[1]
    return Appearance(np.empty((0, 0, 3), np.float32), footprint, labels.astype(np.int32),
                      np.empty((0, 0, 3), np.uint8))


def _moved_holes(app: Any, mask: NDArray[np.bool_], sh: tuple[int, int],
                 ok: NDArray[np.bool_] | None = None) -> NDArray[np.bool_]:
    """``mask`` moved by ``sh``, keeping only the markers
    :func:`~tacswitch.tacdiff.transplant.movable` lets move (``ok``, computed if None)."""
    from tacswitch.tacdiff.transplant import movable, shift

    if ok is None:
        ok = movable(app, mask, sh)
    return shift(mask, sh, False) & ok[shift(app.labels, sh, 0)]


def _share(moved: NDArray[np.bool_], other: NDArray[np.bool_]) -> float:
    """Share of ``moved``'s pixels that ``other`` holds too."""
    return float((moved & other).sum() / max(1, moved.sum()))


def training_shifts(mask: NDArray[np.bool_], offset: tuple[int, int], shifts: int, *,
                    ring: int = DEFAULT_RING, avoid: tuple[int, int] | None = None
                    ) -> list[tuple[int, int]]:
    """The training shifts of a fine-tune: the first ``shifts`` of ``offset`` ``(a, b)``, its
    opposite ``(-a, -b)`` and its axis parts (``(a, 0)``, ``(-a, 0)``, then ``(0, b)``,
    ``(0, -b)``), keeping only
    those that move at least half as many of ``mask``'s markers onto gel as ``offset`` does
    (:func:`~tacswitch.tacdiff.transplant.movable`) and whose moved holes mostly keep clear of
    the original holes (median gap at least
    :data:`~tacswitch.tacdiff.infer.SEPARATION` px, Chebyshev): holes that close are never
    met at inference (they are filled in separate passes), and on the GelSight Mini's dense
    grid (28.5 px pitch, a 2 px median gap at the axis shifts) training on them fooled the
    validation while the held-out frames got worse. With ``avoid`` (the validation shift) a
    candidate is also dropped if its moved holes overlap the validation holes more than
    ``offset``'s do, so validation keeps scoring gel the training never saw. On a square grid
    with the default ``(d, d)`` the diagonals bring other markers to the same gel and the
    axis shifts bring them to gel between two markers; those along the validation shift's axis
    stay free for it."""
    import cv2

    from tacswitch.tacdiff.infer import SEPARATION
    from tacswitch.tacdiff.transplant import movable

    if shifts < 1:
        raise ValueError(f"shifts: must be >= 1; got {shifts}")
    a, b = int(offset[0]), int(offset[1])
    if (a, b) == (0, 0):
        raise ValueError(f"offset: must not be (0, 0); got {offset}")
    app = _footprint_appearance(mask, ring)
    need = 0.5 * max(1, int(movable(app, mask, (a, b)).sum()))
    gap = cv2.distanceTransform((~mask.astype(bool)).view(np.uint8), cv2.DIST_C, 3)
    held = _moved_holes(app, mask, avoid) if avoid is not None else None
    allowed = _share(_moved_holes(app, mask, (a, b)), held) if held is not None else 0.0
    out = [(a, b)]
    for cand in ((-a, -b), (a, 0), (-a, 0), (0, b), (0, -b)):
        if len(out) >= shifts:
            break
        if cand == (0, 0) or cand in out:
            continue
        ok = movable(app, mask, cand)
        if ok.sum() < need:
            continue
        moved = _moved_holes(app, mask, cand, ok)
        if not moved.any() or float(np.median(gap[moved])) < SEPARATION:
            continue
        if held is not None and _share(moved, held) > allowed + 1e-9:
            continue
        out.append(cand)
    return out


def validation_offset(mask: NDArray[np.bool_], train_offset: tuple[int, int], *,
                      ring: int = DEFAULT_RING) -> tuple[tuple[int, int], float]:
    """A half-pitch shift for the validation transplant, and the share of its moved holes that
    overlaps the training holes (``mask`` shifted by ``train_offset``; the extra training shifts
    of :func:`training_shifts` are then chosen to keep off the validation gel).

    Candidates are the eight half-pitch shifts; those moving fewer than half as many markers as
    the training shift (:func:`~tacswitch.tacdiff.transplant.movable`: on dense grids the axis
    shifts land on the neighbours' footprints) are dropped, and the one overlapping the
    training holes least is taken. On a square grid with the training shift (+d, +d) the
    mirrored (-d, +d) lands on the very same gel (the neighbour's training spot) while (d, 0)
    lands between two markers, on gel never trained on; where only the diagonals can move
    markers the overlap is returned so the caller can say so."""
    from tacswitch.tacdiff.transplant import movable, shift

    train_offset = (int(train_offset[0]), int(train_offset[1]))
    d = max(abs(train_offset[0]), abs(train_offset[1]))
    if d == 0:
        raise ValueError(f"offset: must not be (0, 0); got {train_offset}")
    app = _footprint_appearance(mask, ring)
    trained = shift(mask, train_offset, False)
    need = 0.5 * max(1, int(movable(app, mask, train_offset).sum()))
    options = []
    for cand in ((d, 0), (0, d), (-d, 0), (0, -d), (-d, d), (d, -d), (-d, -d), (d, d)):
        if cand == train_offset:
            continue
        ok = movable(app, mask, cand)
        if ok.sum() < need:
            continue
        options.append((_share(_moved_holes(app, mask, cand, ok), trained), -int(ok.sum()), cand))
    if not options:
        raise ValueError("offset: no validation shift moves enough markers onto gel; pass "
                         "another offset")
    overlap, _, best = min(options)
    return best, overlap


@dataclass(frozen=True)
class ValidationSet:
    """Transplanted validation inputs: ``cond``/``target``/``mask``/``loss_mask`` as in
    :func:`~tacswitch.tacdiff.data.marker_offset_pairs`, and ``labels`` (``B x H x W`` int32,
    one label per moved marker, 0 elsewhere) for per-marker scores."""

    pairs: dict[str, NDArray[Any]]
    labels: NDArray[np.int32]
    offset: tuple[int, int]

    @property
    def markers(self) -> int:
        """Moved markers with at least one scored pixel."""
        return len(self.marker_frames)

    @property
    def marker_frames(self) -> NDArray[np.int64]:
        """The validation frame (index into its frames) of each scored marker, in the order of
        :func:`marker_scores`."""
        per = [len(np.unique(lab[lm])) for lab, lm
               in zip(self.labels, self.pairs["loss_mask"], strict=True)]
        return np.repeat(np.arange(len(per), dtype=np.int64), per)


def validation_set(frames: Sequence[NDArray[np.uint8]], offset: tuple[int, int], *,
                   ring: int = DEFAULT_RING, recompress: Recompress | None = None,
                   pseudo_fill: Any = None, mask_originals: bool = False,
                   **extract_opts: Any) -> ValidationSet:
    """The validation transplant of ``frames`` by ``offset`` (one ``(dx, dy)``; see the module
    docstring), re-compressed by ``recompress`` like the training pairs."""
    import cv2

    if np.ndim(offset) != 1:
        raise ValueError(f"offset: expected one (dx, dy) shift for validation; got {offset!r}")

    from tacswitch.tacdiff.data import marker_offset_pairs

    pairs = marker_offset_pairs(frames, offset=offset, transplant=True, ring=ring,
                                recompress=recompress, pseudo_fill=pseudo_fill,
                                mask_originals=mask_originals, **extract_opts)
    # One label per moved marker (the originals, holes too with mask_originals, are not scored).
    labels = np.stack([cv2.connectedComponents(m.view(np.uint8), connectivity=8)[1]
                       for m in pairs.get("moved", pairs["mask"])]).astype(np.int32)
    return ValidationSet(pairs, labels, offset)


def marker_scores(model: str | Path, val: ValidationSet) -> NDArray[np.float64]:
    """Per moved marker (all frames, in order): the masked MAE (grey levels, all channels) of
    ``model``'s fill, run as :func:`~tacswitch.tacdiff.infer.inpaint_tacdiff` runs it in one
    orientation, over the marker's real-gel pixels."""
    from tacswitch.tacdiff.infer import inpaint_tacdiff

    out: list[float] = []
    p = val.pairs
    for cond, target, mask, loss, lab in zip(p["cond"], p["target"], p["mask"],
                                             p["loss_mask"], val.labels, strict=True):
        # One orientation: the check compares checkpoints, and averaging four would only
        # quadruple its cost (inference averages them for the returned model alike).
        fill = inpaint_tacdiff(cond, mask, model=model, orientations=1)
        err = np.abs(fill.astype(np.float64) - target.astype(np.float64)).mean(axis=2)
        keys = lab[loss]
        sums = np.bincount(keys, weights=err[loss], minlength=int(lab.max()) + 1)
        counts = np.bincount(keys, minlength=int(lab.max()) + 1)
        out.extend((sums[counts > 0] / counts[counts > 0]).tolist())
    return np.asarray(out)


def t975(df: int) -> float:
    """The 97.5 % quantile of Student's t with ``df >= 1`` degrees of freedom."""
    if df < 1:
        raise ValueError(f"df: must be >= 1; got {df}")
    if df <= len(_T975):
        return _T975[df - 1]
    z = 1.959964
    return z + (z ** 3 + z) / (4 * df) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * df * df)


def beats(start: NDArray[np.float64], cand: NDArray[np.float64], z: float = NOISE_Z,
          groups: NDArray[np.int64] | None = None) -> tuple[bool, float]:
    """Whether ``cand``'s per-marker errors beat ``start``'s beyond noise. Returns ``(beats,
    noise)``.

    Without ``groups`` (or with fewer than :data:`MIN_CLUSTER_FRAMES` of them): the mean paired
    improvement must exceed ``z`` standard errors (noise = ``z * SE``). With ``groups`` (the
    validation frame of each marker): the mean of the per-frame mean improvements must exceed
    ``t975(G - 1)`` standard errors of those ``G`` means. Markers of one frame share its
    capture and contact, so counting them as independent overstates the evidence: on the
    GelSight Mini proxy (3 validation frames, 139 markers) a checkpoint passed the per-marker
    test while the held-out frames got 4 % worse, and fails this one."""
    if start.shape != cand.shape or len(start) == 0:
        raise ValueError("cand: needs one score per marker of start")
    d = start - cand
    if groups is not None:
        g = np.asarray(groups)
        if g.shape != d.shape:
            raise ValueError("groups: needs one frame index per marker of start")
        keys = np.unique(g)
        if len(keys) >= MIN_CLUSTER_FRAMES:
            per = np.array([d[g == k].mean() for k in keys])
            noise = t975(len(per) - 1) * float(per.std(ddof=1)) / np.sqrt(len(per))
            return bool(per.mean() > 0 and per.mean() > noise), noise
    noise = z * float(d.std(ddof=1)) / np.sqrt(len(d)) if len(d) > 1 else float("inf")
    return bool(d.mean() > 0 and d.mean() > noise), noise


def start_onnx(init: str | Path | None, out: Path) -> Path:
    """The ONNX file of the starting model (what the user runs without a fine-tune): the
    shipped model by name (None: the default), a ``.onnx`` path itself, or other weights
    exported to ``out/start.onnx``."""
    from tacswitch.tacdiff.infer import SHIPPED, model_path

    if init is None or (isinstance(init, str) and init in SHIPPED):
        return model_path(init)
    p = Path(init)
    if p.suffix == ".onnx":
        return p
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.train import load_network

    return export_onnx(load_network(p), out / "start.onnx")


def start_objective(start: Path) -> tuple[str, float]:
    """``(loss, terminal_fraction)`` the starting model was trained with, as its ONNX records
    them (``tacswitch.loss``, ``tacswitch.terminal_fraction``; the 0.5 models: x0_l1 / v_mse at
    0.9); the training defaults for models exported before they were recorded. A fine-tune keeps
    its start's objective: K = 1 sampling, the shipped setting, runs only the pure-noise step
    that a terminal fraction of 0.9 trains, and a different loss would pull the weights to
    another estimate (median vs mean) than the one they were chosen for."""
    from tacswitch.tacdiff.infer import load_model
    from tacswitch.tacdiff.train import TrainConfig, check_loss

    meta = load_model(start).metadata
    loss = check_loss(meta.get("tacswitch.loss", TrainConfig.loss), "model")
    raw = meta.get("tacswitch.terminal_fraction")
    frac = TrainConfig.terminal_fraction if raw is None else float(json.loads(raw))
    if not 0 <= frac <= 1:
        raise ValueError(f"model: {str(start)!r} records tacswitch.terminal_fraction={raw!r}; "
                         "expected a number in [0, 1]")
    return loss, frac


def init_weights(init: str | Path | None) -> Path:
    """The weights file training starts from: the shipped default's safetensors (None or
    ``"default"``), the fast model's ONNX (``"fast"``), or ``init`` itself."""
    from tacswitch.tacdiff.infer import SHIPPED, default_weights_path, model_path

    if init is None or init == "default":
        return default_weights_path()
    if isinstance(init, str) and init in SHIPPED:
        return model_path(init)
    return Path(init)


def finetune(frames: Sequence[NDArray[np.uint8]], out: str | Path, *,
             init: str | Path | None = None, steps: int = DEFAULT_STEPS, batch: int = 8,
             crop: int = 96, lr: float = 2e-4, seed: int = 0,
             offset: tuple[int, int] | None = None, transplant: bool = True,
             ring: int = DEFAULT_RING, val_every: int = 100, val_share: float = 0.2,
             val_frames: int = 8, threads: int = 0, progress: bool = True,
             loss: str | None = None, terminal_fraction: float | None = None,
             recompress: str = "auto", pseudo: str = "model", mask_originals: bool = True,
             shifts: int = DEFAULT_SHIFTS, trust_dense: bool = False,
             extra: dict[str, Any] | None = None) -> FinetuneResult:
    """Fine-tunes TacDiff on ``frames`` (a sensor's marker frames, no ground truth) and keeps the
    best of the starting model and the validated checkpoints (module docstring).

    Args:
        frames: ``H x W x 3`` uint8 BGR frames with markers, all the same size.
        out: run folder (``checkpoint.pt``, ``log.jsonl``, ``best.safetensors``,
            ``finetune.json``, ``model.onnx``); rerunning resumes.
        init: starting model: None/``"default"``, ``"fast"``, or a weights/ONNX path.
        steps, batch, crop, lr, seed, threads: training (:class:`~.train.TrainConfig`).
        offset: training shift ``(dx, dy)`` px (default: half the pitch, codec-block rounded).
        shifts: how many training shifts each frame's markers are moved by
            (:func:`training_shifts`: ``offset``, its opposite and its axis parts;
            more gel and more marker-neighbour arrangements from the same frames); past
            :data:`MAX_PAIRS` frames x shifts each frame gets fewer shifts (at least one), in
            rotation over the frames.
        transplant, ring: as :func:`~tacswitch.tacdiff.data.marker_offset_pairs`.
        val_every: validate the EMA weights every this many steps (and at the end).
        val_share, val_frames: frames held out for validation (:func:`split_frames`).
        loss, terminal_fraction: training objective (:class:`~.train.TrainConfig`); None: the
            starting model's own (:func:`start_objective`).
        pseudo: the pseudo-markerless fill the transplants are built on (training and
            validation): ``"model"`` (the start model's own fill, closer to the gel around the
            moved markers; the default since 0.6) or ``"telea"`` (TELEA r = 3, before:
            its smooth fills next to the moved markers let validation and held-out frames
            disagree on the dense Mini grid); :data:`PSEUDO_FILLS`.
        mask_originals: every original marker is a hole too in training and validation inputs
            (:func:`~tacswitch.tacdiff.data.marker_offset_pairs`), as at inference (the default
            since 0.6; False: the moved markers only, among pseudo-filled originals).
        recompress: how the transplanted frames (training and validation) are re-compressed
            like the source: ``"auto"``, ``"none"``, ``"jpeg:Q"`` or ``"h264:CRF"``
            (:func:`~tacswitch.tacdiff.recompress.recompressor`).
        trust_dense: on a dense marker grid (one training shift fits, :func:`training_shifts`
            with :data:`DEFAULT_SHIFTS`), train and let the check choose. Default False: keep
            the starting model there without training, because on the GelSight Mini's grid
            (28.5 px pitch) no variant ever made held-out frames better and the check has
            passed models up to 4 % worse (the "TacDiff fine-tune" sections of
            docs/notes/2026-11-marker-removal.md).
    """
    from tacswitch.tacdiff.data import marker_offset_pairs, removal_markers
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.recompress import recompressor
    from tacswitch.tacdiff.train import (
        TrainConfig,
        check_loss,
        load_network,
        save_weights,
        train,
    )
    from tacswitch.tacdiff.transplant import default_offset
    from tacswitch.tracking import estimate_pitch

    if val_every < 1:
        raise ValueError(f"val_every: must be >= 1 step; got {val_every}")
    if pseudo not in PSEUDO_FILLS:
        raise ValueError(f"pseudo: expected one of {PSEUDO_FILLS}; got {pseudo!r}")
    if isinstance(shifts, bool) or not isinstance(shifts, (int, np.integer)) or shifts < 1:
        raise ValueError(f"shifts: expected an int >= 1; got {shifts!r}")
    if not isinstance(trust_dense, (bool, np.bool_)):
        raise ValueError(f"trust_dense: expected a bool; got {trust_dense!r}")
    run = Path(out)
    run.mkdir(parents=True, exist_ok=True)
    frames = list(frames)
    if len(frames) == 0:
        raise ValueError("frames: need at least one frame")
    tr, va = split_frames(len(frames), val_share, val_frames)
    redo, redo_text = recompressor(recompress, frames) if transplant else (None, "none")
    first = removal_markers(frames[0])
    if offset is None:
        pitch = estimate_pitch(first.centres)
        if pitch is None:
            raise ValueError("frames: too few markers found to estimate the pitch; pass offset "
                             "(tacswitch finetune --offset DX,DY)")
        offset = default_offset(pitch) if transplant else (round(pitch / 2),) * 2  # type: ignore[assignment]
    assert offset is not None
    offset = (int(offset[0]), int(offset[1]))
    start = start_onnx(init, run)
    fill = None
    if pseudo == "model":
        from tacswitch.tacdiff.infer import inpaint_tacdiff

        def fill(img: NDArray[np.uint8], holes: NDArray[np.bool_]) -> NDArray[np.uint8]:
            return inpaint_tacdiff(img, holes, model=start, orientations=1)

    # The validation shift first, as with one training shift; the extra shifts then keep off
    # its gel.
    val_offset, overlap = validation_offset(first.mask, offset, ring=ring)
    offsets = training_shifts(first.mask, offset, int(shifts), ring=ring, avoid=val_offset)
    # Dense whatever the number of shifts asked for: only the main one fits among the markers.
    dense = len(offsets if shifts >= DEFAULT_SHIFTS else training_shifts(
        first.mask, offset, DEFAULT_SHIFTS, ring=ring, avoid=val_offset)) == 1
    val = validation_set([frames[i] for i in va], val_offset, ring=ring, recompress=redo,
                         pseudo_fill=fill, mask_originals=mask_originals and transplant)
    if dense and not trust_dense:
        target, score = _keep_dense_start(start, run, val, progress)
        return FinetuneResult(target, 0, score, {}, 0.0, tr, va, val.offset, val.markers,
                              overlap, redo_text, offsets, dense=True, skipped=True)
    pairs = marker_offset_pairs([frames[i] for i in tr], offset=offsets, transplant=transplant,
                                ring=ring, recompress=redo, pseudo_fill=fill,
                                mask_originals=mask_originals and transplant,
                                per_frame=max(1, MAX_PAIRS // len(tr)))
    pairs.pop("moved", None)
    if not pairs["loss_mask"].any():
        raise ValueError("frames: no shifted marker pixel lands on real gel; pass offset "
                         "(tacswitch finetune --offset DX,DY)")
    if not val.pairs["loss_mask"].any():
        raise ValueError("frames: no validation marker lands on real gel; pass offset "
                         "(tacswitch finetune --offset DX,DY)")
    inherited = start_objective(start)
    loss = inherited[0] if loss is None else check_loss(loss)
    terminal_fraction = inherited[1] if terminal_fraction is None else float(terminal_fraction)
    if not 0 <= terminal_fraction <= 1:  # also refuses NaN
        raise ValueError(f"terminal_fraction: must be in [0, 1]; got {terminal_fraction!r}")
    weights = init_weights(init)
    arch = load_network(weights).cfg
    state_path = run / "finetune.json"
    state: dict[str, Any] = json.loads(state_path.read_text()) if state_path.is_file() else {}
    if "start" not in state:
        state["start"] = marker_scores(start, val).tolist()
        state["scores"], state["per_marker"] = {}, {}
    start_scores = np.asarray(state["start"])
    if len(start_scores) != val.markers:
        raise ValueError(f"out: {str(run)!r} holds a run on other frames; use another folder")
    if progress:
        print(f"start model {start.name}: validation {start_scores.mean():.3f} on "
              f"{val.markers} held-out markers ({len(va)} frame(s), offset {val.offset}, "
              f"{100 * overlap:.0f} % of their pixels on training gel; transplants "
              f"re-compressed: {redo_text})", flush=True)

    def validate(step: int, ema: Any) -> None:
        path = export_onnx(ema, run / f".val_{step}.onnx")
        try:
            s = marker_scores(path, val)
        finally:
            path.unlink(missing_ok=True)
        state["scores"][str(step)] = float(s.mean())
        state["per_marker"][str(step)] = s.tolist()
        ok, _ = beats(start_scores, s, groups=val.marker_frames)
        best = state.get("best")
        if ok and (best is None or s.mean() < state["scores"][str(best)]):
            save_weights(ema, run / "best.safetensors", {**asdict(arch), "mults":
                                                          list(arch.mults)})
            state["best"] = step
        _write_json(state_path, state)
        if progress:
            print(json.dumps({"step": step, "validation": round(float(s.mean()), 4),
                              "start": round(float(start_scores.mean()), 4),
                              "beats_start": ok}), flush=True)

    # The start model's prior radius: its weights were trained (and it is scored) with it.
    cfg = TrainConfig(base=arch.base, mults=arch.mults, attention=arch.attention,
                      prior=arch.prior, prior_radius=arch.prior_radius, steps=steps, batch=batch,
                      crop=crop, lr=lr, loss=loss, terminal_fraction=terminal_fraction,
                      warmup=min(100, steps // 10), seed=seed, threads=threads,
                      # The shifts are recorded only when several train, so a run folder of
                      # one shift (every release before) still resumes.
                      extra={**(extra or {}), "offset": list(offset),
                             **({"offsets": [list(o) for o in offsets]} if len(offsets) > 1
                                else {}), "transplant": transplant,
                             "ring": ring, "recompress": redo_text, "train_frames": tr,
                             "val_frames": va})
    train([pairs], run, cfg, progress=progress, init=weights, callback=validate,
          callback_every=val_every)
    best = state.get("best")
    target = run / "model.onnx"
    noise = float("nan")
    if state["scores"]:
        # The noise scale of the chosen checkpoint, or of the best one when none was chosen.
        top = best if best is not None else min(state["scores"], key=state["scores"].get)
        _, noise = beats(start_scores, np.asarray(state["per_marker"][str(top)]),
                         groups=val.marker_frames)
    if best is None:
        shutil.copyfile(start, target)
        chosen = 0
    else:
        export_onnx(load_network(run / "best.safetensors"), target,
                    metadata={"finetuned_on": len(tr), "step": best, "seed": seed,
                              "loss": loss, "terminal_fraction": terminal_fraction,
                              "recompress": redo_text,
                              "transplant": transplant, "validation": state["scores"][str(best)],
                              "validation_start": float(start_scores.mean())})
        chosen = int(best)
    state["chosen"] = chosen
    _write_json(state_path, state)
    return FinetuneResult(target, chosen, float(start_scores.mean()),
                          {int(k): v for k, v in state["scores"].items()}, noise, tr, va,
                          val.offset, val.markers, overlap, redo_text, offsets, dense)


def _keep_dense_start(start: Path, run: Path, val: ValidationSet, progress: bool
                      ) -> tuple[Path, float]:
    """A dense grid without ``trust_dense``: the start model copied to ``OUT/model.onnx``
    (nothing trained) and its validation score (for the summary), as ``(model, score)``. A
    folder holding a trained run (``trust_dense=True`` before) is refused, not overwritten."""
    state_path = run / "finetune.json"
    if state_path.is_file() and "scores" in json.loads(state_path.read_text()):
        raise ValueError(f"out: {str(run)!r} holds a trained run on a dense grid; rerun with "
                         "trust_dense=True (--trust-dense) to resume it, or use another folder")
    score = float(marker_scores(start, val).mean()) if val.markers else float("nan")
    target = run / "model.onnx"
    shutil.copyfile(start, target)
    _write_json(state_path, {"chosen": 0, "skipped": "dense grid", "start": score})
    if progress:
        print("dense marker grid (one training shift fits): keeping the start model without "
              "training (trust_dense=True to train)", flush=True)
    return target, score


def _write_json(path: Path, obj: dict[str, Any]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(obj, indent=1))
    tmp.replace(path)
