"""Grasp sequences: press, shear ramp, then hold, slip or vibration, with per-frame labels."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch.sim.markers import _rng, gel_background, marker_grid, render_markers
from tacswitch.sim.motion import ball_press, sample_field, shear_field
from tacswitch.sim.presets import SensorPreset, get_preset

Kind = Literal["hold", "slip", "vibration"]

#: Frames between the established grasp and the start of slip.
SLIP_ONSET_FRAMES = 2


@dataclass
class GraspSequence:
    """A rendered grasp.

    Attributes:
        preset: the sensor.
        kind: ``"hold"`` (no slip), ``"slip"`` or ``"vibration"`` (disturbance, no slip).
        reference: no-contact frame, uint8 BGR.
        rest: marker centres at rest, ``N x 2`` ``(x, y)``.
        motions: per frame, ``N x 2`` true displacement from rest.
        slip: per frame, True once the contact slips.
        grasp_start: index of the first frame of the grasp (after the press settles), from which
            the slip rule measures displacement.
        frames: rendered frames (uint8 BGR), same length as ``motions``.
    """

    preset: SensorPreset
    kind: str
    reference: NDArray[np.uint8]
    rest: NDArray[np.float32]
    motions: list[NDArray[np.float32]] = field(default_factory=list)
    slip: list[bool] = field(default_factory=list)
    grasp_start: int = 0
    frames: list[NDArray[np.uint8]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[NDArray[np.uint8]]:
        return iter(self.frames)


def grasp_sequence(
    preset: str | SensorPreset = "gelsight",
    kind: Kind = "slip",
    *,
    n_frames: int = 40,
    seed: int | np.random.Generator | None = 0,
) -> GraspSequence:
    """Renders a grasp at camera rate (about 30 fps).

    Phases: a press over the first quarter (markers move outward by the preset's press law, its
    field scaled by the press's progress), a shear ramp over the second quarter
    (contact markers move ~0.15 pitch) — together the loading of the grasp — then, from
    ``grasp_start`` (the established grasp, the slip rule's baseline):

    - ``"hold"``: the load stays — no slip;
    - ``"slip"``: after two frames the contact gives way and its markers keep moving, up to
      ~0.65 pitch more;
    - ``"vibration"``: the shear oscillates by 0.025 pitch — a hard negative.
    """
    p = get_preset(preset) if isinstance(preset, str) else preset
    if kind not in ("hold", "slip", "vibration"):
        raise ValueError(f"kind: must be 'hold', 'slip' or 'vibration'; got {kind!r}")
    if n_frames < 8:
        raise ValueError(f"n_frames: must be >= 8; got {n_frames}")
    rng = _rng(seed)
    bg = gel_background(p.height, p.width, seed=rng)
    rest = marker_grid(p.height, p.width, p.rows, p.cols, p.pitch, jitter=0.3, seed=rng)
    contact = (
        p.width / 2 + rng.uniform(-0.1, 0.1) * p.width,
        p.height / 2 + rng.uniform(-0.1, 0.1) * p.height,
    )
    radius = 1.6 * p.pitch
    direction = rng.normal(size=2)
    direction /= np.linalg.norm(direction)
    # The press: the preset's press law (measured on real presses, sim.presets) at its mean
    # gain, for a gently curved object pressed 0.5 mm deep to this contact radius (a moderate
    # press: taxim's 4 mm calibration ball went 1.0-1.7 mm deep): ball radius
    # (a^2 + d^2) / (2 d).
    a_mm, d_mm = radius * p.mm_per_px, 0.5
    fld, _, _, st = ball_press(p, contact, radius, (a_mm ** 2 + d_mm ** 2) / (2 * d_mm),
                               float(np.mean(p.press_dilation)))
    pressed = sample_field(fld, st, rest + (0.5 - 0.5 * st))[0]
    q1, q2 = n_frames // 4, n_frames // 2
    render = dict(darkness=p.darkness, edge_px=p.edge_px, noise_sigma=p.noise_sigma)
    onset = q2 + SLIP_ONSET_FRAMES
    seq = GraspSequence(
        p, kind, render_markers(bg, rest, p.diameter, seed=rng, **render), rest, grasp_start=q2
    )
    for t in range(n_frames):
        press = min(t / max(q1, 1), 1.0)
        shear = float(np.clip((t - q1) / max(q2 - q1, 1), 0.0, 1.0)) * 0.15 * p.pitch
        slipping = False
        if kind == "slip" and t >= onset:
            shear += (t - onset + 1) / max(n_frames - onset, 1) * 0.65 * p.pitch
            slipping = True
        elif kind == "vibration" and t >= q2:
            shear += 0.025 * p.pitch * np.sin(2 * np.pi * (t - q2) / 4)
        motion = press * pressed + shear_field(
            rest, contact, radius, tuple(shear * direction)
        )
        seq.motions.append(motion)
        seq.slip.append(slipping)
        seq.frames.append(render_markers(bg, rest + motion, p.diameter, seed=rng, **render))
    return seq
