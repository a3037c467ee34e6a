"""The still-marker hysteresis the marker slip scorer reads its tracks through (Rust core,
``rust/core/src/still_filter.rs``): against a numpy statement of it, the identity on streams
without jitter (the codec-frozen recordings the scorers learned from), and a still gel under
sensor noise read as still."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tacswitch.grasp.detector import GraspSlipDetector, load_scorer
from tacswitch.grasp.features import FEATURE_NAMES, FieldFeatures, sequence_features

K, CAP, WINDOW, QUANTILE = 8.0, 0.01, 5, 0.25


def hysteresis(motion: np.ndarray, pitch: float) -> np.ndarray:
    """The filter in numpy: a marker's reported motion follows its tracked one only once the
    two are more than ``h`` pitches apart; ``h`` = K x the smallest running median (over
    WINDOW frames) of each frame's QUANTILE frame-to-frame step, at most CAP; a repeated frame
    (every finite step exactly 0) adds no step."""
    m = np.asarray(motion, np.float64)
    out = m.copy()
    held = m[0].copy()
    steps: list[float] = []
    floor = np.inf
    for t in range(1, len(m)):
        d = np.hypot(*(m[t] - m[t - 1]).T) / pitch
        d = d[np.isfinite(d)]
        repeated = len(d) > 0 and not d.any()
        if not repeated:
            steps.append(float(np.quantile(d, QUANTILE)) if len(d) else np.inf)
        if not repeated and len(steps) >= WINDOW:
            floor = min(floor, float(np.median(steps[-WINDOW:])))
        h = min(K * floor, CAP) * pitch if np.isfinite(floor) else 0.0
        far = ~(np.hypot(*(m[t] - held).T) <= h)  # NaN (lost) always follows
        held[far] = m[t][far]
        out[t] = held
    return out.astype(np.float32)


def grid(n_side: int, pitch: float) -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(n_side) * pitch + 10, np.arange(n_side) * pitch + 10)
    return np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)


def field(rng: np.random.Generator, pts: np.ndarray, frames: int, noise_px: float,
          lost: bool) -> np.ndarray:
    """A still gel whose centre patch is pushed and then slides, plus tracking noise."""
    n = len(pts)
    centre = np.linalg.norm(pts - pts.mean(0), axis=1) < 1.5 * (pts[1, 0] - pts[0, 0])
    push = np.clip(np.arange(frames) - frames // 3, 0, None)[:, None] * 0.3
    motion = np.zeros((frames, n, 2), np.float32)
    motion[:, centre, 0] = push
    motion += rng.normal(0.0, noise_px, motion.shape).astype(np.float32)
    if lost:
        motion[frames // 2: frames // 2 + 3, 0] = np.nan
    return motion


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), noise=st.sampled_from([0.0, 0.005, 0.03, 0.2, 2.0]),
       pitch=st.sampled_from([8.0, 20.0, 45.0]), lost=st.booleans(),
       frames=st.integers(1, 40), repeats=st.integers(0, 8))
def test_matches_numpy(seed: int, noise: float, pitch: float, lost: bool, frames: int,
                       repeats: int) -> None:
    rng = np.random.default_rng(seed)
    pts = grid(6, pitch)
    motion = field(rng, pts, frames, noise * pitch / 20, lost)
    # Repeated frames: at the start (a stale start read as rest) and one in the middle.
    motion[:min(repeats, frames)] = 0.0
    if frames > 12 and repeats:
        motion[frames // 2 + 1] = motion[frames // 2]
    valid = ~np.isnan(motion).any(axis=2)
    got = sequence_features(motion, valid, pts, pitch, still_filter=True)
    want = sequence_features(hysteresis(motion, pitch), valid, pts, pitch)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
    assert np.isfinite(got).all()


def test_a_stream_without_jitter_reads_the_same_with_and_without_the_filter() -> None:
    # As in the recordings: still markers tracked at exactly the same place every frame.
    rng = np.random.default_rng(1)
    pts = grid(8, 20.0)
    motion = field(rng, pts, 60, 0.0, lost=True)
    valid = ~np.isnan(motion).any(axis=2)
    np.testing.assert_array_equal(sequence_features(motion, valid, pts, 20.0, still_filter=True),
                                  sequence_features(motion, valid, pts, 20.0))


@pytest.mark.parametrize("stale", [0, 6])
def test_a_still_gel_under_sensor_noise_reads_still(stale: int) -> None:
    # 0.02 px of jitter (0.001 pitch): what 4 grey levels of sensor noise do to a Mini's markers.
    # ``stale``: the first frames repeat the rest frame exactly, as a recording's stale start
    # is read (`track_clip`) or a camera repeats frames; they must not switch the filter off.
    rng = np.random.default_rng(2)
    pts = grid(8, 20.0)
    clean = np.zeros((40 + stale, len(pts), 2), np.float32)
    noisy = clean + rng.normal(0.0, 0.02, clean.shape).astype(np.float32)
    noisy[:stale] = 0.0
    valid = np.ones(clean.shape[:2], bool)
    still = sequence_features(clean, valid, pts, 20.0)
    filtered = sequence_features(noisy, valid, pts, 20.0, still_filter=True)
    raw = sequence_features(noisy, valid, pts, 20.0)
    # Once the floor is known (WINDOW steps) and the 4-frame changes and 8-frame windows have
    # passed, every value
    # of how the field changes (velocities, accelerations, snap-back) is exactly the still
    # gel's; the raw noise is not. (The held places keep the noise of their last update, under
    # 0.01 pitch: the displacement values stay near, not at, zero.)
    changes = [i for i, n in enumerate(FEATURE_NAMES)
               if n.startswith(("v1_", "v4_", "snap_")) and not n.endswith("_change")]
    settle = stale + WINDOW + 4 + 8
    np.testing.assert_array_equal(filtered[settle:, changes], still[settle:, changes])
    assert np.abs(raw[settle:, changes] - still[settle:, changes]).max() > 1e-4
    assert np.abs(filtered[settle:, :2]).max() < 0.01


def test_the_detector_reads_the_filter_from_the_scorer_and_the_argument() -> None:
    pts = grid(6, 20.0)
    assert load_scorer("markers").still_filter is True  # trained on tracked markers
    assert load_scorer("markerless").still_filter is False  # predicted motion: never still
    assert GraspSlipDetector(pts).still_filter is True
    assert GraspSlipDetector(pts, model="markerless").still_filter is False
    assert GraspSlipDetector(pts, still_filter=False).still_filter is False
    assert GraspSlipDetector(pts, model=lambda x: np.zeros(len(x))).still_filter is False
    assert FieldFeatures(pts, 20.0, True).still_filter is True
    with pytest.raises(ValueError, match="still_filter"):
        GraspSlipDetector(pts, rule="paper", still_filter=True)
    with pytest.raises(TypeError, match="still_filter"):
        GraspSlipDetector(pts, still_filter="yes")  # type: ignore[arg-type]
