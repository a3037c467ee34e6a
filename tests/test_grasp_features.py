"""The slip detector's field features (Rust core) against a plain numpy statement of the same
definitions, on random fields and at the extremes."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tacswitch.grasp.features import (
    FEATURE_NAMES,
    LONG,
    N_BASE_FEATURES,
    N_FEATURES,
    N_FRAME,
    N_SNAP,
    WINDOW,
    FieldFeatures,
    sequence_features,
)


def _affine(pts: np.ndarray, vec: np.ndarray) -> tuple[float, float, float]:
    a = np.c_[pts, np.ones(len(pts))]
    # Nearly collinear markers (spread across under 1 % of the spread along, as variances)
    # determine no affine field: zeros.
    across, along = np.linalg.eigvalsh(np.cov(np.asarray(pts, np.float64).T, bias=True))
    if not across > 0.01 * along:
        return 0.0, 0.0, 0.0
    coef, *_ = np.linalg.lstsq(a, vec, rcond=None)
    resid = np.sqrt(((a @ coef - vec) ** 2).sum(axis=1))
    jac = coef[:2].T
    return (float(np.percentile(resid, 90)), float(jac[0, 0] + jac[1, 1]),
            abs(float(jac[1, 0] - jac[0, 1])))


def _change(pts: np.ndarray, change: np.ndarray) -> list[float]:
    length = np.sqrt((change ** 2).sum(axis=1))
    p90 = float(np.percentile(length, 90))
    resid = _affine(pts, change)[0]
    return [p90, float(np.median(length)), resid, resid / (p90 + 0.02)]


def _snap(hist: deque) -> np.ndarray:
    """The snap-back values of the newest frame of ``hist`` (module doc of the Rust core)."""
    out = np.zeros(N_SNAP)
    if len(hist) < 3:
        return out
    (m0, ok0), (m1, ok1), (m2, ok2) = list(hist)[-3:]
    ok = ok0 & ok1 & ok2
    if ok.sum() < 3:
        return out
    v1, v0 = m2[ok] - m1[ok], m1[ok] - m0[ok]
    n1, n0 = np.linalg.norm(v1, axis=1), np.linalg.norm(v0, axis=1)
    acc = np.percentile(np.linalg.norm(v1 - v0, axis=1), 90)
    out[0] = acc
    out[1] = acc / (np.percentile(n1, 90) + np.percentile(n0, 90) + 0.02)
    out[2] = (v1 * v0).sum() / ((n1 * n0).sum() + 1e-4)
    d = np.linalg.norm(m1[ok], axis=1)
    big = d > 0.2
    if big.sum() >= 3:
        back = -(v1[big] * m1[ok][big]).sum(axis=1) / d[big]
        out[3], out[4] = np.percentile(back, 90), np.median(back)
        out[5] = np.median(back / d[big])
    return out


def reference_features(motions: np.ndarray, valids: np.ndarray, points: np.ndarray,
                       pitch: float) -> np.ndarray:
    """The module doc's definitions, written out in numpy (float64)."""
    pts = (points - points.mean(axis=0)) / pitch
    hist: deque = deque(maxlen=LONG + 1)
    medians: deque = deque(maxlen=LONG)
    frames = []
    snaps = []
    for motion, valid in zip(motions, valids, strict=False):
        m = np.asarray(motion, np.float64) / pitch
        ok = valid & np.isfinite(m).all(axis=1)
        hist.append((m, ok))
        snaps.append(_snap(hist))
        out = np.zeros(N_FRAME)
        out[14] = 1.0 - ok.mean()
        if ok.sum() < 6:
            medians.append(medians[-1] if medians else 0.0)
            frames.append(out)
            continue
        length = np.sqrt((m[ok] ** 2).sum(axis=1))
        out[0], out[1] = np.median(length), np.percentile(length, 90)
        out[2] = np.sqrt((m[ok].mean(axis=0) ** 2).sum())
        out[3:6] = _affine(pts[ok], m[ok])
        for col, lag in ((6, 1), (10, 4)):
            if len(hist) > lag:
                old, old_ok = hist[-1 - lag]
                both = ok & old_ok
                if both.sum() >= 6:
                    out[col:col + 4] = _change(pts[both], m[both] - old[both])
        medians.append(out[0])
        out[15] = max(medians) - out[0]
        if len(hist) > LONG:
            old, old_ok = hist[0]
            both = ok & old_ok
            if both.any():
                out[16] = np.median(np.sqrt(((m[both] - old[both]) ** 2).sum(axis=1)))
        frames.append(out)
    f = np.array(frames)
    sn = np.array(snaps)
    rows = []
    for t in range(len(f)):
        recent = f[max(0, t - WINDOW + 1):t + 1]
        long_change = f[t] - f[max(0, t - LONG)]
        rows.append(np.concatenate([f[t], recent.max(0), recent.min(0), long_change, sn[t],
                                    sn[max(0, t - WINDOW + 1):t + 1].max(0)]))
    return np.array(rows)


