"""The single-frame ensemble (``method="ensemble"``, what ``"auto"`` runs without a reference):
the mean of the mechanics rule and the learned single-frame model."""

from __future__ import annotations

import numpy as np
import pytest

from tacswitch import predict_motion
from tacswitch.motion import ensemble
from tacswitch.motion.infer import MotionModel, resolve_method
from tacswitch.motion.mechanics import MECHANICS_GAIN, mechanics_motion
from tacswitch.sim.presets import MECHANICS_GAINS


def test_is_the_mean_of_the_rule_and_the_scaled_model(mini, grid) -> None:
    img = mini.imgs[5]
    net = MotionModel("single")
    rule = mechanics_motion(img, None, grid)
    # Its recorded scale belongs with the GelSight's gain; the default gain scales it by the
    # ratio (1 while both are 0.25).
    ratio = MECHANICS_GAIN / MECHANICS_GAINS["gelsight"]
    learned = net(img, centres=grid, gain=net.single_frame_gain * ratio)
    assert np.abs(rule).max() > 0 and np.abs(learned).max() > 0
    got = ensemble.ensemble_motion(img, None, grid)
    np.testing.assert_allclose(got, 0.5 * (rule + learned), atol=1e-5)
    # "auto" without a reference is the ensemble, bit for bit.
    np.testing.assert_array_equal(predict_motion(img, None, grid), got)
    np.testing.assert_array_equal(predict_motion(img, None, grid, method="ensemble"), got)
    assert resolve_method("auto", img, None) == "ensemble"
    # With the no-contact frame only the rule uses it.
    np.testing.assert_allclose(ensemble.ensemble_motion(img, mini.f0, grid),
                               0.5 * (mechanics_motion(img, mini.f0, grid) + learned),
                               atol=1e-5)


def test_the_gain_scales_both_parts(mini, grid) -> None:
    img = mini.imgs[5]
    base = predict_motion(img, None, grid, method="ensemble", gain=0.25)
    np.testing.assert_allclose(predict_motion(img, None, grid, method="ensemble", gain=0.5),
                               2.0 * base, atol=1e-4)
    mini_gain = MECHANICS_GAINS["gelsight_mini"]
    np.testing.assert_allclose(predict_motion(img, None, grid, gain="gelsight_mini"),
                               base * (mini_gain / 0.25), atol=1e-4)
    assert not predict_motion(img, None, grid, method="ensemble", gain=0.0).any()


def test_identical_frames_and_no_centres_give_zero(mini, grid) -> None:
    img = mini.imgs[3]
    assert not predict_motion(img, img.copy(), grid, method="ensemble").any()
    assert not predict_motion(img, img.copy(), grid).any()  # auto: flow, exactly zero
    assert predict_motion(img, None, np.zeros((0, 2), np.float32)).shape == (0, 2)


def test_points_outward_around_real_gelsight_presses() -> None:
    """taxim's real GelSight presses: the ensemble points outward from each recorded contact
    (the direction the gel moves under a press) on most markers beyond the contact."""
    from proxies import motion_proxy as proxy

    data = proxy.load_real_presses("gelsight")
    rest, _ = proxy.marker_grid("gelsight")
    cos = []
    for img, c, r in list(zip(data.imgs, data.centres, data.radii, strict=True))[1::4]:
        out = rest - c
        dist = np.linalg.norm(out, axis=1)
        ring = (dist > 1.2 * r) & (dist < 3.0 * r)
        m = predict_motion(img, None, rest)[ring]
        mag = np.linalg.norm(m, axis=1)
        keep = mag > 1e-3
        cos.extend(((m[keep] * out[ring][keep]).sum(1) / (mag[keep] * dist[ring][keep])).tolist())
    assert len(cos) > 50
    assert np.mean(cos) > 0.6, np.mean(cos)


def test_bad_inputs_name_the_argument(mini, grid) -> None:
    img = mini.imgs[2]
    with pytest.raises(ValueError, match=r"^gain: unknown sensor 'digit'"):
        predict_motion(img, None, grid, method="ensemble", gain="digit")
    with pytest.raises(ValueError, match=r"^gain: must be a number in \[0, 1000\]"):
        predict_motion(img, None, grid, method="ensemble", gain=float("nan"))
    for method in ("ensemble", "mechanics", "outward"):
        with pytest.raises(ValueError,
                           match=r"^gain: must be a number in \[0, 1000\]; got 1e\+300"):
            predict_motion(img, None, grid, method=method, gain=1e300)
    big = predict_motion(img, None, grid, method="ensemble", gain=1000.0)
    assert np.isfinite(big).all()
    with pytest.raises(ValueError, match=r"^algorithm: applies to method='flow' only"):
        predict_motion(img, None, grid, method="ensemble", algorithm="dis")
    with pytest.raises(ValueError, match=r"^ref: shape"):
        predict_motion(img, img[:100], grid, method="ensemble")
    with pytest.raises(FileNotFoundError, match=r"^model: "):
        predict_motion(img, None, grid, method="ensemble", model="no_such_model.onnx")
    from tacswitch.tacdiff.infer import model_path as tacdiff_model

    with pytest.raises(ValueError, match=r"^model: "):  # a TacDiff model, not a motion one
        predict_motion(img, None, grid, method="ensemble", model=tacdiff_model("fast"))
    with pytest.raises(ValueError, match=r"^gain: "):
        ensemble.learned_part(img, grid, -1.0)


def test_refuses_a_learned_half_that_needs_a_reference(mini, grid, monkeypatch) -> None:
    net = MotionModel("default")
    monkeypatch.setattr(net, "use_ref", True)
    monkeypatch.setattr("tacswitch.motion.ensemble.load_model",
                        lambda path=None, device="auto": net)
    with pytest.raises(ValueError, match=r"^model: .*single-frame model"):
        predict_motion(mini.imgs[2], None, grid, method="ensemble", model="default")


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs os.fork")
# Python 3.12+ warns when forking a process with threads (onnxruntime's); that is the point.
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_works_in_a_child_forked_after_use(mini, grid) -> None:
    """A forked child inherits the parent's thread pool without its thread; the ensemble must
    make its own there instead of waiting forever."""
    import multiprocessing as mp

    img = mini.imgs[5]
    want = predict_motion(img, None, grid)  # the parent's pool now exists
    with mp.get_context("fork").Pool(1) as pool:
        got = pool.apply_async(predict_motion, (img, None, grid)).get(timeout=120)
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_concurrent_calls_from_threads_match_serial_ones(mini, grid) -> None:
    """Callers on several threads share the one-thread pool of the learned half: every call
    gets its own frame's answer."""
    from concurrent.futures import ThreadPoolExecutor

    frames = [mini.imgs[i] for i in range(0, 16, 2)]
    want = [predict_motion(f, None, grid) for f in frames]
    with ThreadPoolExecutor(4) as ex:
        got = list(ex.map(lambda f: predict_motion(f, None, grid), frames))
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w, atol=1e-5)
