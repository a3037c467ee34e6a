"""Real-texture grasp videos (``proxies.slip_proxy``) and slip scoring on videos."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("taxim")

from proxies import motion_proxy as proxy
from proxies.slip_proxy import TEMPORAL_NOISE, real_grasp

from tacswitch.motion.infer import predict_motion
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
    """Inter-frame coding: on a hold, x264 skips most blocks of a frame (they repeat the
    previous one exactly), while MJPEG codes every frame anew with its fresh noise."""
    same = {}
    for codec in ("h264", "mjpeg"):
        g = real_grasp(mini, 0, "hold", codec=codec, seed=0)
        same[codec] = float(np.median([np.mean(g.frames[t] == g.frames[t + 1])
                                       for t in range(g.grasp_start, len(g.frames) - 1)]))
    assert same["h264"] > 0.75 > 0.6 > same["mjpeg"]


def test_drawn_shear_is_reported_as_applied(mini: proxy.RealPresses) -> None:
    g = real_grasp(mini, 2, "hold", codec="none", seed=1)
    p = g.params
    assert p["fps"] == 25.0 and p["read_noise"] == TEMPORAL_NOISE["gelsight_mini"]
    assert p["shear_px"] == pytest.approx(p["shear_drawn_px"], rel=0.3) or p["capped"]


def test_errors_name_the_argument(mini: proxy.RealPresses) -> None:
    with pytest.raises(ValueError, match="kind"):
        real_grasp(mini, 0, "drop")
    with pytest.raises(ValueError, match="codec"):
        real_grasp(mini, 0, "hold", codec="av1")
    with pytest.raises(ValueError, match="n_frames"):
        real_grasp(mini, 0, "hold", n_frames=4)
    with pytest.raises(ValueError, match="index"):
        real_grasp(mini, 99, "hold")


def test_temporal_noise_is_what_the_real_recordings_show() -> None:
    """The fresh noise per frame is the temporal noise measured on taxim's recordings (the
    constant's recipe, recomputed)."""
    import cv2

    for sensor in ("gelsight", "gelsight_mini"):
        d = proxy.load_real_presses(sensor)
        h, w = d.f0.shape[:2]
        per_pair = []
        for i in range(0, len(d.imgs) - 1, 2):
            diff = d.imgs[i].astype(np.float32) - d.imgs[i + 1].astype(np.float32)
            hp = diff - cv2.GaussianBlur(diff, (0, 0), 3)
            per_pair.append(hp[:h // 5, :w // 5].reshape(-1, 3).std(0) / np.sqrt(2))
        measured = float(np.median(per_pair, axis=0).mean())
        assert measured == pytest.approx(TEMPORAL_NOISE[sensor], abs=0.02), sensor
