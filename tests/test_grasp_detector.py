"""The grasp slip detector: phase gating (nothing before the contact onset or after the release),
the shipped scorer, folds grouped by object, experiment scores and training/export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import tacswitch as ts
from tacswitch import sim
from tacswitch.grasp.detector import GraspSlipDetector, load_scorer, run_clip
from tacswitch.grasp.evaluate import object_folds, score_experiments
from tacswitch.grasp.features import N_BASE_FEATURES, N_FEATURES
from tacswitch.grasp.phases import GRASP, NO_CONTACT, PRESSING, Step

LEAD = 4


def press_recording(seed: int) -> list[np.ndarray]:
    """Simulated GelSight Mini: no contact, press and shear, hold, release, no contact."""
    seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=24, seed=seed)
    return ([seq.reference] * LEAD + list(seq.frames) + list(seq.frames[: seq.grasp_start][::-1])
            + [seq.reference] * 4)


def tracked(frames: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tr = ts.MarkerTracker(frames[0])
    out = [tr.update(f) for f in frames]
    return (np.stack([m for m, _ in out]), np.stack([v for _, v in out]), tr.reference)


class Recorder:
    """A scorer that always says slip and records the frames it ran on."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        assert x.shape == (1, N_FEATURES) and x.dtype == np.float32
        self.calls += 1
        return np.full(len(x), 5.0, np.float32)


@pytest.mark.parametrize("seed", [4, 7])
def test_scorer_runs_only_between_contact_onset_and_release(seed: int) -> None:
    frames = press_recording(seed)
    motion, valid, pts = tracked(frames)
    rec = Recorder()
    states = run_clip(motion, valid, pts, image_width=frames[0].shape[1], model=rec,
                      threshold=0.0)
    phases = [s.phase for s in states]
    assert phases[:LEAD] == [NO_CONTACT] * LEAD and phases[-1] == NO_CONTACT
    assert PRESSING in phases and GRASP in phases
    for s in states:
        # An always-slip scorer flags exactly the contact frames: the gate is the phase.
        assert s.slip == (s.phase in (PRESSING, GRASP) and s.frame >= 3), s
        assert (s.score == s.score) == s.slip
    assert rec.calls == sum(s.slip for s in states)
    released = max(i for i, p in enumerate(phases) if p != NO_CONTACT) + 1
    assert not any(s.slip for s in states[released:])


@pytest.mark.parametrize("seed", [4, 7])
def test_a_recording_that_starts_in_contact_is_scored_from_its_first_frame_with_start_0(
        seed: int) -> None:
    # Tracked from a frame of the hold: the gel is loaded at frame 0. Its release moves the
    # markers back to rest, which the detected phases read as a press; start=0 scores the grasp
    # from the first frame on (the advice of docs/slip.md, measured in bench_slip_incontact.py).
    seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=24, seed=seed)
    frames = list(seq.frames[seq.grasp_start:]) + [seq.reference] * 4
    motion, valid, pts = tracked(frames)
    width = frames[0].shape[1]
    detected = run_clip(motion, valid, pts, image_width=width, model=Recorder(), threshold=0.0)
    assert detected[0].phase == NO_CONTACT  # no onset to see: the loaded frame reads as rest
    rec = Recorder()
    given_start = run_clip(motion, valid, pts, image_width=width, model=rec, threshold=0.0,
                           start=0)
    assert [s.phase for s in given_start] == [GRASP] * len(frames)
    assert all(s.grasp_start == 0 for s in given_start)
    assert rec.calls == len(frames) - 3  # every frame after the scorer's warm-up
    assert [s.slip for s in given_start] == [s.frame >= 3 for s in given_start]


