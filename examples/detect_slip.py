"""Slip detection over a grasp recording, learned and paper rules.

The same code as the README's example; tests/test_readme.py keeps the two equal."""

import tacswitch as ts
from tacswitch import sim

seq = sim.grasp_sequence("gelsight_mini", "slip", n_frames=30, seed=0)
frames = [seq.reference, *seq.frames]              # a recording that starts without contact
for rule in ("learned", "paper"):                   # "learned" is the default
    tracker = ts.MarkerTracker(frames[0])
    detector = ts.GraspSlipDetector(tracker.reference, image_width=frames[0].shape[1], rule=rule)
    flagged = []
    for frame in frames:
        state = detector.update(*tracker.update(frame))   # motion, valid since the first frame
        if state.slip:
            flagged.append(state.frame)                  # also state.phase, state.score
    print(f"{rule}: slip flagged at frames {flagged}")
print("true slip from frame", seq.slip.index(True) + 1)
