"""Sensor presets: image size, marker grid and marker appearance of common sensors."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class SensorPreset:
    """Geometry and look of one sensor.

    Attributes:
        name: preset name.
        height, width: image size, pixels.
        rows, cols: marker grid.
        pitch: marker spacing, pixels.
        diameter: painted dot diameter, pixels.
        darkness: fraction of the background removed at a dot's centre (1 = black dot; GelSight
            Mini dots keep 0.25-0.30 of the background, i.e. darkness ~0.72).
        edge_px: width of the soft dot edge, pixels.
        noise_sigma: temporal camera noise, grey levels per channel.
        mm_per_px: size of one pixel on the gel, mm (the physical scale of indenters,
            deformation and gel thickness).
        calib: name of the shipped Taxim calibration (``"gelsight"``, ``"gelsight_mini"``) whose
            real colour tables and no-contact background the optical renderer uses; ``None``:
            Phong shading on a synthetic background.
        gel_thickness_mm: elastomer thickness; the elastic kernels are cut off beyond it.
        fps: camera frame rate of sequences, frames per second.
        press_dilation: range ``(lo, hi)`` of the normal press's dilation gain, drawn uniformly
            per scene (:func:`tacswitch.sim.motion.contact_displacement`, ``dilation``).
        press_decay_mm: how far the press's outward flow reaches (the smoothing sigma of the
            dilation law, mm); None: ``gel_thickness_mm``.
    """

    name: str
    height: int
    width: int
    rows: int
    cols: int
    pitch: float
    diameter: float
    darkness: float
    edge_px: float
    noise_sigma: float
    mm_per_px: float = 0.059
    calib: str | None = None
    gel_thickness_mm: float = 2.0
    fps: float = 30.0
    press_dilation: tuple[float, float] = (0.15, 0.4)
    press_decay_mm: float | None = None


# The normal press law (``sim.motion.contact_displacement``: dilation gain and reach) measured
# on taxim's real presses: block matching of the gel's grain between the real no-contact frame
# and each press, a joint fit of a radial profile about the contact plus a per-press zoom /
# shift (``motion.grainmatch.press_profile``), the law (a ball of the radius the real imprints
# show, ``REAL_BALL_RADIUS_MM`` of ``benches/proxies/motion_proxy.py``, pressed to each recorded
# contact) fitted to the even-index presses over 1.5-6 contact radii and checked on the odd ones
# (``benches/studies/bench_press_calibration.py``; docs/notes/2026-11-markerless-motion.md, "Real
# presses: the gel's outward motion (grain block matching) and the calibrated press law"). The
# gain range is centred on the
# pooled least-squares gain, half-width the distance to the 10th percentile of the per-press
# gains (a pooled gain of 0: up to their 90th percentile). GelSight: the gel moves outward
# ~2.5-3 px (640 x 480) at 2-3 contact radii and still ~0.7 px at 6 radii: reach 5 mm, gain
# 4.94 for the 4 mm ball pressed 1.0-1.7 mm deep that the imprints show (the first calibration,
# 14.6, assumed a ball radius drawn up to 6 mm, i.e. presses 3-4x shallower, and so made the
# simulated gel move ~3x too far per pressed volume; the old law before it: 0.15-0.4 over 2 mm,
# far too small). GelSight Mini: within +-0.15 px (320 x 240) at every radius, slightly inward
# next to the contact: no measurable outward press field (pooled gain 0, per-press 90th
# percentile 0.05; reach kept at the gel thickness). DIGIT / dense: not measured, the old draw
# U(0.15, 0.4) over one gel thickness.
GELSIGHT_PRESS_DILATION = (3.0, 6.9)
GELSIGHT_PRESS_DECAY_MM = 5.0
MINI_PRESS_DILATION = (0.0, 0.05)
MINI_PRESS_DECAY_MM: float | None = None

# Gains of the no-learning single-frame motion rules (``predict_motion(..., method=
# "mechanics" | "outward", gain=<sensor>)``), fitted on REAL frames: the least-squares scale of
# the rule at unit gain (single frame) against the real gel's grain-matched motion at the
# sensor's marker grid around taxim's even-index presses (each press's capture similarity
# removed, markers >= 2 contact radii away), clamped >= 0, checked on the odd-index presses
# (``benches/studies/bench_press_calibration.py``; docs/notes/2026-11-markerless-motion.md, "Real
# presses: the gel's outward motion ...": mechanics 0.252 GelSight, 0.038 Mini;
# outward 0.183 GelSight, 0 Mini). How far a press moves the gel is a property of the gel, not
# visible in one image: on the real GelSight the mechanics rule's old simulator-fitted gain
# 1.02 was ~4x too large; the real Mini's gel does not measurably move (its fitted scale is
# noise: predictions under ~0.05 px). Mechanics: a dimensionless gain; outward: the largest
# motion as a fraction of the marker pitch. Other sensors: measure your own
# (``tacswitch.motion.calibration.calibrate_press_gain``, which gives 0.28-0.30 / 0.036 on the
# same real presses).
MECHANICS_GAINS: dict[str, float] = {"gelsight": 0.25, "gelsight_mini": 0.04}
OUTWARD_GAINS: dict[str, float] = {"gelsight": 0.18, "gelsight_mini": 0.0}
#: The mechanics rule's gain when no sensor is named: the least-squares scale pooled over both
#: sensors' even-index real presses (0.246): the one gain best on real data across both; it
#: keeps the Mini's false motion ~4x below the old 1.02's (bench_press_calibration.py).
MECHANICS_GAIN_POOLED = 0.25

PRESETS: dict[str, SensorPreset] = {
    # The paper's GelSight: 640x480, 48 black markers (8x6), pitch ~80 px, ~23 px dots.
    "gelsight": SensorPreset("gelsight", 480, 640, 6, 8, 80.0, 23.0, 0.85, 1.5, 1.7,
                             mm_per_px=0.0295, calib="gelsight", fps=30.0,
                             press_dilation=GELSIGHT_PRESS_DILATION,
                             press_decay_mm=GELSIGHT_PRESS_DECAY_MM),
    # GelSight Mini after crop/resize: 320x240, 9x11 grid, pitch ~29 px, ~11 px soft grey dots.
    "gelsight_mini": SensorPreset("gelsight_mini", 240, 320, 9, 11, 28.5, 11.0, 0.72, 2.5, 1.5,
                                  mm_per_px=0.059, calib="gelsight_mini", fps=25.0,
                                  press_dilation=MINI_PRESS_DILATION,
                                  press_decay_mm=MINI_PRESS_DECAY_MM),
    # DIGIT at 320x240 with a painted grid (DIGITs usually ship without markers).
    "digit": SensorPreset("digit", 240, 320, 7, 9, 32.0, 9.0, 0.7, 2.0, 2.0,
                          mm_per_px=0.06, gel_thickness_mm=1.5, fps=30.0),
    # Dense GelSlim-3.0-like grid: 427x320, ~265 dots, pitch 22 px.
    "dense": SensorPreset("dense", 320, 427, 14, 19, 22.0, 8.0, 0.75, 1.5, 1.5,
                          mm_per_px=0.06, gel_thickness_mm=1.5, fps=30.0),
}


def get_preset(name: str) -> SensorPreset:
    """Returns a preset by name; ``ValueError`` naming the valid ones otherwise."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"preset: unknown {name!r}; choose from {sorted(PRESETS)}") from None


def as_preset(preset: Any, name: str = "preset") -> SensorPreset:
    """A :class:`SensorPreset` from itself or its name; an error naming ``name`` otherwise."""
    if isinstance(preset, SensorPreset):
        return preset
    if not isinstance(preset, str):
        raise TypeError(f"{name}: expected a preset name ({', '.join(sorted(PRESETS))}) or a "
                        f"SensorPreset; got {type(preset).__name__}")
    return get_preset(preset)
