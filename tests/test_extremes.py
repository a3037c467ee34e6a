"""Bad input and extremes: a clear error naming the argument, or a defined result; never a crash."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import tacswitch as ts
from tacswitch import sim

shapes = st.tuples(st.integers(1, 48), st.integers(1, 48)).flatmap(
    lambda hw: st.sampled_from([hw, (*hw, 1), (*hw, 3), (*hw, 4)])
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(img=shapes.flatmap(lambda s: arrays(np.uint8, s)))
def test_any_uint8_image_gives_a_consistent_result(img: np.ndarray) -> None:
    m = ts.extract_markers(img)
    h, w = img.shape[:2]
    assert m.mask.shape == (h, w)
    assert np.isfinite(m.centres).all()
    assert len(m) == len(m.areas) == len(m.bboxes) == len(m.contrast)
    assert ((m.contrast >= 0) & (m.contrast <= 1)).all()
    assert 0 <= m.threshold <= 255


@settings(max_examples=60, deadline=None)
@given(
    noise=st.floats(0, 60),
    level=st.integers(0, 255),
    seed=st.integers(0, 2**16),
)
def test_noise_and_saturation_never_crash(noise: float, level: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    img = np.clip(level + rng.normal(0, noise, (120, 160, 3)), 0, 255).astype(np.uint8)
    m = ts.extract_markers(img)
    assert m.mask.shape == (120, 160)
    if noise < 2:  # a flat frame, however bright or dark, has no markers
        assert len(m) == 0


def test_heavy_noise_keeps_real_markers() -> None:
    p = sim.get_preset("gelsight")
    rest = sim.marker_grid(p.height, p.width, p.rows, p.cols, p.pitch)
    bg = sim.gel_background(p.height, p.width, seed=0)
    img = sim.render_markers(bg, rest, p.diameter, darkness=0.85, noise_sigma=12.0, seed=1)
    m = ts.extract_markers(img)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(m.centres).query(rest)
    assert (d < 1.5).all()
    assert len(m) == len(rest)


def test_non_contiguous_and_views_are_accepted() -> None:
    seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=8, seed=0)
    img = seq.reference
    flipped = img[:, ::-1]  # negative stride
    cropped = img[10:200, 20:300]  # offset view
    rgb_view = img[:, :, ::-1]  # channel-reversed view: still a valid BGR-shaped array
    for view in (flipped, cropped, rgb_view, np.asfortranarray(img)):
        m = ts.extract_markers(view)
        assert len(m) > 50
    np.testing.assert_allclose(
        np.sort(ts.extract_markers(flipped).centres[:, 0]),
        np.sort(img.shape[1] - 1 - ts.extract_markers(img).centres[:, 0]),
        atol=0.05,
    )


@pytest.mark.parametrize(
    ("img", "exc", "needle"),
    [
        (np.zeros((10, 10), np.float32), TypeError, "img: expected dtype uint8"),
        (np.zeros((10, 10), np.uint16), TypeError, "img: expected dtype uint8"),
        (np.zeros((10, 10), bool), TypeError, "img"),
        ([[0, 1], [2, 3]], TypeError, "img: expected a numpy array"),
        (np.zeros((10, 10, 2), np.uint8), ValueError, "img: expected a grey"),
        (np.zeros((10,), np.uint8), ValueError, "img"),
        (np.zeros((2, 3, 3, 3), np.uint8), ValueError, "img"),
        (np.zeros((0, 10, 3), np.uint8), ValueError, "img: image must be at least 1 x 1"),
    ],
)
def test_bad_images_are_named(img: object, exc: type, needle: str) -> None:
    with pytest.raises(exc, match=needle):
        ts.extract_markers(img)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "exc", "needle"),
    [
        ({"polarity": "black"}, ValueError, "polarity"),
        ({"block_size": 4}, ValueError, "block_size"),
        ({"block_size": 1}, ValueError, "block_size"),
        ({"block_size": 1001}, ValueError, "block_size"),
        ({"block_size": 3.5}, TypeError, "block_size"),
        ({"threshold": -1}, ValueError, "threshold"),
        ({"threshold": float("nan")}, ValueError, "threshold"),
        ({"min_area": -1}, ValueError, "min_area"),
        ({"min_area": 50, "max_area": 10}, ValueError, "max_area"),
        ({"min_fill": 2.0}, ValueError, "min_fill"),
        ({"max_aspect": 0.5}, ValueError, "max_aspect"),
        ({"dilate": -1}, ValueError, "dilate"),
    ],
)
def test_bad_options_are_named(kwargs: dict, exc: type, needle: str) -> None:
    with pytest.raises(exc, match=needle):
        ts.extract_markers(np.zeros((20, 20, 3), np.uint8), **kwargs)


@pytest.mark.parametrize(
    ("ref", "cur", "needle"),
    [
        (np.array([[np.nan, 1.0]]), np.zeros((1, 2)), "ref_pts"),
        (np.zeros((1, 2)), np.array([[1.0, np.inf]]), "cur_pts"),
        (np.zeros((3, 3)), np.zeros((1, 2)), "ref_pts"),
        (np.zeros((1, 2)), np.zeros(4), "cur_pts"),
        (np.zeros((2, 2), bool), np.zeros((1, 2)), "ref_pts"),
        ("abc", np.zeros((1, 2)), "ref_pts"),
    ],
)
def test_bad_points_are_named(ref: object, cur: object, needle: str) -> None:
    with pytest.raises((ValueError, TypeError), match=needle):
        ts.match_markers(ref, cur)
    with pytest.raises(ValueError, match="max_dist"):
        ts.match_markers(np.zeros((1, 2)), np.zeros((1, 2)), max_dist=0)


def test_every_marker_lost_and_back() -> None:
    seq = sim.grasp_sequence("gelsight", "hold", n_frames=8, seed=1)
    tracker = ts.MarkerTracker(seq.reference)
    black = np.zeros_like(seq.reference)
    motion, valid = tracker.update(black)
    assert not valid.any() and np.isnan(motion).all()
    detector = ts.SlipDetector()
    state = detector.update(motion, valid)
    assert not state.slip and state.n_compared == 0 and state.marker == -1
    motion, valid = tracker.update(seq.frames[0])
    assert valid.all()


def test_reference_without_markers_gives_empty_tracking() -> None:
    tracker = ts.MarkerTracker(np.full((60, 80, 3), 128, np.uint8))
    assert len(tracker) == 0
    motion, valid = tracker.update(np.full((60, 80, 3), 128, np.uint8))
    assert motion.shape == (0, 2) and valid.shape == (0,)
