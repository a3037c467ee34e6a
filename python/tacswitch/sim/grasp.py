"""Physically rendered grasp sequences (paired images, per-frame labels) at camera rate.

Phases (fractions of ``n_frames``): press (depth ramps in, first quarter), shear ramp (the stuck
zone and the object move together, load ratio rises, second quarter), then from ``grasp_start``:

- ``"hold"``: the load stays below friction (no slip);
- ``"slip"``: two frames later the load reaches friction: the stuck zone vanishes, the marker
  field saturates where it was, and the object (its texture, its imprint) slides on;
- ``"vibration"``: the stuck shear oscillates (8-15 Hz, ~0.05 pitch) — a hard negative.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tacswitch.sim.presets import SensorPreset
from tacswitch.sim.scene import Appearance, Frame, Optics, Scene, _as_rng
from tacswitch.sim.sequences import SLIP_ONSET_FRAMES, Kind


@dataclass
class SimSequence:
    """A rendered grasp: ``frames[t]`` with ``slip[t]`` and ``phase[t]`` labels."""

    scene: Scene
    kind: str
    reference: np.ndarray
    frames: list[Frame] = field(default_factory=list)
    slip: list[bool] = field(default_factory=list)
    phase: list[str] = field(default_factory=list)
    object_offset: list[tuple[float, float]] = field(default_factory=list)
    grasp_start: int = 0
    params: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frames)


def render_grasp(preset: str | SensorPreset = "gelsight_mini", kind: Kind = "slip", *,
                 n_frames: int = 30, seed: Any = 0, label: str | None = None,
                 optics: Optics = "auto", jpeg_quality: int | None = None,
                 appearance: Appearance = "preset") -> SimSequence:
    """Renders a grasp sequence (see the module docstring); deterministic given ``seed``.

    The gel-attached grain and dust move with the gel in every frame (the scene's field);
    ``appearance="random"`` draws a random sensor look (:class:`~tacswitch.sim.scene.Scene`)."""
    if kind not in ("hold", "slip", "vibration"):
        raise ValueError(f"kind: must be 'hold', 'slip' or 'vibration'; got {kind!r}")
    if n_frames < 8:
        raise ValueError(f"n_frames: must be >= 8; got {n_frames}")
    rng = _as_rng(seed)
    if label is None:
        from tacswitch.sim.indenters import CLASSES

        label = CLASSES[1 + int(rng.integers(len(CLASSES) - 1))]  # a grasp touches something
    scene = Scene(preset, rng, label=label, optics=optics, jpeg_quality=jpeg_quality,
                  appearance=appearance)
    pitch, fps = scene.pitch, scene.preset.fps
    ang = rng.uniform(0, 2 * np.pi)
    e = np.array([np.cos(ang), np.sin(ang)])
    shear_max = pitch * rng.uniform(0.1, 0.25)
    load_hold = rng.uniform(0.4, 0.8)
    slip_speed = pitch * rng.uniform(0.03, 0.08)  # px per frame
    vib_amp, vib_hz = pitch * rng.uniform(0.03, 0.06), rng.uniform(8, 15)
    q1, q2 = n_frames // 4, n_frames // 2
    onset = q2 + SLIP_ONSET_FRAMES
    seq = SimSequence(scene, kind, scene.reference(rng), grasp_start=q2,
                      params=scene.describe() | {"kind": kind, "fps": fps, "onset": onset})
    for t in range(n_frames):
        press = min((t + 1) / max(q1, 1), 1.0)
        ramp = float(np.clip((t - q1 + 1) / max(q2 - q1, 1), 0.0, 1.0))
        shear = ramp * shear_max * e
        load = ramp * load_hold
        offset = shear.copy()
        phase = "press" if t < q1 else "shear" if t < q2 else kind
        slipping = False
        if kind == "slip" and t >= onset:
            load, slipping = 1.0, True
            offset = shear + (t - onset + 1) * slip_speed * e
        elif kind == "slip" and t >= q2:
            load = load_hold + (1 - load_hold) * (t - q2 + 1) / (SLIP_ONSET_FRAMES + 1)
        elif kind == "vibration" and t >= q2:
            shear = shear + vib_amp * np.sin(2 * np.pi * vib_hz * (t - q2) / fps) * e
            offset = shear
        f = scene.render(rng, depth=press * scene.depth, shear_px=tuple(shear),
                         offset=tuple(offset), load_ratio=load)
        seq.frames.append(f)
        seq.slip.append(slipping)
        seq.phase.append(phase)
        seq.object_offset.append((float(offset[0]), float(offset[1])))
    return seq
