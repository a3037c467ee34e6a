"""The grasp slip detector: grasp phases, and slip by a learned scorer or by the paper's rule.

:class:`GraspSlipDetector` is what ``tacswitch slip`` runs on every frame. It follows the grasp
(:class:`tacswitch.grasp.phases.GraspSegmenter`: contact onset, established contact, release)
and decides slip with one of two rules:

- ``"learned"`` (default): a committee of small classifiers over causal features of the tracked
  field (:mod:`tacswitch.grasp.features`), trained on real GelSight Mini grasps that were lifted
  and shaken, some slipping (``MODEL_CARD_slip.md``). Each member that scores a frame above the
  threshold has fired for the rest of that contact; slip is flagged once ``votes`` members have
  fired, on the frames where one fires. It runs only while the markers show a contact (from
  the onset to the release); nothing is flagged before the onset or after the release.
- ``"paper"``: the paper's displacement rule from the grasp start, optionally with the rigid
  criterion (:class:`tacswitch.SlipDetector`).

Elastic shear and rotation of a firmly held, shaken object move the markers as far as a slip
does (7-24 px on real Mini grasps against the rule's 1.6 px), so the displacement rule calls most
shaken grasps slipping; the learned rule reads how the field moves over time instead.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_count, as_motion, as_number, as_points, as_valid
from tacswitch.grasp.features import N_BASE_FEATURES, N_FEATURES, FieldFeatures, marker_pitch
from tacswitch.grasp.phases import GRASP, PRESSING, GraspSegmenter, Step
from tacswitch.grasp.timebase import TRAINED_FPS, TimeBase, check_fps, needs_resampling

#: The shipped scorers (``python/tacswitch/models``): trained on tracked markers, and on the
#: motion ``MarkerlessTracker`` predicts once the markers are removed from the same videos.
SHIPPED_SLIP_MODELS = {"markers": "slip_scorer.onnx", "markerless": "slip_scorer_markerless.onnx"}
DEFAULT_SLIP_MODEL = SHIPPED_SLIP_MODELS["markers"]
#: The DIS preset (:data:`tacswitch.motion.flow.DIS_PRESETS`) of the markerless motion the
#: shipped markerless scorer was trained on (``MarkerlessTracker``'s plain flow; ``refined``,
#: its default, since 2026-11-30, ``balanced`` before): the slip paths keep it, and training on
#: markerless videos uses it too, so a scorer reads what it learned.
SCORER_FLOW_PRESET = "refined"
#: How the markers were removed from the marker videos the markerless scorer learned from
#: (:func:`tacswitch.remove_markers` keywords; the removal the motion guide recommends: a mask
#: grown five steps and a wider fill leave fewer seams for the flow to follow).
SCORER_REMOVAL: dict[str, int] = {"dilate": 5, "radius": 5}
#: The weight of ``MarkerlessTracker``'s frame-to-frame path (``frame_to_frame``) in the
#: markerless motion the shipped markerless scorer was trained on (since 2026-12-01; 0 before):
#: the increment steadies the velocities its features read (on the real Mini videos their error
#: against the tracked markers falls from 0.95 to 0.48 px RMS a frame). Scorer files record it
#: (``tacswitch.frame_to_frame``; files without it: 0), and the slip paths follow the file.
SCORER_FRAME_TO_FRAME = 0.8
#: :data:`SCORER_REMOVAL` as a call writes it (``"dilate=5, radius=5"``), for help and reports.
SCORER_REMOVAL_TEXT = ", ".join(f"{k}={v}" for k, v in SCORER_REMOVAL.items())
RULES = ("learned", "paper")

Scorer = Callable[[NDArray[np.float32]], NDArray[np.float32]]


def slip_model_path(path: str | os.PathLike[str] | None = None) -> Path:
    """The scorer file: ``path``, a shipped model's name (``"markers"``, ``"markerless"``),
    else the shipped marker scorer."""
    name = SHIPPED_SLIP_MODELS.get(str(path)) if path is not None else DEFAULT_SLIP_MODEL
    if name is None:
        return Path(path)  # type: ignore[arg-type]
    return Path(__file__).resolve().parent.parent / "models" / name


class OnnxScorer:
    """A slip scorer exported by ``tacswitch train slip``: ``B x N_FEATURES`` -> ``B`` logits,
    or ``B x K`` for a committee of ``K`` (``committee``; ``votes``: members that must fire),
    run on one onnxruntime thread (the slip loop is single-threaded), on the CPU by default:
    one frame's features are a few hundred bytes, which a GPU round trip would only slow."""

    def __init__(self, path: Path, device: str = "cpu") -> None:
        import json

        from tacswitch._ort import open_session

        self.session, meta = open_session(path, threads=1, kind="slip", device=device)
        self.path = path

        def value(key: str, default: str, kind: type) -> Any:
            """Metadata ``tacswitch.<key>`` as ``kind``; ``ValueError`` naming the model."""
            text = meta.get(f"tacswitch.{key}", default)
            try:
                return kind(json.loads(text))
            except (ValueError, TypeError):
                raise ValueError(f"model: {str(path)!r}: metadata tacswitch.{key} is not a "
                                 f"{kind.__name__} ({text[:40]!r}); re-export it with "
                                 "`tacswitch train slip`") from None

        self.threshold = value("threshold", "0", float)
        self.warmup = value("warmup", "3", int)
        self.committee = value("committee", "1", int)
        self.votes = value("votes", "1", int)
        # The members after the first ``real_only`` (trained with rendered grasps too) also flag
        # on ``half_votes`` of their own (files before these keys, or 0: no such vote).
        real_only = value("real_only", "0", int)
        half = value("half_votes", "0", int)
        self.half_vote: tuple[int, int] | None = (real_only, half) if half > 0 else None
        # Whether its features read tracked markers through the still-marker hysteresis
        # (:class:`~tacswitch.grasp.features.FieldFeatures`; files before this key: no).
        self.still_filter = value("still_filter", "false", bool)
        # The frame rate its features were computed at (files before this key: 25 frames/s).
        self.fps = value("fps", str(TRAINED_FPS), float)
        # The frame-to-frame weight of the markerless motion it learned from (files before this
        # key, and marker scorers: 0).
        self.frame_to_frame = value("frame_to_frame", "0", float)
        # "markers" or "markerless": what its features came from (files before this key: None).
        self.motion: str | None = meta.get("tacswitch.motion")
        n = value("n_features", str(N_FEATURES), int)
        # A scorer trained before the snap-back features reads the vector's first values.
        if n not in (N_FEATURES, N_BASE_FEATURES):
            raise ValueError(f"model: {str(path)!r} takes {n} features; this tacswitch "
                             f"computes {N_FEATURES} (retrain it with `tacswitch train slip`)")
        self.n_features = n

    def __call__(self, features: NDArray[np.float32]) -> NDArray[np.float32]:
        x = np.asarray(features, np.float32).reshape(-1, N_FEATURES)[:, :self.n_features]
        return self.session.run(  # type: ignore[no-any-return]
            None, {"features": np.ascontiguousarray(x)})[0]