def _linear_scorer(path: Path, n_features: int) -> Path:
    """A one-member ONNX slip scorer (``features`` ``B x n_features`` -> ``logit`` ``B x 1``,
    a random linear map) with the metadata ``tacswitch train slip`` writes."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    w = np.random.default_rng(1).normal(0, 1, (n_features, 1)).astype(np.float32)
    graph = helper.make_graph(
        [helper.make_node("MatMul", ["features", "w"], ["logit"])], "scorer",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, ["B", n_features])],
        [helper.make_tensor_value_info("logit", TensorProto.FLOAT, ["B", 1])],
        [numpy_helper.from_array(w, "w")])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    for key, value in (("kind", "slip"), ("n_features", str(n_features))):
        entry = model.metadata_props.add()
        entry.key, entry.value = f"tacswitch.{key}", value
    onnx.save(model, str(path))
    return path


@pytest.mark.parametrize("n", [N_BASE_FEATURES, N_FEATURES])
def test_a_scorer_of_the_base_layout_reads_only_its_prefix(n: int, tmp_path: Path) -> None:
    """Scorers trained before the snap-back features take the first N_BASE_FEATURES values;
    the values after them must not reach such a scorer, and must reach one of the full layout."""
    pytest.importorskip("onnx")
    scorer = load_scorer(_linear_scorer(tmp_path / f"scorer{n}.onnx", n))
    assert scorer.n_features == n
    rng = np.random.default_rng(0)
    x = rng.normal(0, 1, (4, N_FEATURES)).astype(np.float32)
    y = x.copy()
    y[:, N_BASE_FEATURES:] += 5.0
    same = np.allclose(scorer(x), scorer(y))
    assert same == (n == N_BASE_FEATURES)
    z = x.copy()
    z[:, :N_BASE_FEATURES] += 5.0
    assert not np.allclose(scorer(x), scorer(z))


@pytest.mark.parametrize("name", ["markers", "markerless"])
def test_shipped_scorers_read_every_feature(name: str) -> None:
    # Both shipped committees were trained with the snap-back features (the markerless one
    # since 2026-11-30).
    assert load_scorer(name).n_features == N_FEATURES


@pytest.mark.parametrize("name", [None, "markers", "markerless"])
def test_shipped_scorers_load_and_score(name: str | None) -> None:
    scorer = load_scorer(name)
    x = np.zeros((3, N_FEATURES), np.float32)
    out = scorer(x)
    # A committee of the recipe's size: one logit per member and frame; 40 % must fire.
    from tacswitch.grasp.train import default_votes, recipe_committee

    assert out.shape == (3, scorer.committee) and np.isfinite(out).all()
    assert scorer.committee == recipe_committee(markerless=name == "markerless")
    assert scorer.votes == default_votes(scorer.committee)
    np.testing.assert_allclose(out, np.broadcast_to(out[0], out.shape), rtol=1e-5)  # per frame
    assert np.isfinite(scorer.threshold) and scorer.warmup >= 0
    assert scorer.path.name.startswith("slip_scorer")


@pytest.mark.parametrize("seed", [4, 7])
def test_shipped_scorer_leaves_a_simulated_press_and_release_alone(seed: int) -> None:
    # Simulated, and the scorer was trained on real Mini grasps: a sanity check that a plain
    # press, hold and release (no slip) is not called slip, not a measure of accuracy.
    frames = press_recording(seed)
    motion, valid, pts = tracked(frames)
    states = run_clip(motion, valid, pts, image_width=frames[0].shape[1])
    assert not any(s.slip for s in states)
    assert any(s.score == s.score for s in states)  # it did run during the contact


def test_paper_rule_matches_the_slip_detector_from_the_grasp_start() -> None:
    seq = sim.grasp_sequence("gelsight_mini", "slip", n_frames=24, seed=9)
    frames = [seq.reference] * LEAD + list(seq.frames)
    motion, valid, pts = tracked(frames)
    states = run_clip(motion, valid, pts, image_width=frames[0].shape[1], rule="paper")
    start = next(s.frame for s in states if s.grasp_start == s.frame)
    ref = ts.SlipDetector(image_width=frames[0].shape[1])
    for s in states[start:]:
        want = ref.update(motion[s.frame], valid[s.frame])
        assert s.slip == want.slip and s.max_displacement == pytest.approx(want.max_displacement)
    assert any(s.slip for s in states)
    assert not any(s.slip for s in states[:start])


def test_a_callable_scorer_that_fails_keeps_its_own_error() -> None:
    frames = press_recording(4)
    motion, valid, pts = tracked(frames)

    def broken(x: np.ndarray) -> np.ndarray:
        raise ValueError("my scorer's own bug")

    with pytest.raises(ValueError, match=r"^my scorer's own bug$"):
        run_clip(motion, valid, pts, image_width=frames[0].shape[1], model=broken)


@pytest.mark.parametrize("output, message", [
    (lambda x: np.full(len(x), np.nan), "not finite"),
    (lambda x: np.zeros(0), "returned 0 logits"),
    (lambda x: "x", "not numbers"),
])
def test_a_callable_scorer_with_bad_output_is_named(output, message: str) -> None:
    frames = press_recording(4)
    motion, valid, pts = tracked(frames)
    with pytest.raises(ValueError, match=f"^model: .*{message}"):
        run_clip(motion, valid, pts, image_width=frames[0].shape[1], model=output)


def test_detector_errors_name_the_argument() -> None:
    pts = np.array([[10, 10], [40, 10], [10, 40], [40, 40]], np.float32)
    with pytest.raises(ValueError, match="rule"):
        GraspSlipDetector(pts, rule="magic")
    with pytest.raises(ValueError, match="rigid_threshold_px"):
        GraspSlipDetector(pts, rigid_threshold_px=1.0)
    with pytest.raises(ValueError, match="threshold"):
        GraspSlipDetector(pts, model=Recorder(), threshold=float("nan"))
    with pytest.raises(FileNotFoundError, match="model"):
        GraspSlipDetector(pts, model="/nonexistent/slip.onnx")
    det = GraspSlipDetector(pts, model=Recorder())
    with pytest.raises(ValueError, match="motion"):
        det.update(np.zeros((3, 2), np.float32))
    with pytest.raises(ValueError, match="image_width"):
        GraspSlipDetector(pts, image_width=0)
    with pytest.raises(ValueError, match=r"^rigid_only: True needs rigid_threshold_px"):
        GraspSlipDetector(pts, rule="paper", rigid_only=True)


def test_a_scorer_with_unreadable_metadata_is_named(tmp_path: Path) -> None:
    onnx = pytest.importorskip("onnx")

    from tacswitch.grasp.detector import OnnxScorer, slip_model_path

    proto = onnx.load(str(slip_model_path()))
    for prop in proto.metadata_props:
        if prop.key == "tacswitch.threshold":
            prop.value = "not json"
    bad = tmp_path / "bad.onnx"
    onnx.save(proto, str(bad))
    with pytest.raises(ValueError, match=r"^model: .*tacswitch.threshold is not a float"):
        OnnxScorer(bad)


def test_a_tacdiff_model_is_refused_as_a_slip_scorer() -> None:
    from tacswitch.tacdiff.infer import model_path

    pts = np.array([[10, 10], [40, 10], [10, 40], [40, 40]], np.float32)
    with pytest.raises(ValueError, match=r"model: .* expected a slip scorer"):
        GraspSlipDetector(pts, model=model_path(None))


def test_object_folds_keep_objects_together_and_balance() -> None:
    objects = ["a"] * 7 + ["b"] * 5 + ["c"] * 5 + ["d"] * 3 + ["e"] * 2 + ["f"] * 2 + ["g"]
    folds = object_folds(objects, 5)
    assert object_folds(objects, 5) == folds  # deterministic
    for o in set(objects):
        assert len({f for f, x in zip(folds, objects, strict=False) if x == o}) == 1
    sizes = np.bincount(folds, minlength=5)
    assert sizes.min() >= 3 and sizes.max() <= 7
    with pytest.raises(ValueError, match="k"):
        object_folds(["a", "b"], 5)


def test_experiment_scores() -> None:
    labels = [True, True, False, False, False]
    flags = [
        [np.array([0, 0, 1, 1], bool), np.zeros(4, bool)],   # caught at frame 2
        [np.zeros(4, bool), np.zeros(4, bool)],              # missed
        [np.zeros(4, bool), np.zeros(4, bool)],              # left alone
        [np.array([1, 0, 1, 0], bool), np.zeros(4, bool)],   # two false alarms
        [np.zeros(4, bool), np.array([0, 0, 0, 1], bool)],   # one on the other finger
    ]
    s = score_experiments(labels, flags, fps=1.0)
    assert (s.tp, s.fn, s.tn, s.fp) == (1, 1, 1, 2)
    assert s.tpr == 0.5 and s.tnr == pytest.approx(1 / 3)
    assert s.balanced_accuracy == pytest.approx((0.5 + 1 / 3) / 2)
    assert s.accuracy == pytest.approx(2 / 5)
    assert s.false_alarms_per_min == pytest.approx(3 / (24 / 60))
    assert s.median_first_frame == 2


def test_train_and_export_roundtrip(tmp_path) -> None:  # type: ignore[no-untyped-def]
    torch = pytest.importorskip("torch")
    from tacswitch.grasp.train import export_scorer, frame_scores, train_scorer

    rng = np.random.default_rng(0)
    feats, labels = [], []
    for i in range(16):
        slip = i % 2 == 0
        video = rng.normal(0, 0.1, (30, N_FEATURES)).astype(np.float32)
        if slip:  # a burst in a few frames of one feature
            video[20:24, 9] += 3.0
        feats.append([video, rng.normal(0, 0.1, (30, N_FEATURES)).astype(np.float32)])
        labels.append(slip)
    res = train_scorer(feats, labels, epochs=40, seed=0, members=1)
    scores = [max(frame_scores(res.net, v)[3:].max() for v in exp) for exp in feats]
    assert all((s > 0) == lab for s, lab in zip(scores, labels, strict=False)), scores
    path = tmp_path / "slip.onnx"
    export_scorer(res, path, threshold=0.25)
    onnx = load_scorer(path)
    assert onnx.threshold == 0.25
    assert onnx.fps == 25.0  # the time base its features were computed at
    assert onnx.still_filter is False
    filtered = tmp_path / "slip_still.onnx"
    export_scorer(res, filtered, still_filter=True)
    assert load_scorer(filtered).still_filter is True
    x = feats[0][0]
    np.testing.assert_allclose(onnx(x), frame_scores(res.net, x), rtol=1e-4, atol=1e-4)
    assert torch is not None
    with pytest.raises(ValueError, match="labels"):
        train_scorer(feats[:1], labels[:1])


def _grid() -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(20.0, 181.0, 20.0), np.arange(20.0, 141.0, 20.0))
    return np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)


def test_default_votes_are_forty_percent_of_the_committee_rounded_up() -> None:
    from tacswitch.grasp.train import (
        COMMITTEE,
        MARKERLESS_COMMITTEE,
        VOTES,
        committee_votes,
        default_votes,
        recipe_committee,
    )

    assert [default_votes(k) for k in (1, 2, 3, 5, 8, 10, 16, 24, 32)] == \
        [1, 1, 2, 2, 4, 4, 7, 10, 13]
    assert all(default_votes(k) == int(np.ceil(0.4 * k - 1e-9)) for k in range(1, 101))
    assert VOTES == default_votes(COMMITTEE) and committee_votes(COMMITTEE) == VOTES
    assert recipe_committee() == COMMITTEE
    assert recipe_committee(markerless=True) == MARKERLESS_COMMITTEE
    assert committee_votes(8, 2) == 2


def test_committee_trains_one_scorer_per_seed_and_exports_every_logit(tmp_path) -> None:  # type: ignore[no-untyped-def]
    pytest.importorskip("torch")
    from tacswitch.grasp.train import export_scorer, frame_scores, train_committee

    rng = np.random.default_rng(1)
    feats, labels = [], []
    for i in range(12):
        video = rng.normal(0, 0.1, (20, N_FEATURES)).astype(np.float32)
        if i % 2 == 0:
            video[12:15, 4] += 3.0
        feats.append([video])
        labels.append(i % 2 == 0)
    res = train_committee(feats, labels, seed=3, seeds=3, votes=2, epochs=15)
    assert (res.committee, res.votes, res.seed) == (3, 2, 3)
    x = feats[0][0]
    logits = frame_scores(res.net, x)
    assert logits.shape == (len(x), 3)
    # The members differ (each its own seed) and each is the scorer train_scorer makes alone.
    assert not np.allclose(logits[:, 0], logits[:, 1])
    path = tmp_path / "committee.onnx"
    export_scorer(res, path)
    onnx = load_scorer(path)
    assert (onnx.committee, onnx.votes) == (3, 2)
    np.testing.assert_allclose(onnx(x), logits, rtol=1e-4, atol=1e-4)
    det = GraspSlipDetector(_grid(), image_width=200, model=path)
    assert det.votes == 2
    with pytest.raises(ValueError, match="votes: must be >= 1, at most the committee's 3"):
        GraspSlipDetector(_grid(), image_width=200, model=path, votes=4)
    one = train_committee(feats, labels, seeds=1, epochs=2)
    assert (one.committee, one.votes) == (1, 1) and frame_scores(one.net, x).shape == (len(x),)
    for bad, match in (({"seeds": 0}, "seeds"), ({"seeds": 2, "votes": 3}, "votes")):
        with pytest.raises(ValueError, match=match):
            train_committee(feats, labels, epochs=1, **bad)  # type: ignore[arg-type]


def test_committee_trains_its_real_only_members_without_the_extra_experiments(
        tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """With ``extra`` (rendered grasps), the first half of the members train on the real grasps
    alone and the rest on both; the exported committee (each member's standardisation folded
    into its first layer) scores as the torch one does."""
    pytest.importorskip("torch")
    from tacswitch.grasp import train

    rng = np.random.default_rng(2)

    def experiments(n: int, scale: float) -> tuple[list[list[np.ndarray]], list[bool]]:
        feats, labels = [], []
        for i in range(n):
            video = rng.normal(0, scale, (20, N_FEATURES)).astype(np.float32)
            if i % 2 == 0:
                video[12:15, 4] += 3.0
            feats.append([video])
            labels.append(i % 2 == 0)
        return feats, labels

    real, real_labels = experiments(8, 0.1)
    rendered, rendered_labels = experiments(6, 2.0)  # standardised differently
    sizes: list[int] = []
    original = train.train_scorer

    def spy(features, labels, **kw):  # type: ignore[no-untyped-def]
        sizes.append(len(labels))
        return original(features, labels, **kw)

    monkeypatch.setattr(train, "train_scorer", spy)
    assert [train.real_only_members(k, True) for k in (1, 2, 5, 8, 32)] == [0, 1, 2, 4, 16]
    assert train.real_only_members(32, False) == 0
    res = train.train_committee(real, real_labels, seeds=5, epochs=3,
                                extra=(rendered, rendered_labels))
    assert sizes == [8, 8, 14, 14, 14] and res.n_experiments == 14
    sizes.clear()
    train.train_committee(real, real_labels, seeds=3, epochs=1, extra=(rendered, rendered_labels),
                          real_only=0)
    assert sizes == [14, 14, 14]
    mean = [s.mean for s in res.net.scorers]
    assert not all(bool((m == mean[0]).all()) for m in mean[1:])
    x = np.concatenate([real[0][0], rendered[0][0]])
    fused = train.frame_scores(train.fused_committee(res.net), x)
    np.testing.assert_allclose(fused, train.frame_scores(res.net, x), rtol=1e-4, atol=1e-4)
    path = tmp_path / "mixed.onnx"
    train.export_scorer(res, path)
    np.testing.assert_allclose(load_scorer(path)(x), train.frame_scores(res.net, x),
                               rtol=1e-4, atol=1e-4)
    # Its two later members (with the rendered grasps) also vote on their own: 2 of 3 of them.
    assert (res.real_only, res.half_votes) == res.half_vote == (2, 2)
    assert load_scorer(path).half_vote == (2, 2)
    alone = train.train_committee(real, real_labels, seeds=3, epochs=1)
    assert (alone.real_only, alone.half_votes, alone.half_vote) == (0, 0, None)
    with pytest.raises(ValueError, match="real_only"):
        train.train_committee(real, real_labels, seeds=2, epochs=1, real_only=3)


def test_committee_flags_a_grasp_once_enough_members_have_fired() -> None:
    """Each member that scores a frame above the threshold has fired for the rest of the
    contact; slip is flagged once ``votes`` have, on the frames where one fires, and a new
    contact starts with no votes."""
    pts = _grid()
    # Three members; frame by frame, which ones score above 0.
    plan = {5: [0], 6: [], 7: [1], 8: [], 9: [2], 10: [0]}
    calls: list[int] = []

    def scorer(x: np.ndarray) -> np.ndarray:
        calls.append(len(calls))
        out = -np.ones((len(x), 3), np.float32)
        for k in plan.get(frame[0], []):
            out[:, k] = 1.0
        return out

    frame = [0]
    det = GraspSlipDetector(pts, image_width=200, model=scorer, votes=2, start=0)
    got = []
    for t in range(12):
        frame[0] = t
        st = det.update(np.zeros_like(pts) + 0.01 * t)
        got.append((st.slip, st.votes))
    assert [s for s, _ in got] == [False] * 7 + [True, False, True, True, False]
    assert got[7][1] == 2 and got[9][1] == 3
    assert det.first_slip == 7
    # Released (no contact), then a new contact: its members start unfired.
    det = GraspSlipDetector(pts, image_width=200, model=scorer, votes=2)
    phases = iter(["no contact"] * 6 + ["grasp"] * 2 + ["no contact"] + ["pressing"] * 3)
    det.segmenter.update = lambda m, v: Step(next(phases), False, 1, None, None, 0.0, 0.0)
    plan.clear()
    plan.update({6: [0], 7: [1], 9: [2], 10: [0], 11: [1]})
    got = []
    for t in range(12):
        frame[0] = t
        st = det.update(np.zeros_like(pts))
        got.append((st.slip, st.votes))
    assert got == [(False, 0)] * 6 + [(False, 1), (True, 2), (False, 0), (False, 1),
                                      (True, 2), (True, 3)]
    with pytest.raises(ValueError, match="votes: must be >= 1"):
        GraspSlipDetector(pts, image_width=200, model=scorer, votes=0)
    with pytest.raises(TypeError, match="votes"):
        GraspSlipDetector(pts, image_width=200, model=scorer, votes=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="votes: applies to rule='learned' only"):
        GraspSlipDetector(pts, image_width=200, rule="paper", votes=2)
    # A callable's committee size is known at its first score: more votes than members fail.
    det = GraspSlipDetector(pts, image_width=200, model=scorer, votes=4, start=0)
    with pytest.raises(ValueError, match="votes: must be >= 1, at most the committee's 3"):
        for _ in range(6):
            det.update(np.zeros_like(pts))


def test_committee_half_vote_flags_on_the_later_members_alone() -> None:
    """``half_vote=(first, votes)``: a grasp is also flagged once ``votes`` of the members from
    ``first`` on have fired, however few of all the members that is; errors name it."""
    pts = _grid()
    fire = {6: [2], 8: [3], 10: [0]}
    frame = [0]

    def scorer(x: np.ndarray) -> np.ndarray:
        out = -np.ones((len(x), 4), np.float32)
        for k in fire.get(frame[0], []):
            out[:, k] = 1.0
        return out

    def run(**kw: object) -> list[bool]:
        det = GraspSlipDetector(pts, image_width=200, model=scorer, votes=3, start=0, **kw)
        out = []
        for t in range(12):
            frame[0] = t
            out.append(det.update(np.zeros_like(pts) + 0.01 * t).slip)
        return out

    # Without it three of four must fire: members 2, 3 and then 0 (frame 10).
    assert run() == [False] * 10 + [True, False]
    # Members 2 and 3 are both of the later half: two of them flag at frame 8.
    assert run(half_vote=(2, 2)) == [False] * 8 + [True, False, True, False]
    assert run(half_vote=(3, 1)) == [False] * 8 + [True, False, True, False]
    with pytest.raises(ValueError, match="half_vote: applies to rule='learned' only"):
        GraspSlipDetector(pts, image_width=200, rule="paper", half_vote=(1, 1))
    for bad in ((0, 1), (1, 0), (1,), "ab", (1.5, 1), (True, 1)):
        with pytest.raises(ValueError, match="half_vote"):
            GraspSlipDetector(pts, image_width=200, model=scorer, half_vote=bad)  # type: ignore[arg-type]
    # More votes than the later members: known at the first score of a callable.
    det = GraspSlipDetector(pts, image_width=200, model=scorer, half_vote=(2, 3), start=0)
    with pytest.raises(ValueError, match=r"half_vote: needs .* for a committee of 4"):
        for _ in range(6):
            det.update(np.zeros_like(pts))


def test_shipped_marker_committee_has_the_rendered_half_vote() -> None:
    from tacswitch.grasp.train import COMMITTEE, default_votes, half_votes, real_only_members

    first = real_only_members(COMMITTEE, True)
    assert load_scorer("markers").half_vote == (first, half_votes(COMMITTEE, first))
    assert load_scorer("markerless").half_vote is None
    # A loaded file passed as the model is read as its path is (votes, half vote, filter).
    det = GraspSlipDetector(_grid(), image_width=200, model=load_scorer("markers"))
    assert (det.votes, det.half_vote, det.still_filter) == (
        default_votes(COMMITTEE), (first, half_votes(COMMITTEE, first)), True)
    assert [half_votes(k, r) for k, r in ((96, 48), (32, 16), (8, 4), (1, 0), (8, 0), (4, 4))] \
        == [30, 10, 3, 0, 0, 0]


@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), max_size=60),
       st.integers(1, 12), st.one_of(st.none(), st.floats(-1e6, 1e6, allow_nan=False)))
def test_rolling_median_matches_numpy_over_the_window(values: list[float], size: int,
                                                      extra: float | None) -> None:
    from tacswitch.grasp.phases import RollingMedian

    rm = RollingMedian(size)
    for i, v in enumerate(values):
        rm.append(v)
        window = values[max(0, i + 1 - size):i + 1]
        assert len(rm) == len(window)
        assert rm.median() == pytest.approx(float(np.median(window)))
        with_extra = window + ([] if extra is None else [extra])
        assert rm.median(extra) == pytest.approx(float(np.median(with_extra)))
    if not values:
        assert rm.median() == 0.0


class _Tagged:
    """A stand-in clip whose features carry an id (what a fold trained on is then visible)."""

    def __init__(self, tag: float) -> None:
        self.tag = tag

    def features(self, still_filter: bool = False) -> np.ndarray:
        return np.full((1, 1), self.tag, np.float32)


def test_paired_view_trains_only_on_the_training_objects(monkeypatch) -> None:
    """``cross_validated_flags(paired=...)``: each fold trains on its training objects' clips
    and their paired view (e.g. a markerless scorer on the marker tracks of the same grasps),
    never on the held-out objects' paired clips."""
    from tacswitch.grasp import crossval
    from tacswitch.grasp.train import SlipTrainResult

    objects = ["a", "a", "b", "c", "c", "d", "e", "e"]
    labels = [True, False, True, False, True, False, True, False]
    clips = [[_Tagged(i)] for i in range(len(objects))]
    paired = [[_Tagged(100 + i)] for i in range(len(objects))]
    seen: list[set[int]] = []

    def fake_train(features, labels, *, epochs, seed, log=None, starts=None):  # type: ignore[no-untyped-def]
        seen.append({int(v[0][0, 0]) for v in features})
        assert len(features) == len(labels)
        return SlipTrainResult(len(seen) - 1, len(labels), sum(labels), epochs, seed)

    monkeypatch.setattr("tacswitch.grasp.train.train_scorer", fake_train)
    monkeypatch.setattr(crossval, "torch_scorer", lambda net: net)
    monkeypatch.setattr(crossval, "clip_flags", lambda c, **kw: np.zeros(1, bool))
    crossval.cross_validated_flags(clips, labels, objects, seeds=1, paired=paired)
    fold_of = object_folds(objects, 5)
    assert len(seen) == 5
    for f, ids in enumerate(seen):
        train = {i for i, k in enumerate(fold_of) if k != f}
        assert ids == train | {100 + i for i in train}
    seen.clear()
    crossval.cross_validated_flags(clips, labels, objects, seeds=1)
    assert all(max(ids) < 100 for ids in seen)
    with pytest.raises(ValueError, match="paired: one entry per experiment"):
        crossval.cross_validated_flags(clips, labels, objects, seeds=1, paired=paired[:3])


