"""``predict_motion``'s ``method="auto"`` with a reference: the ensemble (its rule against the
reference) against a frame that lacks the contact (the no-contact frame), flow against a frame of
the same contact; the test that tells them apart (:mod:`tacswitch.motion.reference`) on taxim's
real presses."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from proxies import motion_proxy as proxy

from tacswitch import predict_motion
from tacswitch.motion import ensemble, flow, reference
from tacswitch.motion.infer import resolve_method


def _sheared(data: proxy.RealPresses, i: int, amp: float = 8.0) -> np.ndarray:
    fld = proxy.random_field("shear", tuple(data.centres[i]), float(data.radii[i]), amp,
                             np.random.default_rng(i), shape=data.imgs[i].shape[:2])
    return proxy.warp(data.imgs[i], fld)


def test_the_no_contact_frame_is_told_from_a_reference_of_the_same_contact(mini) -> None:
    for i in range(0, len(mini.imgs), 3):
        # Real: the no-contact frame lacks every press; the press itself, sheared, does not.
        assert reference.is_new_contact(mini.imgs[i], mini.f0), i
        assert not reference.is_new_contact(_sheared(mini, i), mini.imgs[i]), i
        # A contact that goes away is not a new one (flow follows the release).
        assert not reference.is_new_contact(mini.f0, mini.imgs[i]), i


def test_contact_changed_is_the_new_contact_test_both_ways(mini) -> None:
    frames = [mini.f0, *mini.imgs[::4], _sheared(mini, 6)]
    seen = set()
    for a in frames:
        for b in frames:
            either = reference.is_new_contact(a, b) or reference.is_new_contact(b, a)
            assert reference.contact_changed(a, b) == either
            seen.add(either)
    assert seen == {True, False}  # both answers occur


def test_real_gelsight_presses_against_the_no_contact_frame() -> None:
    gs = proxy.load_real_presses("gelsight")
    ratios = [reference.contact_energy_ratio(im, gs.f0) for im in gs.imgs[::6]]
    assert max(ratios) < reference.NEW_CONTACT_RATIO
    assert reference.contact_energy_ratio(_sheared(gs, 5), gs.imgs[5]) > 0.8


def test_auto_runs_flow_with_any_reference_and_the_ensemble_without(mini, grid) -> None:
    img = mini.imgs[6]
    # The no-contact frame too (real Mini videos: the ensemble kept ~1/6 of a press's motion).
    np.testing.assert_array_equal(predict_motion(img, mini.f0, grid),
                                  flow.flow_motion(img, mini.f0, grid))
    same = _sheared(mini, 6)
    np.testing.assert_array_equal(predict_motion(same, img, grid), flow.flow_motion(same, img,
                                                                                    grid))
    # The gain is the ensemble's; flow ignores it.
    np.testing.assert_array_equal(predict_motion(same, img, grid, gain=3.0),
                                  flow.flow_motion(same, img, grid))
    np.testing.assert_array_equal(predict_motion(img, None, grid, gain="gelsight"),
                                  ensemble.ensemble_motion(img, None, grid, gain=0.25))
    assert resolve_method("auto", img, mini.f0) == "flow"
    assert resolve_method("auto", same, img) == "flow"
    assert resolve_method("auto", img, None) == "ensemble"
    assert resolve_method("flow", img, mini.f0) == "flow"


def test_auto_from_the_no_contact_frame_keeps_the_press_magnitude(grid) -> None:
    # A generated gel pressed and sheared by a known field, its imprint appearing: "auto"
    # against the no-contact frame keeps the motion's size (it ran the ensemble before, whose
    # rule and model predicted a fraction of it).
    from gel_fixtures import _gel, _pressed_and_sheared

    f0 = _gel(1)
    for amp in (3.0, 8.0):
        img, fld = _pressed_and_sheared(f0, amp)
        assert reference.is_new_contact(img, f0)
        true = flow.sample_field(fld, grid)
        moved = np.hypot(*true.T) >= 1.0
        got = predict_motion(img, f0, grid)
        ratio = np.hypot(*got[moved].T).sum() / np.hypot(*true[moved].T).sum()
        assert 0.7 < ratio < 1.3, ratio
        assert np.hypot(*(got - true).T).mean() < 0.3 * np.hypot(*true.T).mean()


def test_auto_with_a_reference_is_consistent(mini, grid) -> None:
    for img in (mini.f0, mini.imgs[3]):
        assert not predict_motion(img, img.copy(), grid).any()
        # A global exposure change is no new contact: flow, under the 0.2 px bound.
        brighter = np.clip(img.astype(np.float32) * 1.12 + 4, 0, 255).astype(np.uint8)
        assert reference.contact_energy_ratio(brighter, img) == 1.0
        assert np.hypot(*predict_motion(brighter, img, grid).T).max() < 0.2


@settings(max_examples=25, deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), level=st.integers(0, 255),
       noise=st.floats(0, 60))
def test_ratio_is_finite_on_any_frame(h: int, w: int, level: int, noise: float) -> None:
    rng = np.random.default_rng(h * 41 + w)
    a = np.full((h, w, 3), level, np.uint8)
    b = np.clip(a + rng.normal(0, noise, a.shape), 0, 255).astype(np.uint8)
    r = reference.contact_energy_ratio(b, a)
    assert np.isfinite(r) and r >= 0
    assert reference.contact_energy_ratio(a, a) == 1.0


def test_auto_rejects_flow_only_options_and_bad_gains(mini, grid) -> None:
    # With a reference "auto" runs flow, with flow's options.
    with pytest.raises(ValueError, match=r"^preset: unknown 'slow'"):
        predict_motion(mini.imgs[2], mini.f0, grid, preset="slow")
    np.testing.assert_array_equal(predict_motion(mini.imgs[2], mini.f0, grid, preset="medium"),
                                  flow.flow_motion(mini.imgs[2], mini.f0, grid,
                                                   preset="medium"))
    with pytest.raises(ValueError, match=r"^preset: applies to method='flow' only"):
        predict_motion(mini.imgs[2], None, grid, preset="medium")
    with pytest.raises(ValueError, match=r"^gain: must be a number in \[0, 1000\]"):
        predict_motion(mini.imgs[2], mini.f0, grid, gain=-1.0)
    with pytest.raises(ValueError, match=r"^gain: unknown sensor 'digit'"):
        predict_motion(mini.imgs[2], mini.f0, grid, gain="digit")


def test_near_contact_keeps_the_markers_around_the_contact(mini, grid) -> None:
    w = mini.f0.shape[1]
    for i in (2, 10, 20):
        near = reference.near_contact(mini.imgs[i], mini.f0, grid)
        assert near is not None
        d = np.hypot(*(grid - mini.centres[i]).T)
        # Every marker on the contact counts, none far beyond the reach does.
        assert near[d <= mini.radii[i]].all()
        assert not near[d > mini.radii[i] + 2.5 * reference.CONTACT_REACH * w].any()
        assert 0 < near.sum() < len(grid)
    # Nothing changed (identical frames, a brightness change): no contact to place, all count.
    same = reference.near_contact(mini.f0, mini.f0.copy(), grid)
    assert same is not None and same.all()
    brighter = np.clip(mini.f0.astype(np.float32) * 1.1, 0, 255).astype(np.uint8)
    lit = reference.near_contact(brighter, mini.f0, grid)
    assert lit is not None and lit.all()
    empty = reference.near_contact(mini.imgs[2], mini.f0, grid[:0])
    assert empty is not None and empty.shape == (0,)


def test_near_contact_keeps_a_few_markers_and_checks_its_arguments(mini) -> None:
    # A small contact in the middle of a coarse grid's cell: no marker within the reach, the
    # nearest MIN_NEAR_MARKERS still count (the rigid criterion needs 3).
    img = mini.f0.copy()
    img[100:110, 150:160] = 255
    coarse = np.array([[x, y] for x in (95.0, 215.0) for y in (45.0, 165.0)], np.float32)
    near = reference.near_contact(img, mini.f0, coarse)
    assert near is not None
    assert near.sum() == reference.MIN_NEAR_MARKERS
    assert reference.near_contact(mini.f0, mini.f0.copy(), coarse, fallback=False) is None
    with pytest.raises(ValueError, match=r"^no_contact: shape"):
        reference.near_contact(img, mini.f0[:100], coarse)
    with pytest.raises(ValueError, match=r"^reach: "):
        reference.near_contact(img, mini.f0, coarse, reach=-0.1)
    with pytest.raises(ValueError, match=r"^centres: "):
        reference.near_contact(img, mini.f0, coarse[:, :1])
    with pytest.raises(TypeError, match=r"^img: "):
        reference.near_contact(img.astype(np.float32), mini.f0, coarse)