def load_scorer(path: str | os.PathLike[str] | None = None) -> OnnxScorer:
    """The cached :class:`OnnxScorer` of ``path`` (default: the shipped model)."""
    from tacswitch._ort import cached

    return cached(OnnxScorer, slip_model_path(path), "cpu")


def scorer_frame_to_frame(model: Any) -> float:
    """The frame-to-frame weight (``MarkerlessTracker(frame_to_frame=...)``) of the motion the
    scorer ``model`` learned from, ``model`` as :class:`GraspSlipDetector` takes it: a path or a
    shipped name (read from its file), a loaded :class:`OnnxScorer`, or a plain callable (which
    records none: 0)."""
    if isinstance(model, OnnxScorer):
        return model.frame_to_frame
    if callable(model) and not isinstance(model, (str, os.PathLike)):
        return 0.0
    return load_scorer(model).frame_to_frame


def check_half_vote(half_vote: Any, committee: int | None) -> tuple[int, int] | None:
    """``half_vote`` as ``(first, votes)`` (or None); ``ValueError`` naming it unless both are
    ints with ``first >= 1`` and ``1 <= votes <= committee - first`` (None: not known yet)."""
    if half_vote is None:
        return None
    try:
        first, votes = half_vote
    except (TypeError, ValueError):
        raise ValueError(f"half_vote: expected (first member, votes); got {half_vote!r}") from None
    if any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in (first, votes)):
        raise ValueError(f"half_vote: expected two ints; got {half_vote!r}")
    top = None if committee is None else int(committee) - int(first)
    if first < 1 or votes < 1 or (top is not None and votes > top):
        raise ValueError(f"half_vote: needs first >= 1 and 1 <= votes <= the committee's "
                         f"members from first on; got {half_vote!r}"
                         + ("" if committee is None else f" for a committee of {committee}"))
    return int(first), int(votes)


