"""Marker extraction: centres, areas and mask of every marker in a frame.

The same code as the README's example; tests/test_readme.py keeps the two equal."""

import tacswitch as ts
from tacswitch import sim

seq = sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=0)
m = ts.extract_markers(seq.frames[-1])   # BGR uint8 frame -> Markers
print(len(m.centres), "markers, threshold", m.threshold)
centres, areas, mask = m.centres, m.areas, m.mask   # N x 2 (x, y) sub-pixel; N; H x W bool
