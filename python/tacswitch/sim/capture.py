"""What a camera and a recorder make of a clean frame: optics, sensor, colour drift, codec.

A simulated (or painted) tactile frame is exact; a real one went through a lens (blur), an image
sensor (shot and read noise, 8-bit quantisation), an auto-exposure / white-balance loop that drifts
(per-channel gain and offset) and, almost always, a lossy recorder: MJPEG from a USB camera or
H.264 from a video file. The codec matters most for marker removal: it rings around high-contrast
dots (the "dark ring" a fill must not copy) and smooths their edges. This module applies those
steps, in that physical order, to uint8 BGR frames:

1. optical blur: Gaussian, ``blur_sigma`` px (:func:`blur`);
2. exposure and white balance: ``out = gain[c] * in + offset[c]`` per BGR channel
   (:func:`colour_drift`);
3. sensor noise: shot noise (variance ``shot_noise * value``, grey levels²) plus read noise
   (``read_noise`` grey levels, sigma), then rounding to uint8 (:func:`sensor_noise`);
4. lossy capture: ``"mjpeg"`` (JPEG at ``quality`` 1..100 with 4:2:0 chroma, as USB cameras
   send it; OpenCV's encoder, :func:`jpeg_roundtrip`) or ``"h264"`` (libx264 through PyAV,
   yuv420p, constant rate factor ``quality`` 0..51, x264 ``preset``; :func:`h264_roundtrip`).

:func:`sample_profile` draws a random but realistic :class:`CaptureProfile` from a seeded
``numpy.random.Generator``; :func:`apply` captures one frame, :func:`apply_sequence` a video
(one encoder over all frames, so inter-frame coding is real). For a single frame under H.264,
:func:`apply` encodes a short clip of the same scene with fresh sensor noise in each frame and
returns frame ``profile.h264_index`` of it: 0 is the intra-coded first frame, later ones are
predicted frames as most of a recording is.

Only the frame WITH markers should be captured; the markerless training target stays clean.

PyAV (``pip install tacswitch[train]``, module ``av``) is needed for H.264 only; everything else
uses numpy and OpenCV.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

Codec = Literal["none", "mjpeg", "h264"]
#: A generator, or a seed for ``numpy.random.default_rng`` (an int or a sequence of ints).
Seed = np.random.Generator | int | Sequence[int] | None
CODECS: tuple[str, ...] = ("none", "mjpeg", "h264")
X264_PRESETS: tuple[str, ...] = ("ultrafast", "superfast", "veryfast", "faster", "fast",
                                 "medium", "slow")

#: Ranges :func:`sample_profile` draws from (uniform unless noted). Chosen to span what USB
#: tactile cameras and their recordings show: lens blur under ~1 px sigma, a few grey levels of
#: noise, +-10 % exposure and +-5 % white-balance drift, JPEG quality 60-95 (webcam MJPEG streams
#: sit around 75-90) and x264 CRF 18-30 (18 is "visually lossless", 23 the default, 28-30 what
#: small recordings use).
BLUR_SIGMA = (0.3, 1.2)
READ_NOISE = (0.5, 2.5)
SHOT_NOISE = (0.0, 0.04)
EXPOSURE = (0.9, 1.1)
WHITE_BALANCE = (0.95, 1.05)
OFFSET = (-3.0, 3.0)
JPEG_QUALITY = (60, 95)
H264_CRF = (18, 30)
#: Codec probabilities of :func:`sample_profile` (none, mjpeg, h264).
CODEC_WEIGHTS = (0.2, 0.4, 0.4)
#: x264 presets a recorder plausibly uses (ultrafast also turns off the deblocking filter).
SAMPLED_PRESETS = ("ultrafast", "veryfast", "medium")
#: Frames of the clip :func:`apply` encodes for one H.264 frame (it returns one of them).
H264_CLIP = 4
#: Frame rate written into the H.264 stream (it only scales the rate control's time base).
H264_FPS = 30


@dataclass(frozen=True)
class CaptureProfile:
    """How one camera + recorder turns a clean frame into what the user gets.

    Attributes:
        blur_sigma: Gaussian optical blur, px (0: none).
        read_noise: read noise, grey levels (sigma, 0: none).
        shot_noise: shot-noise variance per grey level of signal (grey levels; 0: none), so a
            pixel of value v gets noise of sigma ``sqrt(shot_noise * v)``.
        gain: per-channel B, G, R gain (exposure times white balance; 1: none).
        offset: per-channel B, G, R offset, grey levels (black level drift; 0: none).
        codec: ``"none"`` (lossless), ``"mjpeg"`` or ``"h264"``.
        quality: JPEG quality 1..100 (mjpeg) or x264 CRF 0..51 (h264; lower is better).
        preset: x264 preset (h264 only).
        h264_index: which frame of the clip :func:`apply` returns, 0 .. ``H264_CLIP - 1``
            (0: the intra-coded frame).
    """

    blur_sigma: float = 0.0
    read_noise: float = 0.0
    shot_noise: float = 0.0
    gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    codec: Codec = "none"
    quality: int = 90
    preset: str = "veryfast"
    h264_index: int = H264_CLIP - 1

    def __post_init__(self) -> None:
        for name in ("blur_sigma", "read_noise", "shot_noise"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{name}: must be a finite number >= 0; got {v!r}")
        for name in ("gain", "offset"):
            v = getattr(self, name)
            if len(v) != 3 or not all(np.isfinite(x) for x in v):
                raise ValueError(f"{name}: expected 3 finite numbers (B, G, R); got {v!r}")
        if any(g <= 0 for g in self.gain):
            raise ValueError(f"gain: must be > 0; got {self.gain!r}")
        if self.codec not in CODECS:
            raise ValueError(f"codec: expected one of {CODECS}; got {self.codec!r}")
        if self.codec == "mjpeg" and not 1 <= self.quality <= 100:
            raise ValueError(f"quality: JPEG quality must be 1..100; got {self.quality!r}")
        if self.codec == "h264" and not 0 <= self.quality <= 51:
            raise ValueError(f"quality: x264 CRF must be 0..51; got {self.quality!r}")
        if self.preset not in X264_PRESETS:
            raise ValueError(f"preset: expected one of {X264_PRESETS}; got {self.preset!r}")
        if not 0 <= self.h264_index < H264_CLIP:
            raise ValueError(f"h264_index: must be 0..{H264_CLIP - 1}; got {self.h264_index!r}")


#: A lossless, noise-free capture (the identity up to nothing).
CRISP = CaptureProfile()


def sample_profile(rng: Seed = None, *,
                   codec: Codec | None = None) -> CaptureProfile:
    """A random realistic :class:`CaptureProfile` (ranges: the module constants).

    Args:
        rng: a ``numpy.random.Generator`` or a seed; the result is deterministic given it.
        codec: force this codec (default: drawn with :data:`CODEC_WEIGHTS`).
    """
    g = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    if codec is not None and codec not in CODECS:
        raise ValueError(f"codec: expected one of {CODECS}; got {codec!r}")
    exposure = g.uniform(*EXPOSURE)
    wb = g.uniform(*WHITE_BALANCE, size=3)
    # Draw every field whatever the codec, so forcing the codec keeps the other fields.
    blur = float(g.uniform(*BLUR_SIGMA))
    read = float(g.uniform(*READ_NOISE))
    shot = float(g.uniform(*SHOT_NOISE))
    off = g.uniform(*OFFSET, size=3)
    drawn = CODECS[int(g.choice(len(CODECS), p=CODEC_WEIGHTS))]
    jpeg_q = int(g.integers(JPEG_QUALITY[0], JPEG_QUALITY[1] + 1))
    crf = int(g.integers(H264_CRF[0], H264_CRF[1] + 1))
    preset = str(SAMPLED_PRESETS[int(g.integers(len(SAMPLED_PRESETS)))])
    # A quarter of single H.264 frames are intra-coded, the rest predicted.
    index = 0 if g.random() < 0.25 else int(g.integers(1, H264_CLIP))
    chosen: Codec = codec if codec is not None else drawn  # type: ignore[assignment]
    return CaptureProfile(
        blur_sigma=blur, read_noise=read, shot_noise=shot,
        gain=tuple(float(exposure * w) for w in wb),  # type: ignore[arg-type]
        offset=tuple(float(o) for o in off),  # type: ignore[arg-type]
        codec=chosen, quality=jpeg_q if chosen == "mjpeg" else crf if chosen == "h264" else 90,
        preset=preset, h264_index=index)


def _as_bgr(img: Any, name: str = "img") -> NDArray[np.uint8]:
    if not isinstance(img, np.ndarray):
        raise TypeError(f"{name}: expected a numpy array, got {type(img).__name__}")
    if img.dtype != np.uint8:
        raise TypeError(f"{name}: expected dtype uint8, got {img.dtype}")
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 2 or img.shape[1] < 2:
        raise ValueError(f"{name}: expected an H x W x 3 BGR image (H, W >= 2); "
                         f"got shape {img.shape}")
    return np.ascontiguousarray(img)


def _rng(rng: Seed) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def blur(img: NDArray[np.floating] | NDArray[np.uint8], sigma: float) -> NDArray[np.float32]:
    """Gaussian optical blur of sigma ``sigma`` px (float32 out; reflect-101 borders, like a
    lens seeing gel beyond the crop). ``sigma`` 0 returns a float32 copy."""
    import cv2

    out = np.asarray(img, np.float32)
    if sigma <= 0:
        return out.copy()
    return np.asarray(cv2.GaussianBlur(out, (0, 0), sigmaX=float(sigma), sigmaY=float(sigma),
                                       borderType=cv2.BORDER_REFLECT_101), np.float32)


def colour_drift(img: NDArray[np.floating], gain: Sequence[float], offset: Sequence[float]
                 ) -> NDArray[np.float32]:
    """``gain[c] * img + offset[c]`` per BGR channel, float32 (not clipped)."""
    g = np.asarray(gain, np.float32).reshape(1, 1, 3)
    o = np.asarray(offset, np.float32).reshape(1, 1, 3)
    return (np.asarray(img, np.float32) * g + o).astype(np.float32)


def sensor_noise(img: NDArray[np.floating], read_noise: float, shot_noise: float,
                 rng: Seed = None) -> NDArray[np.uint8]:
    """Adds shot noise (variance ``shot_noise * value``) and read noise (sigma ``read_noise``),
    both in grey levels, and quantises to uint8 (round, saturate) as the camera's ADC does."""
    x = np.asarray(img, np.float32)
    var = np.float32(read_noise) ** 2 + np.float32(shot_noise) * np.clip(x, 0, None)
    if read_noise > 0 or shot_noise > 0:
        g = _rng(rng)
        x = x + g.standard_normal(x.shape, dtype=np.float32) * np.sqrt(var)
    return np.clip(np.rint(x), 0, 255).astype(np.uint8)