def check_votes(votes: int, committee: int | None) -> None:
    """``ValueError`` naming ``votes`` unless 1 <= ``votes`` <= ``committee`` (the scorer's
    members; None: not known yet)."""
    if votes < 1 or (committee is not None and votes > committee):
        top = "" if committee is None else f", at most the committee's {committee} members"
        raise ValueError(f"votes: must be >= 1{top}; got {votes}")


@dataclass(frozen=True)
class GraspSlipState:
    """What :meth:`GraspSlipDetector.update` concluded for one frame.

    Attributes:
        frame: frame index (0 = the first frame fed).
        phase: ``"no contact"``, ``"pressing"``, ``"grasp"`` or ``"before start"``.
        grasp: 1-based number of the current grasp, 0 before the first.
        grasp_start: frame where the current grasp started, None outside a grasp.
        slip: slip in this frame.
        score: the learned rule's logit, the mean over a committee's members (NaN when it did
            not run: other rule, warm-up, or outside a contact).
        criterion: ``"learned"``, ``"displacement"``, ``"rigid"``, ``"both"`` or None.
        max_displacement: largest marker displacement since the grasp start, px (paper rule;
            NaN with the learned rule).
        marker: index of that marker, -1 if none.
        rigid_residual: the rigid criterion's residual, px (NaN when not evaluated).
        n_valid: markers tracked in this frame.
        votes: learned rule: committee members that have fired in this grasp so far (0 with
            the paper rule).
    """

    frame: int
    phase: str
    grasp: int
    grasp_start: int | None
    slip: bool
    score: float
    criterion: str | None
    max_displacement: float
    marker: int
    rigid_residual: float
    n_valid: int
    votes: int = 0


