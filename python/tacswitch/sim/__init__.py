"""Synthetic tactile sensor data with exact ground truth.

- :mod:`tacswitch.sim.presets`: sensor presets (resolution, marker grid, marker look);
- :mod:`tacswitch.sim.markers`: gel backgrounds, marker grids, marker rendering;
- :mod:`tacswitch.sim.motion`: marker displacement fields (press, shear, twist);
- :mod:`tacswitch.sim.sequences`: grasp sequences with per-frame slip labels.

All images are uint8 BGR; points are ``(x, y)`` pixels; every generator takes a seed or a
``numpy.random.Generator`` and is deterministic given it.
"""

from __future__ import annotations

from tacswitch.sim.markers import gel_background, marker_grid, render_markers
from tacswitch.sim.motion import press_field, shear_field, twist_field
from tacswitch.sim.presets import PRESETS, SensorPreset, get_preset
from tacswitch.sim.sequences import GraspSequence, grasp_sequence

__all__ = [
    "PRESETS",
    "GraspSequence",
    "SensorPreset",
    "gel_background",
    "get_preset",
    "grasp_sequence",
    "marker_grid",
    "press_field",
    "render_markers",
    "shear_field",
    "twist_field",
]
