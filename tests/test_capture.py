"""tacswitch.sim.capture: camera and recorder effects on clean frames."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from tacswitch.sim import capture as C


def _gel(h: int = 96, w: int = 128) -> np.ndarray:
    """A smooth gel-like BGR frame with one crisp black dot in the middle."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.stack([150 + 30 * x / w, 170 - 20 * y / h, 160 + 10 * (x + y) / (w + h)], axis=2)
    img[(x - w / 2) ** 2 + (y - h / 2) ** 2 <= 36] = 0
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_crisp_profile_is_identity() -> None:
    img = _gel()
    out = C.apply(img)
    assert out.dtype == np.uint8 and out is not img
    np.testing.assert_array_equal(out, img)


def test_sample_profile_deterministic_in_range_and_codec_forced() -> None:
    a, b = C.sample_profile(3), C.sample_profile(np.random.default_rng(3))
    assert a == b
    codecs = set()
    for s in range(40):
        p = C.sample_profile(s)
        codecs.add(p.codec)
        assert C.BLUR_SIGMA[0] <= p.blur_sigma <= C.BLUR_SIGMA[1]
        assert C.READ_NOISE[0] <= p.read_noise <= C.READ_NOISE[1]
        if p.codec == "mjpeg":
            assert C.JPEG_QUALITY[0] <= p.quality <= C.JPEG_QUALITY[1]
        if p.codec == "h264":
            assert C.H264_CRF[0] <= p.quality <= C.H264_CRF[1]
        # Forcing the codec keeps every other draw.
        f = C.sample_profile(s, codec="none")
        assert f.codec == "none" and f.blur_sigma == p.blur_sigma and f.gain == p.gain
    assert codecs == set(C.CODECS)


def test_jpeg_is_lossy_and_better_at_higher_quality() -> None:
    img = _gel()
    err = {q: np.abs(C.jpeg_roundtrip(img, q).astype(int) - img).mean() for q in (60, 95)}
    assert 0 < err[95] < err[60]


def test_codecs_ring_around_the_dot_not_on_flat_gel() -> None:
    img = _gel()
    h, w = img.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    r = np.hypot(x - w / 2, y - h / 2)
    ring, flat = (r > 7) & (r < 11), r > 30
    for p in (C.CaptureProfile(codec="mjpeg", quality=70),
              C.CaptureProfile(codec="h264", quality=30)):
        d = np.abs(C.apply(img, p, 0).astype(int) - img).mean(axis=2)
        assert d[ring].mean() > 2 * d[flat].mean() + 0.2, p.codec


def test_h264_unbiased_on_smooth_frames_and_odd_sizes() -> None:
    img = _gel(61, 83)
    img[28:34, 38:45] = 160  # no dot: smooth everywhere
    out = C.h264_roundtrip([img, img], crf=18)
    assert out.shape == (2, 61, 83, 3) and out.dtype == np.uint8
    signed = out.astype(float) - img
    assert abs(signed.mean()) < 0.5
    assert np.abs(signed).mean() < 2.0


def test_h264_single_frame_intra_and_predicted() -> None:
    img = _gel()
    p0 = C.CaptureProfile(codec="h264", quality=26, read_noise=1.0, h264_index=0)
    p3 = C.CaptureProfile(codec="h264", quality=26, read_noise=1.0, h264_index=C.H264_CLIP - 1)
    a, b = C.apply(img, p0, 1), C.apply(img, p3, 1)
    assert a.shape == b.shape == img.shape
    assert not np.array_equal(a, b)
    np.testing.assert_array_equal(a, C.apply(img, p0, 1))  # seeded: deterministic


def test_sensor_noise_level_and_colour_drift() -> None:
    flat = np.full((200, 200, 3), 100, np.uint8)
    noisy = C.sensor_noise(flat.astype(np.float32), read_noise=2.0, shot_noise=0.0, rng=0)
    assert abs(noisy.astype(float).std() - 2.0) < 0.15
    shot = C.sensor_noise(flat.astype(np.float32), read_noise=0.0, shot_noise=0.09, rng=0)
    assert abs(shot.astype(float).std() - 3.0) < 0.2  # sqrt(0.09 * 100)
    drift = C.apply(flat, C.CaptureProfile(gain=(1.1, 1.0, 0.9), offset=(1.0, 0.0, -2.0)))
    np.testing.assert_array_equal(drift[0, 0], [111, 100, 88])


def test_blur_softens_the_edge() -> None:
    img = _gel()
    out = C.apply(img, C.CaptureProfile(blur_sigma=1.0))
    row = img.shape[0] // 2
    col = img.shape[1] // 2 + 6  # on the rim of the dot (radius 6)
    assert out[row, col, 0] > img[row, col, 0]
    assert np.abs(np.diff(out[row, :, 1].astype(int))).max() < np.abs(
        np.diff(img[row, :, 1].astype(int))).max()


def test_apply_sequence_codecs_and_drift() -> None:
    frames = np.stack([_gel()] * 3)
    cases: tuple[tuple[C.Codec, int], ...] = (("none", 90), ("mjpeg", 80), ("h264", 23))
    for codec, q in cases:
        p = C.CaptureProfile(codec=codec, quality=q, read_noise=0.5)
        out = C.apply_sequence(frames, p, 0, gain_drift=0.01)
        assert out.shape == frames.shape and out.dtype == np.uint8
        assert not np.array_equal(out[0], out[2])


@pytest.mark.parametrize("kwargs, name", [
    ({"blur_sigma": -1.0}, "blur_sigma"),
    ({"gain": (1.0, 0.0, 1.0)}, "gain"),
    ({"offset": (1.0, 2.0)}, "offset"),
    ({"codec": "png"}, "codec"),
    ({"codec": "mjpeg", "quality": 0}, "quality"),
    ({"codec": "h264", "quality": 60}, "quality"),
    ({"preset": "warp"}, "preset"),
    ({"h264_index": C.H264_CLIP}, "h264_index"),
])
def test_bad_profile_names_the_field(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        C.CaptureProfile(**kwargs)


def test_bad_input_errors() -> None:
    with pytest.raises(TypeError, match="img"):
        C.apply(_gel().astype(np.float32))
    with pytest.raises(ValueError, match="img"):
        C.apply(np.zeros((8, 8), np.uint8))
    with pytest.raises(TypeError, match="profile"):
        C.apply(_gel(), "h264")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="codec"):
        C.sample_profile(0, codec="avi")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="frames"):
        C.apply_sequence([])
    with pytest.raises(ValueError, match="gain_drift"):
        C.apply_sequence([_gel()], gain_drift=-1.0)
    with pytest.raises(ValueError, match="crf"):
        C.h264_roundtrip([_gel()], crf=52)


@pytest.mark.parametrize("kwargs, name", [
    ({"crf": 52}, "crf"), ({"crf": -1}, "crf"), ({"crf": "23"}, "crf"), ({"crf": 1.5}, "crf"),
    ({"crf": 23, "preset": "warp"}, "preset"),
])
def test_h264_roundtrip_checks_its_arguments_before_pyav(
        monkeypatch: pytest.MonkeyPatch, kwargs: dict, name: str) -> None:
    # Without PyAV (the base install) a bad argument is still named, not "needs PyAV".
    monkeypatch.setitem(sys.modules, "av", None)
    with pytest.raises(ValueError, match=f"^{name}:"):
        C.h264_roundtrip([_gel()], **kwargs)
    with pytest.raises(ImportError, match="PyAV"):  # good arguments: what is missing
        C.h264_roundtrip([_gel()], crf=23)