def grid(nx: int = 9, ny: int = 7, pitch: float = 30.0) -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(nx) * pitch + 20, np.arange(ny) * pitch + 15)
    return np.c_[xs.ravel(), ys.ravel()].astype(np.float32)


def test_names_and_sizes() -> None:
    assert len(FEATURE_NAMES) == len(set(FEATURE_NAMES)) == N_FEATURES
    assert N_BASE_FEATURES == 4 * N_FRAME and N_FEATURES == N_BASE_FEATURES + 2 * N_SNAP


def test_matches_numpy_on_a_random_walk_with_lost_markers() -> None:
    rng = np.random.default_rng(0)
    pts = grid()
    T = 60
    motions = np.cumsum(rng.normal(0, 0.8, (T, len(pts), 2)), axis=0).astype(np.float32)
    valids = rng.random((T, len(pts))) > 0.1
    motions[5, 3] = np.nan  # a NaN row is a lost marker even when flagged valid
    valids[20] = False       # a frame with nothing tracked
    valids[21, 6:] = False   # and one whose markers are collinear (the first row)
    valids[30, 5:] = False   # and one with too few markers
    got = sequence_features(motions, valids, pts, 30.0)
    want = reference_features(motions, valids, pts, 30.0)
    assert got.shape == (T, N_FEATURES) and got.dtype == np.float32
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=2e-5)


@settings(max_examples=40, deadline=None)
@given(scale=st.sampled_from([1e-6, 1.0, 1e3, 1e6]),
       pitch=st.sampled_from([0.5, 10.0, 300.0]),
       n=st.integers(min_value=0, max_value=40),
       seed=st.integers(min_value=0, max_value=10_000))
def test_extremes_are_finite_and_match_numpy(scale: float, pitch: float, n: int,
                                             seed: int) -> None:
    rng = np.random.default_rng(seed)
    pts = (rng.random((n, 2)) * 300).astype(np.float32)
    motions = (rng.normal(0, scale, (8, n, 2))).astype(np.float32)
    valids = rng.random((8, n)) > 0.2
    got = sequence_features(motions, valids, pts, pitch)
    assert np.isfinite(got).all()
    if n >= 6 and scale <= 1e3:
        want = reference_features(motions, valids, pts, pitch)
        np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-4 * max(1.0, scale / pitch))


def random_walk(seed: int, pts: np.ndarray, frames: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Motions of a random walk of every marker, all valid."""
    rng = np.random.default_rng(seed)
    motions = np.cumsum(rng.normal(0, 0.5, (frames, len(pts), 2)), axis=0).astype(np.float32)
    return motions, np.ones((frames, len(pts)), bool)


def test_invariant_to_rotating_and_mirroring_the_image() -> None:
    pts = grid()
    motions, valids = random_walk(1, pts)
    base = sequence_features(motions, valids, pts, 30.0)
    for flip in (np.array([[0, -1], [1, 0]]), np.array([[-1, 0], [0, 1]])):
        f = flip.astype(np.float32)
        got = sequence_features(motions @ f.T, valids, pts @ f.T, 30.0)
        np.testing.assert_allclose(got, base, rtol=1e-3, atol=1e-4)


def test_scales_with_the_pitch() -> None:
    pts = grid()
    motions, valids = random_walk(2, pts)
    small = sequence_features(motions, valids, pts, 30.0)
    big = sequence_features(motions * 2, valids, pts * 2, 60.0)
    np.testing.assert_allclose(small, big, rtol=1e-3, atol=1e-4)


def test_bad_arguments_name_themselves() -> None:
    pts = grid()
    with pytest.raises(ValueError, match="pitch"):
        FieldFeatures(pts, 0.0)
    with pytest.raises(ValueError, match="pitch"):
        FieldFeatures(pts, float("nan"))
    ff = FieldFeatures(pts, 30.0)
    with pytest.raises(ValueError, match="motion"):
        ff.update(np.zeros((3, 2), np.float32))
    with pytest.raises(ValueError, match="valid"):
        ff.update(np.zeros((len(pts), 2), np.float32), np.ones(2, bool))
    with pytest.raises(ValueError, match="points"):
        FieldFeatures(np.zeros((4, 3), np.float32), 30.0)
