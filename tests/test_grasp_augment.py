"""Augmented copies of tracked grasps (``tacswitch.grasp.augment``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tacswitch.grasp.augment import (
    augmented_experiments,
    marker_training_set,
    rescaled_clip,
    with_copies,
)
from tacswitch.grasp.dataset import TrackedClip


def _clip(t: int = 20, n: int = 6, seed: int = 0) -> TrackedClip:
    rng = np.random.RandomState(seed)
    motion = np.cumsum(rng.normal(0, 0.5, (t, n, 2)), axis=0).astype(np.float32)
    valid = rng.rand(t, n) > 0.1
    points = (rng.rand(n, 2) * 100).astype(np.float32)
    return TrackedClip(motion, valid, points, 20.0, 320)


def test_identity_scale_and_speed() -> None:
    c = _clip()
    r = rescaled_clip(c, 1.0, 1.0)
    np.testing.assert_array_equal(r.motion, c.motion)
    np.testing.assert_array_equal(r.valid, c.valid)
    assert r.pitch == c.pitch and r.width == c.width and r.points is c.points


def test_scale_multiplies_every_displacement() -> None:
    c = _clip()
    np.testing.assert_allclose(rescaled_clip(c, 1.5, 1.0).motion, c.motion * 1.5, rtol=1e-6)


def test_double_speed_keeps_every_other_frame() -> None:
    c = _clip(t=21)
    r = rescaled_clip(c, 1.0, 2.0)
    assert len(r.motion) == 11
    np.testing.assert_allclose(r.motion, c.motion[::2], rtol=1e-6)
    np.testing.assert_array_equal(r.valid, c.valid[::2])


def test_half_speed_interpolates_between_frames() -> None:
    c = _clip(t=5)
    r = rescaled_clip(c, 1.0, 0.5)
    assert len(r.motion) == 9
    np.testing.assert_allclose(r.motion[1], (c.motion[0] + c.motion[1]) / 2, rtol=1e-6)
    # A marker counts as valid in an interpolated frame only where both frames saw it.
    np.testing.assert_array_equal(r.valid[1], c.valid[0] & c.valid[1])


@settings(max_examples=40, deadline=None)
@given(t=st.integers(1, 60), scale=st.floats(1e-3, 1e3), speed=st.floats(0.05, 20.0))
def test_extremes_stay_finite_and_shaped(t: int, scale: float, speed: float) -> None:
    c = _clip(t=t)
    r = rescaled_clip(c, scale, speed)
    assert r.motion.shape[1:] == c.motion.shape[1:] and r.valid.shape == r.motion.shape[:2]
    assert len(r.motion) >= 1 and np.isfinite(r.motion).all()
    assert r.motion.dtype == np.float32


def test_copies_share_one_draw_per_experiment_and_are_deterministic() -> None:
    exps = [[_clip(seed=1), _clip(seed=2)], [_clip(t=30, seed=3)]]
    out, owner = augmented_experiments(exps, 3, seed=7)
    assert owner == [0, 1, 0, 1, 0, 1]
    for copy, i in zip(out, owner, strict=True):
        assert len(copy) == len(exps[i])
        # Both fingers of one copy: the same speed (same length) and the same scale.
        ratios = [np.abs(c.motion[-1]).sum() / np.abs(e.motion[-1]).sum()
                  for c, e in zip(copy, exps[i], strict=True)
                  if len(c.motion) == len(e.motion)]
        assert len({len(c.motion) for c in copy}) == 1
        if len(ratios) == 2:
            assert ratios[0] == pytest.approx(ratios[1], rel=1e-4)
    again, _ = augmented_experiments(exps, 3, seed=7)
    for a, b in zip(out, again, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x.motion, y.motion)
    assert augmented_experiments(exps, 0)[0] == []


def test_bad_arguments_name_themselves() -> None:
    c = _clip()
    for kw in ({"scale": 0.0, "speed": 1.0}, {"scale": 1.0, "speed": float("nan")},
               {"scale": "2", "speed": 1.0}):
        name = next(k for k, v in kw.items() if not (isinstance(v, float) and v > 0))
        with pytest.raises(ValueError, match=name):
            rescaled_clip(c, **kw)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="copies"):
        augmented_experiments([[c]], -1)
    with pytest.raises(ValueError, match="scale_range"):
        augmented_experiments([[c]], 1, scale_range=0.5)
    with pytest.raises(ValueError, match="speed_range"):
        augmented_experiments([[c]], 1, speed_range=float("inf"))


def test_with_copies_keeps_the_originals_first_and_their_labels() -> None:
    exps = [[_clip(seed=1)], [_clip(seed=2)], [_clip(seed=3)]]
    out, labels = with_copies(exps, [True, False, True], 2)
    assert out[:3] == exps and len(out) == 9
    assert labels == [True, False, True] * 3
    real, real_labels, rendered, rendered_labels = marker_training_set(
        exps, [True, False, True], 0, 1)
    assert real[:3] == exps and real_labels == [True, False, True] * 2
    assert rendered == [] and rendered_labels == []
    with pytest.raises(ValueError, match="labels"):
        with_copies(exps, [True], 1)
