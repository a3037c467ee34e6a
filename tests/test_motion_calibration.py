"""Per-sensor press gains of the single-frame rules and their self-calibration on real frames
(motion.calibration, predict_motion's ``gain``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tacswitch.motion.calibration import calibrate_press_gain
from tacswitch.motion.infer import predict_motion
from tacswitch.motion.mechanics import MECHANICS_GAIN, mechanics_field, mechanics_motion
from tacswitch.sim.presets import MECHANICS_GAINS, OUTWARD_GAINS


@pytest.fixture(scope="module")
def gelsight() -> tuple[np.ndarray, np.ndarray]:
    """taxim's real GelSight no-contact frame and six of its odd-index presses (640 x 480, the
    capture size): the shipped gain was fitted on the even ones."""
    taxim = pytest.importorskip("taxim")
    pack = np.load(Path(taxim.__file__).parent / "calib" / "gelsight" / "dataPack.npz")
    return pack["f0"], pack["imgs"][1:12:2]


def test_shipped_gains_are_per_sensor_and_the_default_is_between() -> None:
    # The real GelSight gel moves, the real Mini's not measurably: gains ~7x apart at least.
    assert MECHANICS_GAINS["gelsight"] > 5 * MECHANICS_GAINS["gelsight_mini"]
    assert OUTWARD_GAINS["gelsight"] > 5 * OUTWARD_GAINS["gelsight_mini"]
    assert MECHANICS_GAINS["gelsight_mini"] <= MECHANICS_GAIN <= MECHANICS_GAINS["gelsight"]


def test_self_calibration_recovers_the_shipped_gelsight_gain(gelsight: tuple) -> None:
    """Held-out presses, no marker grid, no recorded contacts: within 35 % of the shipped value
    (fitted by a different estimator on the other presses), far from the old 1.02."""
    f0, imgs = gelsight
    r = calibrate_press_gain(f0, imgs)
    ship = MECHANICS_GAINS["gelsight"]
    assert abs(r.gain - ship) < 0.35 * ship, (r, ship)
    assert r.n_frames == len(imgs) and r.n_patches > 1000
    assert r.explained > 0.3 and 0.1 < r.peak < 0.6 and 0 < r.stderr < 0.05
    assert r.method == "ensemble"  # the default: what predict_motion runs


def test_the_rule_alone_gets_its_own_gain_and_explains_less(gelsight: tuple) -> None:
    """The ensemble and the rule were scaled on the same real presses, so their gains agree;
    on held-out presses the ensemble explains more of the grain's real motion."""
    f0, imgs = gelsight
    ens = calibrate_press_gain(f0, imgs)
    rule = calibrate_press_gain(f0, imgs, method="mechanics")
    assert rule.method == "mechanics"
    assert abs(ens.gain - rule.gain) < 0.1 * rule.gain, (ens, rule)
    assert ens.explained > rule.explained, (ens, rule)


def test_self_calibration_scales_with_a_known_outward_field(gelsight: tuple) -> None:
    """The presses warped by ``k`` times the rule's own unit-gain field (their grain moves with
    it): the fitted gain rises by ``k``."""
    import cv2
    from proxies.motion_proxy import warp_dense

    f0, imgs = gelsight
    imgs = imgs[:4]
    k = 0.3
    warped = []
    for im in imgs:
        fld, st = mechanics_field(im, None, gain=1.0)
        h, w = im.shape[:2]
        # Coarse cell centres sit at (j + 0.5) st - 0.5: an INTER_LINEAR resize by st maps them.
        dense = cv2.resize(fld, (fld.shape[1] * st, fld.shape[0] * st),
                           interpolation=cv2.INTER_LINEAR)[:h, :w]
        warped.append(warp_dense(im, (k * dense).astype(np.float32)))
    # The field added is the rule's own, so the rule's gain must rise by exactly k.
    base = calibrate_press_gain(f0, imgs, method="mechanics").gain
    up = calibrate_press_gain(f0, np.stack(warped), method="mechanics").gain
    assert abs((up - base) - k) < 0.08, (base, up)


def test_predict_motion_gain_by_sensor_and_number(gelsight: tuple) -> None:
    img = gelsight[1][0]
    pts = np.array([[100.0, 100.0], [540.0, 380.0], [320.0, 60.0]], np.float32)
    unit = mechanics_motion(img, None, pts, gain=1.0)
    assert np.abs(unit).max() > 0.5
    for g in ("gelsight", "gelsight_mini"):
        got = predict_motion(img, None, pts, method="mechanics", gain=g)
        np.testing.assert_allclose(got, MECHANICS_GAINS[g] * unit, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(predict_motion(img, None, pts, method="mechanics", gain=0.5),
                               0.5 * unit, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(predict_motion(img, None, pts, method="mechanics"),
                               MECHANICS_GAIN * unit, rtol=1e-5, atol=1e-6)
    assert not predict_motion(img, None, pts, method="mechanics", gain=0).any()
    out = predict_motion(img, None, pts, method="outward", gain="gelsight")
    base = predict_motion(img, None, pts, method="outward", gain=1.0)
    np.testing.assert_allclose(out, OUTWARD_GAINS["gelsight"] * base, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("kw, match", [
    ({"method": "mechanics", "gain": -0.1}, "gain"),
    ({"method": "mechanics", "gain": float("nan")}, "gain"),
    ({"method": "mechanics", "gain": True}, "gain"),
    ({"method": "mechanics", "gain": "digit"}, "gain: unknown sensor"),
    ({"method": "outward", "gain": [1.0]}, "gain"),
    ({"method": "flow", "gain": 1.0}, "gain: applies"),
    ({"method": "model", "gain": "gelsight"}, "gain: applies"),
])
def test_predict_motion_rejects_a_bad_gain(kw: dict, match: str) -> None:
    img = np.full((48, 64, 3), 128, np.uint8)
    with pytest.raises(ValueError, match=match):
        predict_motion(img, img, np.zeros((1, 2), np.float32), **kw)


def test_calibration_rejects_bad_inputs(gelsight: tuple) -> None:
    f0, imgs = gelsight
    with pytest.raises(ValueError, match=r"^frames: need at least one"):
        calibrate_press_gain(f0, [])
    with pytest.raises(ValueError, match=r"^frames: shape"):
        calibrate_press_gain(f0, [imgs[0][:240]])
    with pytest.raises(ValueError, match=r"^frames: expected a sequence"):
        calibrate_press_gain(f0, imgs[0])
    with pytest.raises(TypeError, match=r"^frames"):
        calibrate_press_gain(f0, 3)
    with pytest.raises(ValueError, match=r"^no_contact"):
        calibrate_press_gain(f0[..., 0], imgs[:1])
    with pytest.raises(ValueError, match=r"^patch"):
        calibrate_press_gain(f0, imgs[:1], patch=4)
    with pytest.raises(ValueError, match=r"^step"):
        calibrate_press_gain(f0, imgs[:1], step=0)
    with pytest.raises(ValueError, match=r"^method: unknown 'flow'"):
        calibrate_press_gain(f0, imgs[:1], method="flow")
    with pytest.raises(ValueError, match=r"^min_peak"):
        calibrate_press_gain(f0, imgs[:1], min_peak=1.5)
    with pytest.raises(ValueError, match=r"^centres"):
        calibrate_press_gain(f0, imgs[:1], centres=np.zeros((0, 2), np.float32))
    # Nothing pressed: no imprint, no gain to fit.
    with pytest.raises(ValueError, match=r"^frames: no press visible"):
        calibrate_press_gain(f0, [f0])
