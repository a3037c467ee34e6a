"""Training the learned slip scorer on labelled grasps (needs ``tacswitch[train]``: torch, onnx).

Labels are per experiment (did the object slip at some point), not per frame, so the scorer is
trained as a multiple-instance classifier: it scores every frame from the online features of
that frame (:mod:`tacswitch.grasp.features`), an experiment's score is the largest frame score
over all its videos (after :data:`WARMUP` frames), and the loss is the binary cross-entropy of
that score against the experiment's label. A held grasp therefore has to stay below the
threshold on every frame of every finger, the way the online detector is judged.

The scorer is a small MLP (signed ``log1p`` of the features, standardised with the training set's
statistics, two hidden layers); :data:`N_MEMBERS` of them trained from different seeds are
averaged. Everything, the input transform included, is exported into one ONNX file.

What ships is a committee of :data:`COMMITTEE` such scorers (:func:`train_committee`), each
trained alone from its own seed: the detector flags a grasp once :func:`committee_votes` of them
(:data:`VOTE_FRACTION` of the members, rounded up) have fired in it. Why: one scorer's decisions on
unseen objects are unstable, not its ranking. Over 12 seeds (real GelSight Mini grasps, 5 folds by
object, real grasps only) single scorers reach balanced accuracy 0.73-0.85 (mean 0.79), and each
experiment is caught by a different subset of seeds; committees that vote decide more steadily,
and the larger the committee, the steadier (recipe with the rendered grasps; 32 seeds: committees
of 8 / 16 / 24 drawn from them reach 0.81 / 0.83 / 0.84 on average at 40 % of the votes, all 32
0.86). Averaging their logits or probabilities frame by frame does not help (0.80): the members
fire at different frames of the same slip. 40 %: 4 of 8 and 13 of 32 leave every rendered
validation hold alone (another sensor; 3 of 8 flag half of them), and on the real grasps
35-45 % of the votes decide alike at every committee size (``docs/notes/2026-11-slip.md``). The
markerless scorer is a committee of :data:`MARKERLESS_COMMITTEE` too (0.75 against 0.73 for 8 at
4 votes, objects held out).

When rendered grasps join the training set (the marker recipe), half of the committee
(:data:`REAL_ONLY_FRACTION`) trains on the real grasps alone. Members trained that way decide
better on unseen real objects (committees of 8 at 4 votes: 0.84 / 0.84 / 0.81 / 0.82 against
0.82 / 0.79 / 0.77 / 0.80 with the rendered grasps), but never learn the rendered grasps' textbook
slip (a committee of them alone catches none of the rendered held-out slips). Half and half keeps
every rendered decision and gains on the real grasps: 0.845 against 0.828 on average over 300
committees of 32 drawn from the same seeds' members (13 votes).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.grasp.features import N_FEATURES

#: Frames at the start of a video that are never scored (the windows are still filling).
WARMUP = 3
#: Members of the averaged ensemble.
N_MEMBERS = 3
HIDDEN = (32, 16)
#: Passes over the experiments. Fewer generalise better to new objects here (5-fold
#: leave-objects-out balanced accuracy on the real Mini grasps: 20 / 40 / 150 epochs 0.71 / 0.73 /
#: 0.70, benches/bench_slip_real.py).
EPOCHS = 40
#: Scorers of the shipped marker committee (:func:`train_committee`), from consecutive seeds (96
#: since 2026-11-30, twenty-ninth stop; 32 before): committees drawn from 96 seeds' members,
#: objects held out, 32 / 64 / all 96 reach balanced accuracy 0.885 / 0.892 / 0.900, the larger
#: ones leaving more shaken holds alone (``docs/notes/2026-11-slip.md``).
COMMITTEE = 96
#: Scorers of the shipped markerless committee (32 since 2026-11-29, twelfth stop; 8 before).
MARKERLESS_COMMITTEE = 32
#: Share of a committee's members that must have fired in a grasp before the detector flags slip
#: (rounded up: 13 of 32, 4 of 8). A fraction, so rounding up is exact.
VOTE_FRACTION = Fraction(2, 5)
#: Share of the members trained with the rendered grasps that also flags a grasp on their own
#: (rounded up: 30 of 48, 10 of 16; :func:`half_votes`). Only they know the rendered grasps'
#: textbook slip, and :data:`VOTE_FRACTION` of all the votes would need about 80 % of them, which
#: a draw of seeds reaches about half of the time; on the real grasps this second vote never
#: fired where the first had not (objects held out, 30-36 of 48; notes).
HALF_VOTE_FRACTION = Fraction(5, 8)
#: Share of a committee's members trained without the rendered grasps (rounded down: 16 of 32)
#: when rendered grasps join the training set (:func:`train_committee`'s ``extra``).
REAL_ONLY_FRACTION = Fraction(1, 2)
#: What a scorer learned from (ONNX metadata ``tacswitch.motion``): tracked markers, or the
#: motion ``MarkerlessTracker`` predicts on a markerless sensor.
SCORER_MOTIONS = ("markers", "markerless")
#: A slip video counts as cut short by its slip when it is shorter than this share of the
#: median held video of its training set (the recording was stopped once the object fell).
CUT_SHORT = 0.9
#: The share of a cut-short slip video, from its end, whose frames may carry its experiment's
#: score in training (:func:`counted_from`): 1, every frame. The default of
#: :func:`train_committee` and the markerless recipe's (0.5 cost it: 0.770 -> 0.731, notes).
SLIP_TAIL = 1.0
#: The marker recipe's share (:func:`recipe_slip_tail`): its members trained on the real
#: grasps alone count the last half of a cut-short slip video. On the real GelSight Mini
#: grasps, objects held out, two seed sets of the recipe's committee: balanced accuracy 0.872 /
#: 0.890 -> 0.870 / 0.909, false alarms 1.12 / 0.57 -> 0.53 / 0.44 a minute of held footage,
#: the held-out rendered slips all caught (``docs/notes/2026-11-slip.md``, twenty-eighth stop).
MARKER_SLIP_TAIL = 0.5
#: Experiments per optimisation step.
BATCH = 8
LEARNING_RATE = 2e-3
WEIGHT_DECAY = 1e-4


@dataclass
class SlipTrainResult:
    """A trained scorer (a torch module) and what it was trained on."""

    net: Any
    n_experiments: int
    n_slip: int
    epochs: int
    seed: int
    #: Scorers in ``net`` (a committee of :func:`train_committee` outputs one logit each).
    committee: int = 1
    #: Members that must have fired in a grasp before it is flagged (1 for a single scorer).
    votes: int = 1
    #: The share of each cut-short slip video that counted in training (:func:`counted_from`;
    #: set by :func:`train_committee`: its ``slip_tail``, or 1 when every member also learned
    #: ``extra`` and so counted every frame).
    slip_tail: float = 1.0
    #: The first ``real_only`` members trained on the real grasps alone (:func:`train_committee`).
    real_only: int = 0
    #: Votes of the members after ``real_only`` that flag a grasp on their own (0: none;
    #: :func:`half_votes`).
    half_votes: int = 0

    @property
    def half_vote(self) -> tuple[int, int] | None:
        """``(real_only, half_votes)``, the detector's ``half_vote``; None without one."""
        return (self.real_only, self.half_votes) if self.half_votes else None