def jpeg_roundtrip(img: NDArray[np.uint8], quality: int) -> NDArray[np.uint8]:
    """Encodes and decodes one BGR frame as JPEG (OpenCV/libjpeg, 4:2:0 chroma), as an MJPEG
    camera stream delivers it. ``quality`` 1..100."""
    import cv2

    arr = _as_bgr(img)
    if not 1 <= int(quality) <= 100:
        raise ValueError(f"quality: JPEG quality must be 1..100; got {quality!r}")
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
    if hasattr(cv2, "IMWRITE_JPEG_SAMPLING_FACTOR"):
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420]
    ok, buf = cv2.imencode(".jpg", arr, params)
    if not ok:
        raise RuntimeError("OpenCV could not encode the frame as JPEG")
    out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return np.ascontiguousarray(out)


def _av() -> Any:
    try:
        import av
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("H.264 capture needs PyAV: pip install 'tacswitch[train]' "
                          "(or pip install av)") from exc
    return av


def h264_roundtrip(frames: Sequence[NDArray[np.uint8]] | NDArray[np.uint8], crf: int,
                   preset: str = "veryfast") -> NDArray[np.uint8]:
    """Encodes BGR frames as one H.264 stream (libx264 via PyAV, yuv420p, constant rate
    factor ``crf``, x264 ``preset``, one thread so the result is deterministic) and decodes it.

    Args:
        frames: ``T x H x W x 3`` uint8 BGR (or a list of ``H x W x 3``), all the same size.
            Odd sizes are padded by edge replication for 4:2:0 and cropped back.
        crf: 0..51 (18 visually lossless, 23 x264's default, 28-30 small files).
        preset: one of :data:`X264_PRESETS`.

    Returns:
        ``T x H x W x 3`` uint8 BGR, the decoded frames in display order.
    """
    import cv2

    # The arguments first: a mistake is named even where PyAV is missing.
    if isinstance(crf, bool) or not isinstance(crf, (int, np.integer)) or not 0 <= crf <= 51:
        raise ValueError(f"crf: must be an integer 0..51; got {crf!r}")
    if not isinstance(preset, str) or preset not in X264_PRESETS:
        raise ValueError(f"preset: expected one of {X264_PRESETS}; got {preset!r}")
    seq = [_as_bgr(f, "frames") for f in frames]
    if not seq:
        raise ValueError("frames: expected at least one frame")
    h, w = seq[0].shape[:2]
    if any(f.shape != seq[0].shape for f in seq):
        raise ValueError("frames: all frames must have the same shape")
    av = _av()
    ph, pw = h + h % 2, w + w % 2
    enc = av.CodecContext.create("libx264", "w")
    enc.width, enc.height = pw, ph
    enc.pix_fmt = "yuv420p"
    enc.time_base = Fraction(1, H264_FPS)
    enc.framerate = Fraction(H264_FPS, 1)
    enc.options = {"crf": str(int(crf)), "preset": preset, "threads": "1"}
    packets = []
    for i, f in enumerate(seq):
        if (ph, pw) != (h, w):
            f = np.pad(f, ((0, ph - h), (0, pw - w), (0, 0)), mode="edge")
        # OpenCV's BT.601 conversion both ways: PyAV's default swscale path (bgr24 <->
        # yuv420p) shifts a round trip by -1.4 to -2.7 grey levels per channel before any
        # coding, a bias no codec adds (recorders' own offsets are in colour_drift).
        vf = av.VideoFrame.from_ndarray(cv2.cvtColor(f, cv2.COLOR_BGR2YUV_I420), format="yuv420p")
        vf.pts = i
        packets += enc.encode(vf)
    packets += enc.encode(None)
    dec = av.CodecContext.create("h264", "r")
    decoded = []
    for p in packets:
        decoded += dec.decode(p)
    decoded += dec.decode(None)
    if len(decoded) != len(seq):
        raise RuntimeError(f"H.264 round trip returned {len(decoded)} frames for {len(seq)}")
    decoded.sort(key=lambda fr: fr.pts)
    return np.stack([cv2.cvtColor(fr.to_ndarray(format="yuv420p"), cv2.COLOR_YUV2BGR_I420)[:h, :w]
                     for fr in decoded])


