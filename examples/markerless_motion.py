"""Marker motion from markerless frames: flow, one frame, and a tracker over a video.

The same code as the README's example; tests/test_readme.py keeps the two equal."""

import numpy as np

import tacswitch as ts
from tacswitch.sim import render_grasp

seq = render_grasp("gelsight", "slip", n_frames=8, seed=0)  # markerless frames, true motion
rest = seq.scene.rest                                 # your sensor's marker rest centres (x, y)
a, b = seq.frames[1], seq.frames[seq.grasp_start - 1]  # two frames of one stuck contact
motion = ts.predict_motion(b.image, a.image, rest + a.displacement)  # optical flow from a to b
truth = b.displacement - a.displacement
print(f"flow error {np.hypot(*(motion - truth).T).mean():.2f} px, "
      f"zero motion {np.hypot(*truth.T).mean():.2f} px")
single = ts.predict_motion(b.image, None, rest)       # one frame: rule + learned model ensemble
tracker = ts.MarkerlessTracker(None, rest)            # a video that starts in contact
motions = [tracker.update(f.image) for f in seq.frames]   # each from rest
