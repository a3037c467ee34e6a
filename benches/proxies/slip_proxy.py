"""Real-texture grasp videos for markerless slip detection: taxim's real presses, animated.

Markerless slip was measured on rendered grasps only (``sim.grasp``), whose frames carry no
codec. This module builds grasp *videos* from real frames: taxim's real GelSight (640 x 480) and
GelSight Mini (320 x 240) no-contact frame ``f0`` and one real press ``P`` of it, with the
imprint ``D = P - f0`` (its real shading, grain and noise), animated with the phases and the
draws of :func:`tacswitch.sim.grasp.render_grasp` (pitch from the sensor's marker grid):

- press (first quarter): ``f0 + a D``, ``a`` rising from 0 (frame 0 is the no-contact frame,
  as a video starts before the touch) to 1 (the imprint's contrast fades in; a real contact
  also grows, which this does not show);
- shear ramp (second quarter): ``P`` moved by ``r v`` with ``r`` rising to 1, ``v`` the
  simulator's stuck-contact shear field of that press's recorded contact
  (:func:`motion_proxy.contact_fields`, scaled to a stuck shear of 0.1-0.25 pitch):
  the gel, its grain and the imprint move together;
- from the grasp start (half way): ``"hold"``: ``P`` moved by ``v``; ``"vibration"``: by
  ``(1 + s(t)) v``, an 8-15 Hz oscillation of 0.03-0.06 pitch (a hard negative); ``"slip"``:
  from :data:`~tacswitch.sim.sequences.SLIP_ONSET_FRAMES` frames later the object slides on at
  0.03-0.08 pitch per frame: the gel stays at ``v`` while the imprint (``D`` within
  :data:`IMPRINT_REACH` contact radii of the recorded contact; the rest of ``D`` stays with the
  gel) moves on with the object, by ``v`` plus the slid offset.

Then the capture, as a recorder makes a video (:func:`tacswitch.sim.capture.apply_sequence`):
fresh noise per frame (:data:`TEMPORAL_NOISE`, measured on taxim's recordings), a slowly
hunting exposure, and one codec over the sequence (``"none"``, ``"mjpeg"`` per frame, or
``"h264"``: one stream, so inter-frame coding is real).
Real texture and imprint, modelled motion; the slip label is exact by construction.

Units and conventions: frames ``H x W x 3`` uint8 BGR; fields and centres ``(x, y)`` px.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .motion_proxy import RealPresses

__all__ = ["CODECS", "DEFAULT_QUALITY", "KINDS", "TEMPORAL_NOISE", "RealGrasp", "real_grasp",
           "real_grasps"]

#: Grasp endings, as :func:`tacswitch.sim.grasp.render_grasp`.
KINDS = ("hold", "slip", "vibration")
#: Captures of the video.
CODECS = ("none", "mjpeg", "h264")
#: Default quality per codec: JPEG quality (mjpeg), x264 CRF (h264; x264's own default).
DEFAULT_QUALITY = {"none": 90, "mjpeg": 85, "h264": 23}
#: Fresh noise per frame, grey levels (sigma), per sensor at its working size: the temporal
#: noise of taxim's real recordings, measured as the high-passed (Gaussian sigma 3 px)
#: difference of consecutive pairs of its presses in the frame's top-left fifth (no contact
#: there), over sqrt(2), median over pairs, mean over B, G, R (GelSight 0.78 / 0.59 / 0.74,
#: GelSight Mini at 320 x 240 1.21 / 0.69 / 1.05). The real frame's own noise is frozen in it
#: (a fixed pattern, like grain); a video has new noise every frame.
TEMPORAL_NOISE = {"gelsight": 0.70, "gelsight_mini": 0.98}
#: Per-frame random-walk step of the exposure gain (a hunting auto-exposure).
GAIN_DRIFT = 0.002
#: The imprint that slides with the object: the press's change from the no-contact frame, in
#: full up to the first multiple of the contact radius, fading to none at the second.
IMPRINT_REACH = (1.3, 2.0)


@dataclass
class RealGrasp:
    """One grasp video: ``frames`` (``T x H x W x 3`` uint8 BGR, captured), the sensor's marker
    grid ``rest`` (``N x 2`` px), its ``kind``, the ``grasp_start`` frame (the slip rule starts
    there, its reference), the slip ``onset`` frame (slip only; as the simulator's), and the
    draws in ``params``."""

    sensor: str
    kind: str
    frames: NDArray[np.uint8]
    rest: NDArray[np.float32]
    grasp_start: int
    onset: int
    press: int
    params: dict[str, Any] = field(default_factory=dict)


def _moved(layer: NDArray[np.float32], v: NDArray[np.float32]) -> NDArray[np.float32]:
    """``layer`` (``H x W x C`` float32) with its content moved by the dense field ``v``."""
    import cv2

    from .motion_proxy import dense_backward_map

    if not np.any(v):
        return layer
    px, py = dense_backward_map(v)
    return np.asarray(cv2.remap(layer, px, py, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT),
                      np.float32)


def real_grasp(presses: RealPresses, index: int, kind: str, *, n_frames: int = 30,
               codec: str = "h264", quality: int | None = None, seed: int = 0,
               read_noise: float | None = None) -> RealGrasp:
    """The grasp video of real press ``index`` of ``presses`` ending in ``kind`` (module doc).

    Deterministic given ``seed``; the grasp's draws (direction, shear, speeds) do not depend on
    ``codec`` or ``quality``, so one grasp can be compared across captures. ``quality``: JPEG
    quality (mjpeg) or x264 CRF (h264); default :data:`DEFAULT_QUALITY`. ``read_noise``: fresh
    noise per frame, grey levels (sigma); default the sensor's :data:`TEMPORAL_NOISE`.
    """
    from tacswitch.sim import capture
    from tacswitch.sim.grain import dense_field
    from tacswitch.sim.presets import get_preset
    from tacswitch.sim.sequences import SLIP_ONSET_FRAMES

    from .motion_proxy import MAX_GRADIENT, contact_fields, marker_grid

    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {KINDS}; got {kind!r}")
    if codec not in CODECS:
        raise ValueError(f"codec: expected one of {CODECS}; got {codec!r}")
    if not isinstance(n_frames, (int, np.integer)) or n_frames < 8:
        raise ValueError(f"n_frames: must be an integer >= 8; got {n_frames!r}")
    if not 0 <= index < len(presses.imgs):
        raise ValueError(f"index: must be 0..{len(presses.imgs) - 1}; got {index!r}")
    q = DEFAULT_QUALITY[codec] if quality is None else int(quality)
    noise = TEMPORAL_NOISE[presses.sensor] if read_noise is None else float(read_noise)
    rng = np.random.default_rng([seed, index, KINDS.index(kind)])
    rest, pitch = marker_grid(presses.sensor)
    f0 = presses.f0.astype(np.float32)
    pressed = presses.imgs[index].astype(np.float32)
    h, w = f0.shape[:2]
    centre = (float(presses.centres[index, 0]), float(presses.centres[index, 1]))
    # The object's imprint: the press's change from f0 near the recorded contact (its shading
    # reaches a little past the contact edge); elsewhere the change stays with the gel.
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    dist = np.hypot(xx - centre[0], yy - centre[1]) / max(float(presses.radii[index]), 1.0)
    near = np.clip((IMPRINT_REACH[1] - dist) / (IMPRINT_REACH[1] - IMPRINT_REACH[0]), 0, 1)
    imprint = (pressed - f0) * near[..., None]
    gel = pressed - imprint
    _, other, step, drawn = contact_fields(presses.sensor, centre, float(presses.radii[index]),
                                           "shear", rng)
    shear_max = pitch * float(rng.uniform(0.1, 0.25))
    slip_speed = pitch * float(rng.uniform(0.03, 0.08))
    vib_amp, vib_hz = pitch * float(rng.uniform(0.03, 0.06)), float(rng.uniform(8, 15))
    fps = float(get_preset(presses.sensor).fps)
    mag = float(np.hypot(drawn["shear_x"], drawn["shear_y"]))
    e = np.array([drawn["shear_x"], drawn["shear_y"]]) / max(mag, 1e-6)
    v = dense_field(other, step, h, w) * np.float32(shear_max / max(mag, 1e-6))
    # The largest field of the grasp (vibration peaks) must keep the backward map a contraction.
    top = (shear_max + vib_amp) / shear_max
    grad = float(np.abs(np.gradient(v * np.float32(top), axis=(0, 1))).max()) * 2
    capped = grad > MAX_GRADIENT
    if capped:
        v = v * np.float32(MAX_GRADIENT / grad)
    q1, q2 = n_frames // 4, n_frames // 2
    onset = q2 + SLIP_ONSET_FRAMES
    frames = []
    for t in range(n_frames):
        if t < q1:
            img = f0 + t / max(q1 - 1, 1) * (pressed - f0)
        elif t < q2 or kind == "hold" or (kind == "slip" and t < onset):
            ramp = float(np.clip((t - q1 + 1) / max(q2 - q1, 1), 0.0, 1.0))
            img = _moved(pressed, v * np.float32(ramp))
        elif kind == "vibration":
            s = 1.0 + vib_amp / shear_max * np.sin(2 * np.pi * vib_hz * (t - q2) / fps)
            img = _moved(pressed, v * np.float32(s))
        else:  # slipping: the gel stays sheared, the imprint slides on with the object
            slid = (t - onset + 1) * slip_speed * e
            img = _moved(gel, v) + _moved(imprint, v + slid.astype(np.float32))
        frames.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    prof = capture.CaptureProfile(read_noise=noise, codec=codec,  # type: ignore[arg-type]
                                  quality=q)
    video = capture.apply_sequence(frames, prof, np.random.default_rng([seed, index, 7]),
                                   gain_drift=GAIN_DRIFT)
    # The field's own peak: the draw, unless the gradient cap scaled the field down.
    params = {"shear_px": float(np.hypot(v[..., 0], v[..., 1]).max()),
              "shear_drawn_px": shear_max, "capped": bool(capped),
              "direction": (float(e[0]), float(e[1])),
              "slip_px_per_frame": slip_speed, "vibration_px": vib_amp,
              "vibration_hz": vib_hz, "fps": fps, "codec": codec, "quality": q,
              "read_noise": noise}
    return RealGrasp(presses.sensor, kind, np.ascontiguousarray(video), rest, q2,
                     onset, index, params)


def real_grasps(presses: RealPresses, *, kinds: tuple[str, ...] = KINDS, n_frames: int = 30,
                codec: str = "h264", quality: int | None = None, seed: int = 0,
                read_noise: float | None = None) -> Iterator[RealGrasp]:
    """:func:`real_grasp` for every press of ``presses`` and every kind of ``kinds``."""
    for i in range(len(presses.imgs)):
        for kind in kinds:
            yield real_grasp(presses, i, kind, n_frames=n_frames, codec=codec,
                             quality=quality, seed=seed, read_noise=read_noise)
