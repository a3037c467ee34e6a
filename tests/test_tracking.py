"""Matching and tracking: agreement with SciPy, gating, lost markers, large displacements."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import tacswitch as ts
from tacswitch import sim


def scipy_mutual_nn(ref: np.ndarray, cur: np.ndarray, gate: float) -> np.ndarray:
    """Reference implementation: mutual nearest neighbour within ``gate`` (index or -1)."""
    out = np.full(len(ref), -1)
    if len(ref) == 0 or len(cur) == 0:
        return out
    d, j = cKDTree(cur).query(ref)
    _, back = cKDTree(ref).query(cur)
    for i in range(len(ref)):
        if d[i] <= gate and back[j[i]] == i:
            out[i] = j[i]
    return out


points = st.lists(
    st.tuples(st.floats(0, 300, width=32), st.floats(0, 200, width=32)), min_size=0, max_size=60
).map(lambda v: np.array(v, np.float32).reshape(-1, 2))


def has_tie(q: np.ndarray, pts: np.ndarray) -> bool:
    """True when ``q`` has two equally near points in ``pts`` (nearest neighbour ambiguous)."""
    if len(pts) < 2:
        return False
    d = np.sort(np.hypot(*(pts.astype(np.float64) - q).T))
    return bool(d[1] - d[0] < 1e-4)


@settings(max_examples=150, deadline=None)
@given(ref=points, cur=points, gate=st.floats(0.5, 80))
def test_matches_scipy_mutual_nearest_neighbour(ref: np.ndarray, cur: np.ndarray,
                                                gate: float) -> None:
    motion, valid, index = ts.match_markers(ref, cur, max_dist=gate, return_index=True)
    expected = scipy_mutual_nn(ref, cur, np.float32(gate))
    # Where a nearest neighbour is ambiguous SciPy picks arbitrarily (we pick the lowest index):
    # compare only unambiguous reference points whose candidate is unambiguous too.
    for i in range(len(ref)):
        if has_tie(ref[i], cur):
            continue
        j = int(np.argmin(np.hypot(*(cur - ref[i]).T))) if len(cur) else -1
        if j >= 0 and has_tie(cur[j], ref):
            continue
        assert index[i] == expected[i], (i, index[i], expected[i])
    np.testing.assert_array_equal(valid, index >= 0)
    assert np.isnan(motion[~valid]).all()
    np.testing.assert_allclose(motion[valid], cur[index[valid]] - ref[valid], atol=1e-5)
    # Every match is mutual and gated, whatever the ties; no current point is used twice.
    used = index[valid]
    assert len(set(used.tolist())) == len(used)
    assert (np.hypot(*motion[valid].T) <= np.float32(gate) + 1e-4).all()


def test_default_gate_is_half_the_pitch() -> None:
    ref = sim.marker_grid(240, 320, 9, 11, 28.5)
    assert ts.estimate_pitch(ref) == pytest.approx(28.5, abs=1e-3)
    small = ref + np.array([5.0, -6.0], np.float32)  # 7.8 px < 14.25
    _, valid = ts.match_markers(ref, small)
    assert valid.all()
    far = ref + np.array([11.0, 11.0], np.float32)  # 15.6 px > 14.25 and 15.6 from any neighbour
    motion, valid = ts.match_markers(ref, far)
    assert not valid.any() and np.isnan(motion).all()


def test_lost_marker_does_not_borrow_a_neighbour() -> None:
    ref = sim.marker_grid(240, 320, 4, 4, 30.0)
    cur = np.delete(ref, 5, axis=0) + np.float32(1.0)
    motion, valid = ts.match_markers(ref, cur)
    assert not valid[5] and np.isnan(motion[5]).all()
    assert valid.sum() == 15


def test_duplicates_and_empty_inputs() -> None:
    ref = sim.marker_grid(100, 100, 3, 3, 20.0)
    motion, valid = ts.match_markers(ref, np.vstack([ref[:1], ref[:1]]))
    assert valid.sum() == 1 and valid[0]
    motion, valid = ts.match_markers(np.zeros((0, 2)), ref)
    assert motion.shape == (0, 2) and valid.shape == (0,)
    motion, valid = ts.match_markers(ref, [])
    assert not valid.any()
    assert ts.estimate_pitch(ref[:1]) is None
    assert ts.estimate_pitch(np.vstack([ref[:1], ref[:1]])) is None


def test_tracker_follows_a_press_larger_than_a_pitch() -> None:
    seq = sim.grasp_sequence("gelsight_mini", "slip", n_frames=40, seed=3)
    tracker = ts.MarkerTracker(seq.reference)
    assert len(tracker) == len(seq.rest)
    for frame in seq.frames:
        motion, valid = tracker.update(frame)
    _, ok, idx = ts.match_markers(seq.rest, tracker.reference, return_index=True)
    assert ok.all()
    truth = seq.motions[-1][np.argsort(idx)]
    assert np.hypot(*truth.T).max() > seq.preset.pitch * 0.7
    assert valid.all()
    err = np.hypot(*(motion - truth).T)
    assert np.median(err) < 0.1 and err.max() < 1.0


def test_tracker_reacquires_lost_markers() -> None:
    ref = sim.marker_grid(480, 640, 6, 8, 80.0)
    tracker = ts.MarkerTracker(ref)
    for step in range(1, 16):
        cur = ref + np.array([3.0 * step, -1.0 * step], np.float32)
        if 4 <= step < 12:
            cur = np.delete(cur, [10, 11, 20], axis=0)
        motion, valid = tracker.update(cur)
        if 4 <= step < 12:
            assert not valid[[10, 11, 20]].any()
            assert np.isnan(motion[[10, 11, 20]]).all()
    assert valid.all()
    np.testing.assert_allclose(motion, np.tile([45.0, -15.0], (48, 1)), atol=1e-4)


def test_tracker_on_images_equals_tracker_on_points() -> None:
    seq = sim.grasp_sequence("gelsight", "hold", n_frames=12, seed=0)
    a = ts.MarkerTracker(seq.reference)
    b = ts.MarkerTracker(a.reference)
    for f in seq.frames:
        ma, va = a.update(f)
        mb, vb = b.update(ts.extract_markers(f).centres)
        np.testing.assert_array_equal(va, vb)
        np.testing.assert_array_equal(ma, mb)
    assert a.frame == len(seq.frames)
    a.reset()
    assert a.frame == 0
    np.testing.assert_array_equal(a.positions, a.reference)


def test_tracker_errors_name_the_argument() -> None:
    seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=8, seed=0)
    tracker = ts.MarkerTracker(seq.reference)
    with pytest.raises(ValueError, match="img_or_pts"):
        tracker.update(np.zeros((100, 100, 3), np.uint8))
    with pytest.raises(ValueError, match="img_or_pts"):
        tracker.update(np.array([[np.nan, 1.0]]))
    with pytest.raises(TypeError, match="unknown option"):
        ts.MarkerTracker(seq.reference, thresh=3)
    # OpenCV's N x 1 x 2 point layout is points of the wrong shape, not an image.
    with pytest.raises(ValueError, match=r"^ref_img_or_pts: expected an N x 2"):
        ts.MarkerTracker(np.zeros((20, 1, 2), np.float32))
    # A float or 16-bit frame is named as an image of the wrong dtype, not as bad points.
    for frame in (seq.reference.astype(np.float32), seq.reference[..., 0].astype(np.uint16)):
        with pytest.raises(TypeError, match=r"^ref_img_or_pts: expected dtype uint8"):
            ts.MarkerTracker(frame)
        with pytest.raises(TypeError, match=r"^img_or_pts: expected dtype uint8"):
            tracker.update(frame)
        with pytest.raises(TypeError, match=r"^motion_or_img: expected dtype uint8"):
            ts.SlipDetector().update(frame)
    with pytest.raises(ValueError, match="max_dist"):
        ts.MarkerTracker(seq.reference, max_dist=-2)
