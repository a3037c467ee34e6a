"""``MarkerlessTracker``: motion from rest over a markerless video that starts at the no-contact
frame (real taxim GelSight Mini presses; a known shear of the pressed frame)."""

from __future__ import annotations

import numpy as np
import pytest

from tacswitch.motion import mechanics, proxy
from tacswitch.motion.sequence import MarkerlessTracker


def test_press_then_shear_is_the_rule_plus_the_flow_from_the_anchor(mini, grid) -> None:
    i = 6
    tr = MarkerlessTracker(mini.f0, grid, gain="gelsight")
    assert not tr.update(mini.f0.copy()).any()  # no contact yet: exactly zero
    assert tr.anchor_index is None
    press = tr.update(mini.imgs[i])
    np.testing.assert_array_equal(press, mechanics.mechanics_motion(mini.imgs[i], mini.f0, grid,
                                                                   gain=0.25))
    assert tr.anchor_index == 1
    fld = proxy.random_field("shear", tuple(mini.centres[i]), float(mini.radii[i]), 10.0,
                             np.random.default_rng(4), shape=(240, 320))
    sheared = proxy.warp(mini.imgs[i], fld)
    true = press + fld.at(grid + press)
    got = tr.update(sheared)
    err = np.linalg.norm(got - true, axis=1).mean()
    assert err < 0.3 * np.linalg.norm(true, axis=1).mean()
    # The pair alone (auto: the rule against the no-contact frame) cannot see the shear.
    from tacswitch import predict_motion

    pair = predict_motion(sheared, mini.f0, grid, gain="gelsight")
    assert np.linalg.norm(pair - true, axis=1).mean() > 2 * err
    # Released: back to the no-contact frame, exactly zero, and the anchor is gone.
    assert not tr.update(mini.f0.copy()).any()
    assert tr.anchor_index is None


def test_reset_and_bad_inputs(mini, grid) -> None:
    tr = MarkerlessTracker(mini.f0, grid)
    tr.update(mini.imgs[3])
    assert tr.anchor_index == 0
    tr.reset()
    assert tr.anchor_index is None
    with pytest.raises(ValueError, match=r"^frame: shape \(120, 320, 3\) does not match"):
        tr.update(mini.imgs[3][:120])
    with pytest.raises(ValueError, match=r"^no_contact: expected a BGR"):
        MarkerlessTracker(mini.f0[..., 0], grid)
    with pytest.raises(ValueError, match=r"^gain: unknown sensor"):
        MarkerlessTracker(mini.f0, grid, gain="digit")
    with pytest.raises(ValueError, match=r"^centres:"):
        MarkerlessTracker(mini.f0, np.zeros((3, 3), np.float32))
    empty = MarkerlessTracker(mini.f0, np.zeros((0, 2), np.float32))
    assert empty.update(mini.imgs[2]).shape == (0, 2)
    default = MarkerlessTracker(mini.f0)
    assert default.update(mini.imgs[2]).shape == (99, 2)


def test_video_that_starts_in_contact_anchors_on_its_first_frame(mini, grid) -> None:
    i = 6
    tr = MarkerlessTracker(None, grid, gain="gelsight")
    first = tr.update(mini.imgs[i])
    np.testing.assert_array_equal(first, mechanics.mechanics_motion(mini.imgs[i], None, grid,
                                                                   gain=0.25))
    assert tr.anchor_index == 0
    # The same frame again: the flow from the anchor is exactly zero, the motion unchanged.
    np.testing.assert_array_equal(tr.update(mini.imgs[i].copy()), first)
    fld = proxy.random_field("shear", tuple(mini.centres[i]), float(mini.radii[i]), 10.0,
                             np.random.default_rng(4), shape=(240, 320))
    true = first + fld.at(grid + first)
    got = tr.update(proxy.warp(mini.imgs[i], fld))
    err = np.linalg.norm(got - true, axis=1).mean()
    assert err < 0.3 * np.linalg.norm(true, axis=1).mean()
    assert tr.anchor_index == 0  # no no-contact frame: the contact cannot be seen to end
    with pytest.raises(ValueError, match=r"^frame: shape \(120, 320, 3\) does not match the "
                                         r"first frame"):
        tr.update(mini.imgs[i][:120])
    tr.reset()
    tr.update(mini.imgs[3])
    assert tr.anchor_index == 0
    assert MarkerlessTracker().update(mini.imgs[2]).shape == (99, 2)
    with pytest.raises(ValueError, match=r"^frame: expected a BGR"):
        MarkerlessTracker(None).update(mini.imgs[2][..., 0])
