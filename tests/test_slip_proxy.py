"""Real-texture grasp videos (``tacswitch.motion.slip_proxy``) and slip scoring on videos."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from tacswitch.motion.evaluate import slip_on_videos

pytest.importorskip("taxim")

from tacswitch.motion import proxy
from tacswitch.motion.infer import predict_motion
from tacswitch.motion.slip_proxy import real_grasp
from tacswitch.sim.sequences import SLIP_ONSET_FRAMES


@pytest.fixture(scope="module")
def mini() -> proxy.RealPresses:
    return proxy.load_real_presses("gelsight_mini").subset(slice(0, None, 8))


def test_grasp_video_shape_labels_and_determinism(mini: proxy.RealPresses) -> None:
    g = real_grasp(mini, 1, "slip", codec="none", seed=3)
    assert g.frames.shape == (30, 240, 320, 3) and g.frames.dtype == np.uint8
    assert g.grasp_start == 15 and g.onset == 15 + SLIP_ONSET_FRAMES
    assert g.rest.shape[1] == 2 and g.kind == "slip" and g.press == 1
    again = real_grasp(mini, 1, "slip", codec="none", seed=3)
    assert np.array_equal(g.frames, again.frames)
    # The grasp's draws do not depend on the capture, so captures compare on one grasp.
    coded = real_grasp(mini, 1, "slip", codec="mjpeg", quality=70, seed=3)
    assert {k: v for k, v in coded.params.items() if k not in ("codec", "quality")} == \
        {k: v for k, v in g.params.items() if k not in ("codec", "quality")}
    assert coded.params["quality"] == 70 and not np.array_equal(coded.frames, g.frames)


def test_slip_moves_the_imprint_and_hold_does_not(mini: proxy.RealPresses) -> None:
    """Lossless videos: on slip the flow from the grasp start grows past the paper's threshold
    (scaled to 320 px: 1.625 px); on hold it stays well below it."""
    peaks = {}
    for kind in ("hold", "slip"):
        g = real_grasp(mini, 1, kind, codec="none", seed=0)
        ref = g.frames[g.grasp_start]
        m = predict_motion(g.frames[-1], ref, g.rest)
        peaks[kind] = float(np.linalg.norm(m, axis=1).max())
    assert peaks["slip"] > 1.625 > 2 * peaks["hold"]


def test_h264_is_one_stream(mini: proxy.RealPresses) -> None:
    """Inter-frame coding: two hold frames of one H.264 video differ far less than the same
    frame coded as two separate I-frames would (the stream reuses its reference)."""
    g = real_grasp(mini, 0, "hold", codec="h264", quality=28, seed=0)
    a, b = g.frames[20].astype(int), g.frames[25].astype(int)
    assert np.abs(a - b).mean() < 1.5


def test_errors_name_the_argument(mini: proxy.RealPresses) -> None:
    with pytest.raises(ValueError, match="kind"):
        real_grasp(mini, 0, "drop")
    with pytest.raises(ValueError, match="codec"):
        real_grasp(mini, 0, "hold", codec="av1")
    with pytest.raises(ValueError, match="n_frames"):
        real_grasp(mini, 0, "hold", n_frames=4)
    with pytest.raises(ValueError, match="index"):
        real_grasp(mini, 99, "hold")


def _video(kind: str) -> SimpleNamespace:
    frames = np.zeros((12, 16, 20, 3), np.uint8)
    return SimpleNamespace(frames=frames, rest=np.array([[5.0, 5.0], [12.0, 9.0]], np.float32),
                           kind=kind, grasp_start=6, onset=8)


def test_slip_on_videos_counts_detections_and_delays() -> None:
    grasps = [_video("slip"), _video("hold"), _video("vibration")]

    def still(img: np.ndarray, ref: np.ndarray, rest: np.ndarray) -> np.ndarray:
        return np.zeros((len(rest), 2), np.float32)

    calls = {"n": 0}

    def sliding(img: np.ndarray, ref: np.ndarray, rest: np.ndarray) -> np.ndarray:
        # 7 px to the right from the 4th frame the detector sees (index 9 of the video) on.
        calls["n"] += 1
        k = (calls["n"] - 1) % 6
        return np.full((len(rest), 2), [7.0 if k >= 3 else 0.0, 0.0], np.float32)

    res = slip_on_videos({"still": still, "sliding": sliding}, grasps,
                         criteria={"displacement": {}}, smooth_frames=1)
    s = res[("still", "displacement")]
    assert (s["correct"], s["n"], s["slips_found"], s["fa_hold"], s["fa_vibration"]) == \
        (2, 3, 0, 0, 0)
    m = res[("sliding", "displacement")]
    assert (m["slips_found"], m["fa_hold"], m["fa_vibration"], m["correct"]) == (1, 1, 1, 1)
    assert m["delays"] == [9 - 8]
    with pytest.raises(ValueError, match="smooth_frames"):
        slip_on_videos({"still": still}, grasps, smooth_frames=0)