def _sensor(img: NDArray[np.uint8], profile: CaptureProfile, rng: np.random.Generator
            ) -> NDArray[np.uint8]:
    """Optics, colour drift and sensor noise of one frame (no codec)."""
    x = blur(img, profile.blur_sigma)
    x = colour_drift(x, profile.gain, profile.offset)
    return sensor_noise(x, profile.read_noise, profile.shot_noise, rng)


def apply(img: NDArray[np.uint8], profile: CaptureProfile = CRISP,
          rng: Seed = None) -> NDArray[np.uint8]:
    """Captures one clean BGR uint8 frame with ``profile``: blur, colour drift, noise, codec.

    Under ``"h264"`` the frame is encoded as a clip of :data:`H264_CLIP` frames of the same
    scene, each with its own sensor noise, and frame ``profile.h264_index`` is returned (0: the
    intra-coded frame; later: predicted frames, as most of a video is).

    Args:
        img: ``H x W x 3`` uint8 BGR, the clean frame (with markers).
        profile: the capture (default :data:`CRISP`, which returns an equal copy).
        rng: generator or seed for the sensor noise.

    Returns:
        A new ``H x W x 3`` uint8 BGR frame.
    """
    arr = _as_bgr(img)
    if not isinstance(profile, CaptureProfile):
        raise TypeError(f"profile: expected a CaptureProfile, got {type(profile).__name__}")
    g = _rng(rng)
    if profile.codec == "h264":
        clip = [_sensor(arr, profile, g) for _ in range(profile.h264_index + 1)]
        # Frames after the returned one still shape it (B-frames reference forward).
        clip += [_sensor(arr, profile, g) for _ in range(H264_CLIP - len(clip))]
        return np.ascontiguousarray(
            h264_roundtrip(clip, profile.quality, profile.preset)[profile.h264_index])
    out = _sensor(arr, profile, g)
    if profile.codec == "mjpeg":
        return jpeg_roundtrip(out, profile.quality)
    return out


