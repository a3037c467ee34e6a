"""Synthetic tactile sensor data with exact ground truth.

- :mod:`tacswitch.sim.presets`: sensor presets (resolution, marker grid, marker look);
- :mod:`tacswitch.sim.markers`: gel backgrounds, marker grids, marker rendering;
- :mod:`tacswitch.sim.motion`: marker displacement fields (press, shear, twist);
- :mod:`tacswitch.sim.sequences`: fast marker-only grasp sequences with per-frame slip labels;
- :mod:`tacswitch.sim.optics`, :mod:`~tacswitch.sim.deform`, :mod:`~tacswitch.sim.indenters`:
  Taxim-calibrated (or Phong) rendering of a gel deformed by indenters and textured objects;
- :mod:`tacswitch.sim.scene`: paired marker/markerless samples with exact ground truth;
- :mod:`tacswitch.sim.grasp`: physically rendered grasp sequences (hold / slip / vibration);
- :mod:`tacswitch.sim.dataset`: datasets on disk (read them with :mod:`tacswitch.data`).

All images are uint8 BGR; points are ``(x, y)`` pixels; every generator takes a seed or a
``numpy.random.Generator`` and is deterministic given it.
"""

from __future__ import annotations

from tacswitch.sim.grasp import SimSequence, render_grasp
from tacswitch.sim.indenters import CLASSES
from tacswitch.sim.markers import gel_background, marker_grid, marker_layer, render_markers
from tacswitch.sim.motion import press_field, shear_field, twist_field
from tacswitch.sim.presets import PRESETS, SensorPreset, get_preset
from tacswitch.sim.scene import Frame, Sample, Scene, render_sample
from tacswitch.sim.sequences import GraspSequence, grasp_sequence

__all__ = [
    "CLASSES",
    "PRESETS",
    "Frame",
    "GraspSequence",
    "Sample",
    "Scene",
    "SensorPreset",
    "SimSequence",
    "gel_background",
    "get_preset",
    "grasp_sequence",
    "marker_grid",
    "marker_layer",
    "press_field",
    "render_grasp",
    "render_markers",
    "render_sample",
    "shear_field",
    "twist_field",
]
