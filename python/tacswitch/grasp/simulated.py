"""Rendered grasps for the slip scorer: the physical simulator's press, shear and then hold, slip
or vibration (``tacswitch.sim.grasp_sequence``), each after a few no-contact frames, tracked like
a recording. They add the textbook slip (the stuck zone shrinking until the contact slides) to
the real grasps, whose slips are mostly objects sliding out of the fingers."""

from __future__ import annotations

from tacswitch.grasp.dataset import TrackedClip, track_clip
from tacswitch.sim.sequences import Kind

#: Rendered grasps per kind and sensor in the shipped scorer's training set (and the default of
#: ``tacswitch train slip --simulated``), and their first seed. 48 since 2026-11-29 (eighteenth
#: stop; 24 before): with 24, the members that see them caught the rendered slips with too
#: little margin (11 of those 16 fired on the real grasps' cleaned tracks, 13 votes needed);
#: with 48, 14 of 16 fire, and the real grasps score as before (docs/notes/2026-11-slip.md).
SIMULATED_PER_KIND = 48
SIMULATED_SEED = 1000
#: No-contact frames before each rendered grasp.
LEAD = 4
KINDS: tuple[Kind, ...] = ("slip", "hold", "vibration")
SENSORS = ("gelsight_mini", "gelsight")


def simulated_clips(n_per_kind: int, seed: int, *, sensors: tuple[str, ...] = SENSORS,
                    n_frames: int = 30) -> tuple[list[TrackedClip], list[bool]]:
    """``n_per_kind`` rendered grasps of each kind and sensor, tracked from their no-contact
    first frame; labels: slip or not. Seeds ``seed, seed + 1, ...`` per kind and sensor."""
    from tacswitch import sim

    clips: list[TrackedClip] = []
    labels: list[bool] = []
    for sensor in sensors:
        for kind in KINDS:
            for k in range(n_per_kind):
                seq = sim.grasp_sequence(sensor, kind, n_frames=n_frames, seed=seed + k)
                clips.append(track_clip(iter([seq.reference] * LEAD + list(seq.frames))))
                labels.append(kind == "slip")
    return clips, labels
