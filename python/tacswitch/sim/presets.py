"""Sensor presets: image size, marker grid and marker appearance of common sensors."""

from __future__ import annotations

from dataclasses import dataclass


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


PRESETS: dict[str, SensorPreset] = {
    # The paper's GelSight: 640x480, 48 black markers (8x6), pitch ~80 px, ~23 px dots.
    "gelsight": SensorPreset("gelsight", 480, 640, 6, 8, 80.0, 23.0, 0.85, 1.5, 1.7),
    # GelSight Mini after crop/resize: 320x240, 9x11 grid, pitch ~29 px, ~11 px soft grey dots.
    "gelsight_mini": SensorPreset("gelsight_mini", 240, 320, 9, 11, 28.5, 11.0, 0.72, 2.5, 1.5),
    # DIGIT at 320x240 with a painted grid (DIGITs usually ship without markers).
    "digit": SensorPreset("digit", 240, 320, 7, 9, 32.0, 9.0, 0.7, 2.0, 2.0),
    # Dense GelSlim-3.0-like grid: 427x320, ~265 dots, pitch 22 px.
    "dense": SensorPreset("dense", 320, 427, 14, 19, 22.0, 8.0, 0.75, 1.5, 1.5),
}


def get_preset(name: str) -> SensorPreset:
    """Returns a preset by name; ``ValueError`` naming the valid ones otherwise."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"preset: unknown {name!r}; choose from {sorted(PRESETS)}") from None
