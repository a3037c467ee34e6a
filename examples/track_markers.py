"""Marker tracking: the motion of every marker from a no-contact frame.

The same code as the README's example; tests/test_readme.py keeps the two equal."""

import numpy as np

import tacswitch as ts
from tacswitch import sim

seq = sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=0)
tracker = ts.MarkerTracker(seq.reference)       # the no-contact frame (or reference points)
for frame in seq.frames:
    motion, valid = tracker.update(frame)       # N x 2 (dx, dy) px from the reference, NaN if lost
print(f"{valid.sum()}/{len(valid)} markers, largest motion {np.nanmax(np.hypot(*motion.T)):.1f} px")