def test_a_contact_from_the_first_frame_that_keeps_moving_starts_a_grasp_after_max_wait() -> None:
    from tacswitch.grasp.phases import GraspSegmenter

    # Loaded from frame 0 (onset 0) and never settling: the grasp must start after max_wait,
    # as it does for an onset at any later frame.
    pts = np.stack(np.meshgrid(np.arange(5) * 20.0, np.arange(5) * 20.0), -1).reshape(-1, 2)
    for first in (0, 5):
        seg = GraspSegmenter(1.6, max_wait=30)
        steps = [seg.update(np.full((len(pts), 2), 5.0 + t if t >= first else 0.0),
                            np.ones(len(pts), bool)) for t in range(80)]
        onset = steps[-1].onset
        assert onset is not None and onset <= first + 3
        start = next(s.start for s in steps if s.starts)
        assert start == onset + 30


def test_a_first_frame_with_a_motion_of_its_own_is_rest_when_asked() -> None:
    """A markerless tracker started without a no-contact frame gives its first frame the
    mechanics rule's motion; read as is, that offset stands above the onset level and opens a
    grasp at frame 0 (the contact phases then cover the whole clip)."""
    from tacswitch.grasp.phases import GraspSegmenter

    rng = np.random.default_rng(0)
    pts = np.stack(np.meshgrid(np.arange(8) * 20.0, np.arange(8) * 20.0), -1).reshape(-1, 2)
    offset = rng.normal(0, 0.4, (len(pts), 2))
    press = np.zeros((len(pts), 2))
    press[:10, 0] = 3.0  # a contact of a few markers from frame 40
    fields = [offset + rng.normal(0, 0.02, offset.shape) + (press if t >= 40 else 0)
              for t in range(70)]
    valid = np.ones(len(pts), bool)
    as_is = GraspSegmenter(1.6)
    onsets = [as_is.update(f, valid).onset for f in fields]
    assert onsets[1] == 0
    rest = GraspSegmenter(1.6, first_frame_rest=True)
    steps = [rest.update(f, valid) for f in fields]
    assert all(s.phase == "no contact" for s in steps[:40])
    assert steps[-1].onset == 40 and steps[-1].phase == "grasp"
    # The detector passes it on; clip scoring reads a clip's rest frame so.
    det = GraspSlipDetector(pts.astype(np.float32), image_width=320, rule="paper",
                            first_frame_rest=True)
    assert [det.update(f.astype(np.float32)).phase for f in fields][:40] == ["no contact"] * 40