class GraspSlipDetector:
    """Online slip detection over a recording of grasps, one motion field per frame.

    Feed :meth:`update` the motion of every reference marker since the first frame of the
    recording (from :class:`tacswitch.MarkerTracker`, or predicted on a markerless sensor).

    Args:
        points: ``N x 2`` reference marker centres ``(x, y)``, pixels.
        image_width: frame width, pixels (scales the contact levels and the paper's threshold;
            default: estimated from the markers' extent).
        rule: ``"learned"`` (default) or ``"paper"``.
        model: ONNX scorer for the learned rule: a path, ``"markers"`` (the default, for
            tracked markers) or ``"markerless"`` (for motion predicted on a markerless sensor),
            an :class:`OnnxScorer` (:func:`load_scorer`; read as its file is), or a callable ``B x
            N_FEATURES`` -> ``B`` logits (``B x K`` for a committee).
        threshold: the learned rule's logit threshold, per member (default: the model's).
        votes: the learned rule: committee members that must have fired in a grasp before it
            is flagged (default: the model's; 1 for a callable). Fewer: earlier and more
            detections, more false alarms.
        half_vote: the learned rule: ``(first, votes)``, a grasp is also flagged once ``votes``
            of the members from index ``first`` on have fired (the shipped marker committee's
            members trained with rendered grasps too, which alone know their textbook slip).
            Default: the model's (none for a callable or a file without one).
        threshold_px: the paper rule's displacement threshold (default 3.25 px at 640 wide,
            scaled to ``image_width``).
        rigid_threshold_px: the paper rule's rigid criterion (pixels or ``"auto"``).
        rigid_only: the paper rule with the rigid criterion alone.
        smooth_frames: the paper rule on the mean motion of the last frames (markerless input).
        start: an explicit grasp start (frame index) instead of the detected one.
        fps: the stream's frame rate, frames/s (default: taken to be the scorer's, 25 for the
            shipped ones). A stream faster than 1.25x that is resampled to the scorer's rate
            (:class:`tacswitch.grasp.timebase.TimeBase`), so velocities and the phases' frame
            counts mean what they meant in training; states stay one per fed frame. A slower
            one is read frame by frame (:func:`~tacswitch.grasp.timebase.needs_resampling`).
        still_filter: the learned rule reads the motion through the still-marker hysteresis
            (:class:`~tacswitch.grasp.features.FieldFeatures`: still markers stay exactly still
            under camera noise). Default: as the ONNX scorer was trained (on for the shipped
            marker scorer, off for the markerless one); off for a callable.
        first_frame_rest: the first frame fed shows the gel at rest whatever motion it
            carries: the contact phases read every field minus the first
            (:class:`~tacswitch.grasp.phases.GraspSegmenter`). For the motion of a
            :class:`tacswitch.MarkerlessTracker` started without a no-contact frame (its first
            frame gets the mechanics rule's motion), as ``tacswitch slip --markerless`` runs
            it without ``--ref``. The scorer's features are unchanged.
    """

    def __init__(self, points: Any, *, image_width: int | None = None, rule: str = "learned",
                 model: str | os.PathLike[str] | Scorer | None = None,
                 threshold: float | None = None, votes: int | None = None,
                 threshold_px: float | None = None,
                 rigid_threshold_px: float | str | None = None, rigid_only: bool = False,
                 smooth_frames: int = 1, start: int | None = None,
                 fps: float | None = None, still_filter: bool | None = None,
                 half_vote: tuple[int, int] | None = None,
                 first_frame_rest: bool = False) -> None:
        from tacswitch.slip import SlipDetector, scaled_threshold

        if rule not in RULES:
            raise ValueError(f"rule: one of {RULES}; got {rule!r}")
        self.fps = check_fps(fps)
        self.points = as_points(points, "points")
        if image_width is None:
            xs = self.points[:, 0]
            image_width = max(1, round(float(xs.max() + xs.min()))) if len(xs) else 640
        self.image_width = as_count(image_width, "image_width", 1)
        self.rule = rule
        if threshold_px is not None:
            threshold_px = as_number(threshold_px, "threshold_px")
            if not threshold_px > 0:
                raise ValueError(f"threshold_px: must be > 0; got {threshold_px!r}")
        if start is not None:
            start = as_count(start, "start", 0)
        smooth_frames = as_count(smooth_frames, "smooth_frames", 1)
        epsilon = float(threshold_px) if threshold_px else scaled_threshold(self.image_width)
        self.frame = -1
        self.tick = -1
        self.first_slip: int | None = None
        self._paper: SlipDetector | None = None
        self._features: FieldFeatures | None = None
        self._scorer: Scorer | None = None
        self.threshold = 0.0
        self.warmup = 3
        self.votes = 1
        self.half_vote: tuple[int, int] | None = None
        self._committee: int | None = None
        self._fired: NDArray[np.bool_] | None = None
        #: The time base's rate (frames/s): the scorer's; the paper rule's phases, 25.
        self.model_fps = TRAINED_FPS
        self.still_filter = False
        if rule == "paper":
            if votes is not None:
                raise ValueError("votes: applies to rule='learned' only")
            if half_vote is not None:
                raise ValueError("half_vote: applies to rule='learned' only")
            if still_filter is not None:
                raise ValueError("still_filter: applies to rule='learned' only")
            if rigid_only and rigid_threshold_px is None:
                raise ValueError("rigid_only: True needs rigid_threshold_px (a number of pixels "
                                 "or 'auto'), or nothing is checked")
            self._paper = SlipDetector(epsilon, rigid_threshold_px=rigid_threshold_px,
                                       use_displacement=not rigid_only, points=self.points,
                                       image_width=self.image_width,
                                       smooth_frames=smooth_frames)
        else:
            if rigid_threshold_px is not None or rigid_only:
                raise ValueError("rigid_threshold_px: applies to rule='paper' only")
            if smooth_frames != 1:
                raise ValueError("smooth_frames: applies to rule='paper' only")
            self.pitch = marker_pitch(self.points)
            if (callable(model) and not isinstance(model, (str, os.PathLike))
                    and not isinstance(model, OnnxScorer)):
                self._scorer = model
            else:
                # A loaded file brings its threshold, votes and filter, as its path would.
                onnx = model if isinstance(model, OnnxScorer) else load_scorer(model)
                self._scorer = onnx
                self.threshold, self.warmup = onnx.threshold, onnx.warmup
                self.votes, self._committee = onnx.votes, onnx.committee
                self.half_vote = onnx.half_vote
                self.model_fps = onnx.fps
                self.still_filter = onnx.still_filter
            if still_filter is not None:
                if not isinstance(still_filter, (bool, np.bool_)):
                    raise TypeError("still_filter: expected a bool; got "
                                    f"{type(still_filter).__name__}")
                self.still_filter = bool(still_filter)
            self._features = FieldFeatures(self.points, self.pitch, self.still_filter)
            if threshold is not None:
                self.threshold = as_number(threshold, "threshold")
            if votes is not None:
                if isinstance(votes, bool) or not isinstance(votes, (int, np.integer)):
                    raise TypeError(f"votes: expected an int; got {type(votes).__name__}")
                self.votes = int(votes)
            check_votes(self.votes, self._committee)
            if half_vote is not None:
                self.half_vote = check_half_vote(half_vote, self._committee)
        self.timebase = (TimeBase(self.fps, self.model_fps)
                         if self.fps is not None and needs_resampling(self.fps, self.model_fps)
                         else None)
        if start is not None and self.timebase is not None:
            # The first tick at or after the frame asked for (never an earlier one).
            start = math.ceil(start * self.timebase.ratio - 1e-9)
        self.segmenter = GraspSegmenter(epsilon, start=start,
                                        first_frame_rest=first_frame_rest)
        self._last: GraspSlipState | None = None

    def update(self, motion: Any, valid: Any = None) -> GraspSlipState:
        """Feeds the next frame's motion (``N x 2`` px since the first frame; NaN = lost) and
        its ``N`` valid flags (default: rows without NaN); returns its state."""
        m = as_motion(motion, "motion")
        if len(m) != len(self.points):
            raise ValueError(f"motion: expected {len(self.points)} rows (one per reference "
                             f"marker); got {len(m)}")
        v: NDArray[np.bool_] = (np.asarray(~np.isnan(m).any(axis=1)) if valid is None
                                else as_valid(valid, len(m)))
        self.frame += 1
        if self.timebase is None:
            state = self._tick(m, v)
        else:
            state = self._merge([self._tick(tm, tv)
                                 for _, tm, tv in self.timebase.push(m, v)], int(v.sum()))
        if state.slip and self.first_slip is None:
            self.first_slip = self.frame
        return state

    def _merge(self, ticks: list[GraspSlipState], n_valid: int) -> GraspSlipState:
        """One fed frame's state from the time base's ticks since the previous one: the
        last tick's phase and votes, slip if any tick flagged (then that tick's score), frame
        numbers in fed frames. No tick (a stream faster than the time base): the last tick's
        state holds, as the detector has seen nothing new."""
        assert self.timebase is not None
        tb = self.timebase
        if ticks:
            flagged = [t for t in ticks if t.slip]
            base = flagged[-1] if flagged else ticks[-1]
            self._last = replace(base, phase=ticks[-1].phase, grasp=ticks[-1].grasp,
                                 grasp_start=ticks[-1].grasp_start, votes=ticks[-1].votes)
            state = self._last
        else:
            assert self._last is not None  # frame 0 is always a tick
            state = self._last
        start = None if state.grasp_start is None else tb.frame_of(state.grasp_start)
        return replace(state, frame=self.frame, grasp_start=start, n_valid=n_valid)

    def _logits(self, feats: NDArray[np.float32]) -> NDArray[np.float64]:
        """The scorer's logits for one frame's features: one per committee member, checked
        (a user's callable may return anything): ``ValueError`` naming ``model``."""
        assert self._scorer is not None
        out = self._scorer(feats[None, :])  # its own errors stay its own, traceback and all
        try:
            logits = np.asarray(out, np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"model: the scorer's output is not numbers ({exc})") from None
        if len(logits) == 0 or (self._fired is not None and len(logits) != len(self._fired)):
            raise ValueError(f"model: the scorer returned {len(logits)} logits; expected "
                             f"{'at least 1' if self._fired is None else len(self._fired)} "
                             "(one per committee member, every frame)")
        if not np.isfinite(logits).all():
            raise ValueError("model: the scorer returned a logit that is not finite")
        return logits

    def _tick(self, m: NDArray[np.float32], v: NDArray[np.bool_]) -> GraspSlipState:
        """One step of the time base (a fed frame at the scorer's rate)."""
        self.tick += 1
        step = self.segmenter.update(m, v)
        if self._paper is not None:
            return self._paper_step(step, m, v)
        assert self._features is not None and self._scorer is not None
        feats = self._features.update(m, v)
        score = float("nan")
        contact = step.phase in (PRESSING, GRASP)
        if not contact:
            self._fired = None  # released: the next contact starts with no votes
        slip = False
        if contact and self.tick >= self.warmup:
            # The scene decides: the scorer runs only while a contact is on the gel.
            logits = self._logits(feats)
            if self._fired is None:
                check_votes(self.votes, len(logits))
                check_half_vote(self.half_vote, len(logits))
                self._fired = np.zeros(len(logits), bool)
            above = logits > self.threshold
            self._fired |= above
            score = float(logits.mean())
            slip = bool(above.any()) and (
                int(self._fired.sum()) >= self.votes
                or (self.half_vote is not None
                    and int(self._fired[self.half_vote[0]:].sum()) >= self.half_vote[1]))
        fired = 0 if self._fired is None else int(self._fired.sum())
        return GraspSlipState(self.tick, step.phase, step.grasp, step.start, slip, score,
                              "learned" if slip else None, float("nan"), -1, float("nan"),
                              int(v.sum()), fired)

    def _paper_step(self, step: Step, m: NDArray[np.float32], v: NDArray[np.bool_]
                    ) -> GraspSlipState:
        assert self._paper is not None
        if step.starts:
            self._paper.reset()
        if step.phase != GRASP:
            return GraspSlipState(self.tick, step.phase, step.grasp, step.start, False,
                                  float("nan"), None, float("nan"), -1, float("nan"),
                                  int(v.sum()))
        st = self._paper.update(m, v)
        return GraspSlipState(self.tick, step.phase, step.grasp, step.start, st.slip,
                              float("nan"), st.criterion, st.max_displacement, st.marker,
                              st.rigid_residual, int(v.sum()))


def run_clip(motions: NDArray[np.floating], valids: NDArray[np.bool_], points: Any, *,
             image_width: int | None = None, **options: Any) -> list[GraspSlipState]:
    """A :class:`GraspSlipDetector` over a whole tracked clip (``T x N x 2`` motions since the
    first frame, ``T x N`` valid): the states of every frame, as the online loop sees them."""
    det = GraspSlipDetector(points, image_width=image_width, **options)
    return [det.update(m, v) for m, v in zip(motions, valids, strict=True)]