def apply_sequence(frames: Sequence[NDArray[np.uint8]] | NDArray[np.uint8],
                   profile: CaptureProfile = CRISP,
                   rng: Seed = None, *,
                   gain_drift: float = 0.0) -> NDArray[np.uint8]:
    """Captures a clean video: every frame through the same optics and sensor (fresh noise per
    frame), then one codec over the whole sequence (H.264: one stream, so inter-frame coding is
    real; MJPEG: each frame on its own).

    Args:
        frames: ``T x H x W x 3`` uint8 BGR or a list of such frames.
        profile: the capture.
        rng: generator or seed.
        gain_drift: per-frame random-walk step of the gain, relative (e.g. 0.002 for a slowly
            hunting auto-exposure; 0: the gain stays ``profile.gain``).

    Returns:
        ``T x H x W x 3`` uint8 BGR.
    """
    seq = [_as_bgr(f, "frames") for f in frames]
    if not seq:
        raise ValueError("frames: expected at least one frame")
    if not isinstance(profile, CaptureProfile):
        raise TypeError(f"profile: expected a CaptureProfile, got {type(profile).__name__}")
    if not np.isfinite(gain_drift) or gain_drift < 0:
        raise ValueError(f"gain_drift: must be a finite number >= 0; got {gain_drift!r}")
    g = _rng(rng)
    gain = np.asarray(profile.gain, np.float64)
    raw = []
    for f in seq:
        p = replace(profile, gain=(float(gain[0]), float(gain[1]), float(gain[2])))
        raw.append(_sensor(f, p, g))
        if gain_drift > 0:
            gain = gain * (1.0 + g.normal(0.0, gain_drift))
    if profile.codec == "h264":
        return h264_roundtrip(raw, profile.quality, profile.preset)
    if profile.codec == "mjpeg":
        return np.stack([jpeg_roundtrip(f, profile.quality) for f in raw])
    return np.stack(raw)