def _transform(x: Any) -> Any:
    import torch

    return torch.sign(x) * torch.log1p(torch.abs(x))


def build_scorer(mean: NDArray[np.floating], std: NDArray[np.floating],
                 members: int = N_MEMBERS, seed: int = 0) -> Any:
    """The torch scorer: ``B x N_FEATURES`` raw features -> ``B`` logits."""
    import torch
    from torch import nn

    class Scorer(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.register_buffer("mean", torch.tensor(np.asarray(mean), dtype=torch.float32))
            self.register_buffer("std", torch.tensor(np.asarray(std), dtype=torch.float32))
            torch.manual_seed(seed)
            self.members = nn.ModuleList(
                nn.Sequential(nn.Linear(N_FEATURES, HIDDEN[0]), nn.ReLU(),
                              nn.Linear(HIDDEN[0], HIDDEN[1]), nn.ReLU(),
                              nn.Linear(HIDDEN[1], 1))
                for _ in range(members))

        def forward(self, x: Any) -> Any:
            z = (_transform(x) - self.mean) / self.std
            return torch.stack([m(z)[:, 0] for m in self.members]).mean(dim=0)

    return Scorer()


def counted_from(features: list[list[NDArray[np.float32]]], labels: list[bool],
                 slip_tail: float = SLIP_TAIL) -> list[list[int]]:
    """The first frame of each video (``features[i][j]``) whose score may count towards its
    experiment's in training: :data:`WARMUP`, except in a slip video cut short by its slip
    (shorter than :data:`CUT_SHORT` of the median held video), where only its last
    ``slip_tail`` share counts (``1``: every frame after the warm-up).

    Why: labels say that an experiment slipped, not when. Where the recording was stopped
    because the object fell, the slip is near the end, and the early frames (the grasp
    closing, the lift starting) are not evidence of it; a scorer allowed to explain the label
    with them may learn to fire on events that held grasps show too. On the real GelSight Mini
    grasps, objects held out, ``slip_tail=0.5`` helps committees trained on real grasps alone (8
    scorers at 4 votes, 5 seed sets: balanced accuracy 0.852 -> 0.879, held grasps left alone
    75.8 -> 79.0 of 85), and the marker recipe where only its real-only members use it
    (:data:`MARKER_SLIP_TAIL`); not the markerless recipe (0.770 -> 0.731), nor members that
    also learn rendered grasps, whose slips it then misses (``docs/notes/2026-11-slip.md``).
    """
    if not 0 < slip_tail <= 1:
        raise ValueError(f"slip_tail: must be in (0, 1]; got {slip_tail!r}")
    held = [len(v) for exp, lab in zip(features, labels, strict=True) if not lab for v in exp]
    short = CUT_SHORT * float(np.median(held)) if held else 0.0
    return [[max(WARMUP, math.floor((1 - slip_tail) * len(v))) if lab and len(v) < short
             else WARMUP for v in exp]
            for exp, lab in zip(features, labels, strict=True)]


def train_scorer(features: list[list[NDArray[np.float32]]], labels: list[bool], *,
                 epochs: int = EPOCHS, seed: int = 0, members: int = N_MEMBERS,
                 log: Any = None, starts: list[list[int]] | None = None) -> SlipTrainResult:
    """Trains a scorer on experiments (``features[i]``: one ``T x N_FEATURES`` array per video
    of experiment ``i``; ``labels[i]``: it slipped). Mini-batches of :data:`BATCH` experiments,
    their videos padded to one length and masked. ``starts[i][j]``: the first frame of video
    ``j`` of experiment ``i`` whose score counts (default :data:`WARMUP`;
    :func:`counted_from`); every frame after the warm-up sets the standardisation.
    Deterministic for a seed."""
    import torch

    if len(features) != len(labels) or not features:
        raise ValueError("features: one list of videos per label, at least one experiment")
    y = np.asarray(labels, bool)
    if y.all() or not y.any():
        raise ValueError("labels: training needs both slip and non-slip experiments")
    if starts is not None and [len(s) for s in starts] != [len(e) for e in features]:
        raise ValueError("starts: one first frame per video of features")
    # Small matrices: one thread is fastest, and leaves the other cores to tracking.
    torch.set_num_threads(1)
    videos = [(i, np.asarray(v, np.float32), WARMUP if starts is None else int(starts[i][j]))
              for i, exp in enumerate(features) for j, v in enumerate(exp) if len(v) > WARMUP]
    if not videos:
        raise ValueError("features: no video longer than the warm-up")
    length = max(len(v) for _, v, _ in videos)
    x = torch.zeros(len(videos), length, N_FEATURES)
    mask = torch.zeros(len(videos), length, dtype=torch.bool)
    seen = torch.zeros(len(videos), length, dtype=torch.bool)
    for k, (_, v, first) in enumerate(videos):
        x[k, :len(v)] = torch.from_numpy(v)
        seen[k, WARMUP:len(v)] = True
        mask[k, min(max(first, WARMUP), len(v) - 1):len(v)] = True
    owner = torch.tensor([i for i, _, _ in videos])
    t = _transform(x[seen])
    net = build_scorer(t.mean(0).numpy(), (t.std(0) + 1e-3).numpy(), members, seed)
    opt = torch.optim.Adam(net.parameters(), LEARNING_RATE, weight_decay=WEIGHT_DECAY)
    pos_weight = torch.tensor(float((~y).sum()) / float(y.sum()))
    target = torch.tensor(y, dtype=torch.float32)
    rng = np.random.RandomState(seed)
    exps = np.unique(owner.numpy())
    for epoch in range(epochs):
        total = 0.0
        order = rng.permutation(exps)
        for start in range(0, len(order), BATCH):
            batch = torch.from_numpy(order[start:start + BATCH])
            sel = torch.isin(owner, batch).nonzero()[:, 0]
            score = _experiment_scores(net, x[sel], mask[sel], owner[sel], batch)
            loss = torch.nn.functional.binary_cross_entropy_with_logits(
                score, target[batch], pos_weight=pos_weight)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(batch)
        if log is not None:
            log(f"epoch {epoch + 1}/{epochs}: loss {total / len(exps):.4f}")
    net.eval()
    return SlipTrainResult(net, len(features), int(y.sum()), epochs, seed)


def build_committee(nets: list[Any]) -> Any:
    """The torch committee: ``B x N_FEATURES`` raw features -> ``B x len(nets)`` logits."""
    import torch
    from torch import nn

    class Committee(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.scorers = nn.ModuleList(nets)

        def forward(self, x: Any) -> Any:
            return torch.stack([s(x) for s in self.scorers], dim=1)

    return Committee().eval()


def fused_committee(committee: Any) -> Any:
    """The same function as a committee of :func:`build_committee` (``B x K`` logits), with
    every member's layers stacked into one matrix product, one grouped convolution and one
    product summed over its last axis (one onnxruntime call of a few nodes instead of ``3 K``
    small ones: about 4x faster per frame). Each scorer's input standardisation is folded into
    its first layer (members trained on different experiments standardise differently):
    ``((t - mean) / std) W + b = t (W / std) + (b - (mean / std) W)``."""
    import torch

    scorers = list(committee.scorers)
    mlps = [m for s in scorers for m in s.members]
    w1s, b1s = [], []
    for s in scorers:
        for m in s.members:
            w = m[0].weight.detach().double()                      # H0 x F
            scaled = w / s.std.double()[None, :]
            w1s.append(scaled.float())
            b1s.append((m[0].bias.detach().double() - scaled @ s.mean.double()).float())

    def stack(i: int, part: str) -> Any:
        return torch.stack([getattr(m[i], part).detach() for m in mlps])

    return fused_layers(torch.cat(w1s).t(), torch.cat(b1s), stack(2, "weight"),
                        stack(2, "bias"), stack(4, "weight")[:, 0], stack(4, "bias")[:, 0],
                        len(scorers))


def fused_layers(w1: Any, b1: Any, w2: Any, b2: Any, w3: Any, b3: Any,
                 committee: int) -> Any:
    """The torch module of :func:`fused_committee` from the stacked layers of its ``G``
    MLPs (``committee`` scorers of ``G / committee`` averaged MLPs each): ``w1`` ``F x (G *
    H0)`` and ``b1`` ``G * H0`` (standardisation folded in), ``w2`` ``G x H1 x H0`` and ``b2``
    ``G x H1`` (each MLP's second layer as ``torch.nn.Linear`` stores it), ``w3`` ``G x H1``
    and ``b3`` ``G``. The second layer runs as a convolution of kernel 1 in ``G`` groups and
    the third as a product summed over its last axis: in onnxruntime the call is about 20 %
    faster in a tight loop, and the detector about 10 % inside the slip loop, than with ``G``
    batched matrix products of one row each (2026-12-01, thirty-first stop; the first layer's
    ~3 MB of weights, read once a frame, is most of the rest)."""
    import torch
    from torch import nn

    g, h1, h0 = w2.shape
    if g % committee:
        raise ValueError(f"committee: {committee} scorers cannot share {g} MLPs")

    class Fused(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.register_buffer("w1", w1.float().contiguous())                 # F x (G * H0)
            self.register_buffer("b1", b1.float().reshape(g * h0).contiguous())
            self.register_buffer("w2", w2.float().reshape(g * h1, h0, 1).contiguous())
            self.register_buffer("b2", b2.float().reshape(g * h1).contiguous())
            self.register_buffer("w3", w3.float().reshape(g, h1).contiguous())
            self.register_buffer("b3", b3.float().reshape(g).contiguous())

        def forward(self, x: Any) -> Any:
            b: dict[str, Any] = dict(self.named_buffers())
            h = torch.relu(_transform(x) @ b["w1"] + b["b1"])               # B x (G * H0)
            h = torch.relu(torch.nn.functional.conv1d(h[:, :, None], b["w2"], b["b2"],
                                                      groups=g))           # B x (G * H1) x 1
            out = (h.reshape(-1, g, h1) * b["w3"]).sum(dim=2) + b["b3"]     # B x G
            return out.reshape(-1, committee, g // committee).mean(dim=2)

    return Fused().eval()


def default_votes(seeds: int) -> int:
    """:data:`VOTE_FRACTION` of ``seeds`` members, rounded up."""
    return math.ceil(VOTE_FRACTION * int(seeds))


#: Votes of the shipped marker committee.
VOTES = default_votes(COMMITTEE)


def recipe_committee(markerless: bool = False) -> int:
    """Scorers in the recipe's committee: :data:`COMMITTEE` for marker tracks,
    :data:`MARKERLESS_COMMITTEE` for markerless ones."""
    return MARKERLESS_COMMITTEE if markerless else COMMITTEE


def recipe_slip_tail(markerless: bool = False) -> float:
    """The recipe's ``slip_tail`` (:func:`train_committee`): :data:`MARKER_SLIP_TAIL` for marker
    tracks, :data:`SLIP_TAIL` (every frame) for markerless ones."""
    return float(SLIP_TAIL if markerless else MARKER_SLIP_TAIL)


def default_committee_text(markerless_label: str) -> str:
    """The recipe's committee size for help texts: ``"32"``, or ``"32, <label> 8"`` while the
    markerless recipe differs (``markerless_label`` names it, e.g. ``"with --markerless"``)."""
    return f"{COMMITTEE}" + ("" if MARKERLESS_COMMITTEE == COMMITTEE
                             else f", {markerless_label} {MARKERLESS_COMMITTEE}")


def committee_votes(seeds: int, votes: int | None = None) -> int:
    """The votes of a committee of ``seeds`` scorers: ``votes``, checked, or
    :func:`default_votes`."""
    v = default_votes(seeds) if votes is None else int(votes)
    if not 1 <= v <= seeds:
        raise ValueError(f"votes: must be in [1, seeds={seeds}]; got {votes}")
    return v


def half_votes(seeds: int, real_only: int) -> int:
    """Votes of the members trained with the rendered grasps (those after the first
    ``real_only`` of ``seeds``) that flag a grasp without the others: :data:`HALF_VOTE_FRACTION`
    of them, rounded up; 0 (no such vote) when no member trained alone or none with them."""
    rest = int(seeds) - int(real_only)
    return math.ceil(HALF_VOTE_FRACTION * rest) if real_only > 0 and rest > 0 else 0


def real_only_members(seeds: int, extra: bool) -> int:
    """Members of a committee of ``seeds`` trained without the ``extra`` (rendered) experiments:
    :data:`REAL_ONLY_FRACTION` of them, rounded down, when there are extra experiments (none
    for a single scorer), else 0."""
    return math.floor(REAL_ONLY_FRACTION * int(seeds)) if extra and seeds > 1 else 0


def train_committee(features: list[list[NDArray[np.float32]]], labels: list[bool], *,
                    seed: int = 0, seeds: int = COMMITTEE, votes: int | None = None,
                    epochs: int | None = None, log: Any = None,
                    extra: tuple[list[list[NDArray[np.float32]]], list[bool]] | None = None,
                    real_only: int | None = None,
                    slip_tail: float = SLIP_TAIL) -> SlipTrainResult:
    """Trains ``seeds`` scorers (:func:`train_scorer`, seeds ``seed, seed + 1, ...``) and returns
    them as one committee (``net``: ``B x seeds`` logits) that flags a grasp once ``votes``
    members (default :func:`default_votes`, at most ``seeds``) have fired in it. With
    ``seeds=1``: the single scorer (``B`` logits), one vote. ``epochs``: default
    :data:`EPOCHS`.

    ``extra`` (features, labels): experiments of another kind (the rendered grasps) that join the
    training set of every member but the first ``real_only`` (default
    :func:`real_only_members`). Those train on ``features`` alone: on the real grasps they
    decide better, and only the others know the rendered grasps' textbook slip, so the
    committee needs both (``docs/notes/2026-11-slip.md``).

    ``slip_tail``: in ``features``' slip videos cut short by their slip, the share from the end
    that may carry the score (:func:`counted_from`; 1: every frame; the recipes' is
    :func:`recipe_slip_tail`), for the members trained on ``features`` alone (every member
    without ``extra``). Members that also learn ``extra`` count every frame of both: with the
    tail they learn the rendered grasps' slip too weakly to flag it (12 of the 13 votes a
    held-out rendered slip needs, notes), and rendered clips are not cut by their slip."""
    if not 1 <= seeds <= 100:
        raise ValueError(f"seeds: must be in [1, 100]; got {seeds}")
    v = committee_votes(seeds, votes)
    epochs = EPOCHS if epochs is None else epochs
    extra_feats, extra_labels = (list(extra[0]), list(extra[1])) if extra else ([], [])
    if len(extra_feats) != len(extra_labels):
        raise ValueError("extra: one list of videos per label")
    n_real = (real_only_members(seeds, bool(extra_feats)) if real_only is None
              else int(real_only))
    if not 0 <= n_real <= seeds:
        raise ValueError(f"real_only: must be in [0, seeds={seeds}]; got {real_only}")
    starts = counted_from(features, labels, slip_tail)
    every = [[WARMUP] * len(exp) for exp in features + extra_feats]
    # The share the file records: what its members used (none does when all learn ``extra``).
    used = float(slip_tail) if n_real or not extra_feats else 1.0
    results = []
    for s in range(seed, seed + seeds):
        alone = s - seed < n_real
        if log is not None and seeds > 1:
            log(f"scorer {s - seed + 1}/{seeds} (seed {s}"
                f"{', real grasps only' if alone and extra_feats else ''})")
        feats, labs, firsts = ((features, labels, starts) if alone or not extra_feats
                               else (features + extra_feats, list(labels) + extra_labels,
                                     every))
        results.append(train_scorer(feats, labs, epochs=epochs, seed=s, log=log,
                                    starts=firsts))
    if seeds == 1:
        return replace(results[0], slip_tail=used)
    full = max(results, key=lambda r: r.n_experiments)  # with ``extra`` when any member saw it
    n_alone = n_real if extra_feats else 0
    return SlipTrainResult(build_committee([r.net for r in results]), full.n_experiments,
                           full.n_slip, epochs, seed, committee=seeds, votes=v,
                           slip_tail=used, real_only=n_alone,
                           half_votes=half_votes(seeds, n_alone))


def _experiment_scores(net: Any, x: Any, mask: Any, owner: Any, batch: Any) -> Any:
    """Largest frame logit of each experiment in ``batch`` over its videos' masked frames."""
    import torch

    v, t, f = x.shape
    logits = net(x.reshape(v * t, f)).reshape(v, t).masked_fill(~mask, float("-inf"))
    per_video = logits.max(dim=1).values
    slot = torch.searchsorted(batch.sort().values, owner)
    out = torch.full((len(batch),), float("-inf")).scatter_reduce(
        0, slot, per_video, reduce="amax")
    # Back to the order of ``batch`` (the slots follow its sorted order).
    return out[torch.argsort(torch.argsort(batch))]


def frame_scores(net: Any, features: NDArray[np.float32]) -> NDArray[np.float32]:
    """Per-frame logits of one video with a torch scorer (no gradient): ``T``, or ``T x K`` for
    a committee of ``K``."""
    import torch

    with torch.no_grad():
        return net(torch.tensor(np.asarray(features, np.float32))).numpy()


def export_scorer(result: SlipTrainResult, path: str | os.PathLike[str],
                  threshold: float = 0.0, extra: dict[str, object] | None = None, *,
                  still_filter: bool = False, motion: str = "markers") -> None:
    """Writes the scorer as ONNX (input ``features`` ``B x N_FEATURES`` float32, output
    ``logit`` ``B``, or ``B x K`` for a committee of ``K``) with its decision threshold, votes
    and training summary as metadata; ``still_filter``: its features were read through the
    still-marker hysteresis (the detector then reads them so too); ``motion``: what it learned
    from, ``"markers"`` (tracked) or ``"markerless"`` (predicted motion, perhaps with marker
    tracks beside it), so that a run on the other kind of stream can say so."""
    if motion not in SCORER_MOTIONS:
        raise ValueError(f"motion: one of {SCORER_MOTIONS}; got {motion!r}")
    import tempfile
    from pathlib import Path

    import torch

    from tacswitch._io import write_onnx
    from tacswitch.grasp.detector import SCORER_FRAME_TO_FRAME
    from tacswitch.grasp.features import FRAME_FEATURES, LONG, SNAP_FEATURES, WINDOW
    from tacswitch.grasp.timebase import TRAINED_FPS

    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir) / "slip.onnx"
        net = fused_committee(result.net) if result.committee > 1 else result.net
        torch.onnx.export(net, (torch.zeros(2, N_FEATURES),), str(tmp),
                          input_names=["features"], output_names=["logit"],
                          dynamic_axes={"features": {0: "frames"}, "logit": {0: "frames"}},
                          opset_version=17, dynamo=False)
        meta = {"tacswitch.kind": "slip"}
        info: dict[str, object] = {
            "threshold": float(threshold), "warmup": WARMUP, "window": WINDOW, "long": LONG,
            "frame_features": list(FRAME_FEATURES), "snap_features": list(SNAP_FEATURES),
            "n_features": N_FEATURES,
            "experiments": result.n_experiments, "slip_experiments": result.n_slip,
            "epochs": result.epochs, "seed": result.seed, "committee": result.committee,
            "votes": result.votes, "real_only": result.real_only,
            "half_votes": result.half_votes, "slip_tail": result.slip_tail, "cut_short": CUT_SHORT,
            "fps": TRAINED_FPS, "still_filter": bool(still_filter),
            "motion": motion,
            "frame_to_frame": SCORER_FRAME_TO_FRAME if motion == "markerless" else 0.0,
        }
        info.update(extra or {})
        write_onnx(tmp, path, meta, info)