def test_detector_refuses_arguments_of_the_wrong_kind_by_name() -> None:
    pts = np.stack(np.meshgrid(np.arange(5) * 20.0, np.arange(5) * 20.0), -1).reshape(-1, 2)
    pts = pts.astype(np.float32)
    for kwargs, name in (({"threshold": "a"}, "threshold"), ({"image_width": "640"}, "image_width"),
                         ({"image_width": 0}, "image_width"),
                         ({"rule": "paper", "threshold_px": "3"}, "threshold_px"),
                         ({"start": 2.5}, "start"), ({"start": -1}, "start"),
                         ({"smooth_frames": 3}, "smooth_frames"),
                         ({"rule": "paper", "smooth_frames": 0}, "smooth_frames")):
        with pytest.raises((TypeError, ValueError), match=rf"^{name}:"):
            GraspSlipDetector(pts, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^zip\(\)"):
        run_clip(np.zeros((5, len(pts), 2), np.float32), np.ones((3, len(pts)), bool), pts)


def test_false_alarms_per_minute_use_each_video_s_frame_rate() -> None:
    held = [np.array([False, True, False, True] + [False] * 46)]  # 2 episodes in 50 frames
    at_25 = score_experiments([False, True], [held, [np.ones(50, bool)]])
    at_50 = score_experiments([False, True], [held, [np.ones(50, bool)]],
                              fps=[[50.0], [50.0]])
    assert at_25.false_alarms_per_min == pytest.approx(2 / (50 / 25 / 60))
    assert at_50.false_alarms_per_min == pytest.approx(2 * at_25.false_alarms_per_min)
    mixed = score_experiments([False, True], [held, [np.ones(50, bool)]], fps=[[None], [50.0]])
    assert mixed.false_alarms_per_min == pytest.approx(at_25.false_alarms_per_min)
    with pytest.raises(ValueError, match=r"^fps:"):
        score_experiments([False, True], [held, [np.ones(50, bool)]], fps=[[25.0]])


def test_counted_from_keeps_only_the_tail_of_slip_videos_cut_short() -> None:
    """A slip video shorter than CUT_SHORT of the median held video (the recording stopped once
    the object fell) counts only its last ``tail`` share; full-length slips and every held
    video count every frame after the warm-up, and so does everything at the default."""
    from tacswitch.grasp.train import CUT_SHORT, SLIP_TAIL, WARMUP, counted_from

    def videos(*lengths: int) -> list[np.ndarray]:
        return [np.zeros((n, N_FEATURES), np.float32) for n in lengths]

    feats = [videos(450, 450), videos(200, 200), videos(100, 120), videos(450, 450),
             videos(4, 4), videos(450, 450)]
    labels = [False, False, True, True, True, False]
    assert CUT_SHORT * 450 > 120
    assert counted_from(feats, labels, 0.5) == [
        [WARMUP, WARMUP], [WARMUP, WARMUP], [50, 60],
        [WARMUP, WARMUP], [WARMUP, WARMUP], [WARMUP, WARMUP]]
    assert SLIP_TAIL == 1.0 and counted_from(feats, labels) == counted_from(feats, labels, 1.0)
    assert counted_from(feats, labels, 0.25) == [
        [WARMUP] * 2, [WARMUP] * 2, [75, 90], [WARMUP] * 2, [WARMUP] * 2, [WARMUP] * 2]
    assert all(s == WARMUP for exp in counted_from(feats, labels, 1.0) for s in exp)
    # Every video one length (a user's clips, not cut by the slip): nothing changes.
    same = [videos(300) for _ in labels]
    assert all(s == WARMUP for exp in counted_from(same, labels) for s in exp)
    for bad in (0.0, -0.5, 1.5, float("nan")):
        with pytest.raises(ValueError, match="tail: must be in"):
            counted_from(feats, labels, bad)


def test_train_scorer_scores_each_video_from_its_counted_frames(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """An experiment's score in training is its largest logit over the frames from each video's
    ``starts`` entry on (the warm-up by default); the standardisation still sees every frame
    after the warm-up."""
    pytest.importorskip("torch")
    from tacswitch.grasp import train

    rng = np.random.default_rng(4)
    feats = [[rng.normal(0, 1, (n, N_FEATURES)).astype(np.float32)] for n in (30, 12, 30, 30)]
    labels = [True, True, False, False]
    masks: list[np.ndarray] = []
    original = train._experiment_scores

    def spy(net, x, mask, owner, batch):  # type: ignore[no-untyped-def]
        order = owner.numpy()
        for k, i in enumerate(order):
            masks.append((int(i), mask[k].numpy().copy()))
        return original(net, x, mask, owner, batch)

    monkeypatch.setattr(train, "_experiment_scores", spy)
    w = train.WARMUP
    train.train_scorer(feats, labels, epochs=1, seed=0, members=1,
                       starts=[[20], [40], [w], [0]])
    got = dict(masks)
    np.testing.assert_array_equal(got[0], np.arange(30) >= 20)
    np.testing.assert_array_equal(got[1][:12], np.arange(12) == 11)  # at least its last frame
    assert not got[1][12:].any()
    for i in (2, 3):  # never before the warm-up
        np.testing.assert_array_equal(got[i], np.arange(30) >= w)
    masks.clear()
    train.train_scorer(feats, labels, epochs=1, seed=0, members=1)
    np.testing.assert_array_equal(dict(masks)[0], np.arange(30) >= w)
    with pytest.raises(ValueError, match="starts"):
        train.train_scorer(feats, labels, epochs=1, starts=[[w]] * 3)


def test_train_committee_passes_the_counted_frames_to_each_member(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``train_committee`` counts the real slips' tail (:func:`counted_from`) for the members
    trained on the real experiments alone (every member without ``extra``); members that also
    learn the ``extra`` (rendered) experiments count every frame of both."""
    pytest.importorskip("torch")
    from tacswitch.grasp import train

    def video(n: int) -> list[np.ndarray]:
        return [np.zeros((n, N_FEATURES), np.float32)]

    real = [video(100), video(100), video(40), video(100)]
    real_labels = [False, False, True, True]
    rendered, rendered_labels = [video(30), video(30)], [True, False]
    seen: list[list[list[int]]] = []

    def spy(features, labels, **kw):  # type: ignore[no-untyped-def]
        seen.append(kw["starts"])
        return train.SlipTrainResult(None, len(labels), sum(labels), 0, kw["seed"])

    monkeypatch.setattr(train, "train_scorer", spy)
    monkeypatch.setattr(train, "build_committee", lambda nets: nets)
    res = train.train_committee(real, real_labels, seeds=2, epochs=1,
                                extra=(rendered, rendered_labels), slip_tail=0.5)
    w = train.WARMUP
    assert seen == [[[w], [w], [20], [w]], [[w]] * 6]
    assert res.slip_tail == 0.5
    seen.clear()
    train.train_committee(real, real_labels, seeds=2, epochs=1, slip_tail=0.5)
    assert seen == [[[w], [w], [20], [w]]] * 2
    seen.clear()
    res = train.train_committee(real, real_labels, seeds=1, epochs=1,
                                extra=(rendered, rendered_labels), slip_tail=0.5)
    assert seen == [[[w]] * 6] and res.slip_tail == 1.0  # no member used the tail
    assert (train.recipe_slip_tail(), train.recipe_slip_tail(True)) == (0.5, 1.0)
    seen.clear()
    res = train.train_committee(real, real_labels, seeds=1, epochs=1)
    assert seen == [[[w]] * 4] and res.slip_tail == train.SLIP_TAIL == 1.0
    with pytest.raises(ValueError, match="slip_tail: must be in"):
        train.train_committee(real, real_labels, seeds=1, epochs=1, slip_tail=0.0)
