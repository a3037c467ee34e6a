"""Markerless -> marker motion: inference from the shipped ONNX model (no torch needed)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import tacswitch as ts
from tacswitch.motion import data as mdata
from tacswitch.motion.evaluate import motion_metrics
from tacswitch.motion.infer import default_model_path, load_model, predict_motion


@pytest.fixture(scope="module")
def press_samples():
    """Pure presses (the motion a markerless frame can show in the simulator)."""
    classes, _ = mdata.split_spec("test_press")
    return [mdata.render_motion_sample("gelsight_mini", np.random.SeedSequence([77, i]),
                                       classes=classes, shear=False) for i in range(8)]


def test_shipped_model_loads_with_metadata():
    assert default_model_path().is_file()
    m = load_model()
    assert m.arch == "unet" and m.work_width == 320 and m.default_centres.shape == (99, 2)
    assert load_model() is m  # one session per model path


def test_output_shape_dtype_no_nan(press_samples):
    s = press_samples[0]
    out = predict_motion(s["image"], centres=s["rest"])
    assert out.shape == (99, 2) and out.dtype == np.float32 and np.isfinite(out).all()
    default = predict_motion(s["image"])
    assert default.shape == (99, 2)
    # Centres off the frame read the border value, never NaN.
    far = predict_motion(s["image"], centres=np.array([[-50, -50], [1e4, 3.0]], np.float32))
    assert np.isfinite(far).all()
    assert predict_motion(s["image"], centres=np.zeros((0, 2), np.float32)).shape == (0, 2)


def test_beats_zero_motion_on_presses(press_samples):
    pred = np.concatenate([predict_motion(s["image"], centres=s["rest"])[s["present"]]
                           for s in press_samples])
    true = np.concatenate([s["displacement"][s["present"]] for s in press_samples])
    ours, zero = motion_metrics(pred, true), motion_metrics(np.zeros_like(true), true)
    assert ours["nan_pct"] == 0.0
    assert ours["e_rmse_mean"] < 0.8 * zero["e_rmse_mean"], (ours, zero)


def test_large_frames_are_downsampled_to_the_working_scale(press_samples):
    import cv2

    s = press_samples[1]
    big = cv2.resize(s["image"], (640, 480), interpolation=cv2.INTER_LINEAR)
    small = predict_motion(s["image"], centres=s["rest"])
    centres_big = (s["rest"] + 0.5) * 2 - 0.5
    large = predict_motion(big, centres=centres_big)
    # Same motion, in the big frame's pixels (twice as many).
    assert np.abs(large - 2 * small).mean() < 0.3
    assert load_model().centres_for(480, 640).shape == (99, 2)


def test_argument_errors(press_samples):
    img = press_samples[0]["image"]
    with pytest.raises(TypeError, match="img"):
        predict_motion(img.astype(np.float32))
    with pytest.raises(ValueError, match="img"):
        predict_motion(img[..., 0])
    with pytest.raises(ValueError, match="centres"):
        predict_motion(img, centres=np.zeros((4, 3), np.float32))
    with pytest.raises(ValueError, match="centres"):
        predict_motion(img, centres=np.array([[np.nan, 1.0]], np.float32))
    with pytest.raises(ValueError, match="ref"):
        predict_motion(img, ref=img[:100])
    with pytest.raises(FileNotFoundError, match="model"):
        predict_motion(img, model="/nonexistent/model.onnx")


def test_slip_detector_accepts_predicted_motion(press_samples):
    s = press_samples[2]
    det = ts.SlipDetector(image_width=320)
    first = det.update(predict_motion(s["image"], centres=s["rest"]))
    assert not first.slip and first.n_compared == 99


def test_inference_does_not_import_torch():
    code = ("import sys, numpy as np, tacswitch.motion as m; "
            "m.predict_motion(np.full((240, 320, 3), 120, np.uint8)); "
            "sys.exit('torch' in sys.modules)")
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
