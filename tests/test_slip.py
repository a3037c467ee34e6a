"""Slip detection: the paper's rule, its scaling, the rigid criterion, synthetic grasps."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import tacswitch as ts
from tacswitch import sim
from tacswitch.motion.evaluate import slip_on_videos
from tacswitch.slip import scaled_threshold


def run(seq: sim.GraspSequence, detector: ts.SlipDetector) -> int | None:
    """Tracks a sequence and returns the first frame flagged as slip (None if never)."""
    tracker = ts.MarkerTracker(seq.reference)
    for t, frame in enumerate(seq.frames):
        motion, valid = tracker.update(frame)
        if t == seq.grasp_start:
            detector.reset()
        if t >= seq.grasp_start and detector.update(motion, valid).slip:
            return t
    return None


@pytest.mark.parametrize("preset", ["gelsight", "gelsight_mini", "dense"])
@pytest.mark.parametrize("seed", [0, 1])
def test_synthetic_grasps_are_classified(preset: str, seed: int) -> None:
    width = sim.get_preset(preset).width
    for kind in ("hold", "slip", "vibration"):
        seq = sim.grasp_sequence(preset, kind, n_frames=40, seed=seed)
        first = run(seq, ts.SlipDetector(image_width=width))
        if kind == "slip":
            onset = seq.slip.index(True)
            assert first is not None and onset <= first <= onset + 3, (kind, first, onset)
        else:
            assert first is None, (kind, first)


def test_threshold_scales_with_image_width() -> None:
    assert scaled_threshold(640) == pytest.approx(3.25)
    assert scaled_threshold(320) == pytest.approx(1.625)
    assert ts.SlipDetector(image_width=320).threshold_px == pytest.approx(1.625)
    assert ts.SlipDetector(2.0, image_width=320).threshold_px == 2.0
    det = ts.SlipDetector()
    det.update(np.zeros((4, 2)))
    assert det.threshold_px == pytest.approx(3.25)


def test_rule_is_relative_to_the_first_frame_of_the_grasp() -> None:
    det = ts.SlipDetector(3.25)
    base = np.full((48, 2), 10.0, np.float32)
    assert not det.update(base).slip
    m = base.copy()
    m[7] += [3.0, 0.0]
    state = det.update(m)
    assert not state.slip and state.max_displacement == pytest.approx(3.0)
    m[7] += [0.5, 0.0]
    state = det.update(m)
    assert state.slip and state.criterion == "displacement" and state.marker == 7
    assert state.frame == 2 and det.first_slip == 2
    det.reset()
    assert not det.update(m).slip and det.first_slip is None


def test_lost_markers_are_ignored_and_nan_means_invalid() -> None:
    det = ts.SlipDetector(1.0)
    m = np.zeros((5, 2), np.float32)
    det.update(m)
    m[2] = np.nan
    m[3] = [0.5, 0.0]
    state = det.update(m)
    assert state.n_compared == 4 and not state.slip
    state = det.update(m, valid=np.array([True, True, False, False, True]))
    assert state.n_compared == 3


def test_rigid_criterion_flags_edge_lag_not_rigid_shear() -> None:
    pts = sim.marker_grid(480, 640, 6, 8, 80.0)
    centre = pts[19]
    contact = np.hypot(*(pts - centre).T) < 100
    det = ts.SlipDetector(rigid_threshold_px=1.0, points=pts, use_displacement=False)
    det.update(np.zeros_like(pts))
    theta = 0.02
    rel = pts - centre
    rot = np.stack([np.cos(theta) * rel[:, 0] - np.sin(theta) * rel[:, 1],
                    np.sin(theta) * rel[:, 0] + np.cos(theta) * rel[:, 1]], 1)
    stick = (rot - rel + [8.0, -5.0]) * np.where(contact, 1.0, 0.15)[:, None]
    state = det.update(stick.astype(np.float32))
    assert not state.slip and state.rigid_residual < 0.05
    lag = stick.copy()
    edge = int(np.flatnonzero(contact)[0])
    lag[edge] -= [3.0, 0.0]
    state = det.update(lag.astype(np.float32))
    assert state.slip and state.criterion == "rigid" and state.rigid_marker == edge


def test_image_input_tracks_internally() -> None:
    seq = sim.grasp_sequence("gelsight", "slip", n_frames=30, seed=2)
    det = ts.SlipDetector()
    det.update(seq.reference)
    assert det.tracker is not None and det.threshold_px == pytest.approx(3.25)
    states = [det.update(f) for f in seq.frames]
    assert states[-1].slip and states[-1].max_displacement > 20


def test_bad_arguments_are_named() -> None:
    with pytest.raises(ValueError, match="threshold_px"):
        ts.SlipDetector(-1)
    with pytest.raises(ValueError, match="active_fraction"):
        ts.SlipDetector(active_fraction=0)
    with pytest.raises(ValueError, match="use_displacement"):
        ts.SlipDetector(use_displacement=False)
    with pytest.raises(ValueError, match="points"):
        ts.SlipDetector(rigid_threshold_px=1.0).update(np.zeros((3, 2)))
    det = ts.SlipDetector()
    det.update(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="motion"):
        det.update(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="valid"):
        det.update(np.zeros((3, 2)), valid=np.ones(2, bool))
    with pytest.raises(ValueError, match="motion_or_img"):
        det.update(np.full((3, 2), np.inf))


def test_rigid_auto_is_half_the_scaled_threshold() -> None:
    pts = sim.marker_grid(240, 320, 9, 11, 28.5)
    det = ts.SlipDetector(rigid_threshold_px="auto", points=pts, image_width=320)
    det.update(np.zeros_like(pts))
    assert det.rigid_threshold_px == pytest.approx(0.5 * 1.625)
    only = ts.SlipDetector(rigid_threshold_px="auto", use_displacement=False, points=pts)
    only.update(np.zeros_like(pts))
    big_rigid = np.tile(np.array([9.0, -4.0], np.float32), (len(pts), 1))
    state = only.update(big_rigid)
    assert not state.slip and only.threshold_px is None
    with pytest.raises(ValueError, match="rigid_threshold_px"):
        ts.SlipDetector(rigid_threshold_px="sometimes")


def test_smooth_frames_averages_the_last_n_motion_fields() -> None:
    det = ts.SlipDetector(1.0, smooth_frames=2)
    m = np.zeros((3, 2), np.float32)
    assert not det.update(m).slip
    # One frame's 1.5 px spike on marker 1 is averaged with the previous frame: 0.75 px.
    spike = m.copy()
    spike[1] = [1.5, 0.0]
    state = det.update(spike)
    assert not state.slip and state.max_displacement == pytest.approx(0.75)
    # Sustained motion is seen in full one frame later.
    assert det.update(spike).slip
    # reset() forgets the window: the next frame is the new baseline, averaged with nothing.
    det.reset()
    state = det.update(spike)
    assert not state.slip and state.max_displacement == 0.0
    # A marker invalid in the newest frame is invalid; earlier invalid frames are skipped.
    det.reset()
    det.update(m)
    nan = m.copy()
    nan[2] = np.nan
    assert det.update(nan).n_compared == 2
    # Without smoothing the same spike fires at once (the paper's rule, the default).
    plain = ts.SlipDetector(1.0)
    plain.update(m)
    assert plain.update(spike).slip


def test_smooth_frames_bad_values_are_named() -> None:
    with pytest.raises(ValueError, match=r"^smooth_frames: "):
        ts.SlipDetector(smooth_frames=0)
    with pytest.raises(TypeError, match=r"^smooth_frames: "):
        ts.SlipDetector(smooth_frames=1.5)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"^smooth_frames: "):
        ts.SlipDetector(smooth_frames=True)


@pytest.mark.parametrize("smooth", [1, 2])
def test_a_changed_marker_count_is_named_smoothed_or_not(smooth: int) -> None:
    det = ts.SlipDetector(1.0, smooth_frames=smooth)
    det.update(np.zeros((10, 2), np.float32))
    with pytest.raises(ValueError, match=r"^motion(_or_img)?: has 8 rows .* call reset\(\)"):
        det.update(np.zeros((8, 2), np.float32))
    det.reset()
    assert not det.update(np.zeros((8, 2), np.float32)).slip


def test_markerless_slip_evaluation_checks_smooth_frames_first() -> None:
    from tacswitch.motion.evaluate import evaluate_slip, slip_on_grasps

    # Checked before any grasp is rendered: one line naming the argument.
    with pytest.raises(ValueError, match=r"^smooth_frames: "):
        slip_on_grasps({}, smooth_frames=0)
    with pytest.raises(TypeError, match=r"^smooth_frames: "):
        evaluate_slip(lambda i, r, c: np.zeros_like(c), smooth_frames=2.0)  # type: ignore[arg-type]


def _video(kind: str) -> SimpleNamespace:
    frames = np.zeros((12, 16, 20, 3), np.uint8)
    return SimpleNamespace(frames=frames, rest=np.array([[5.0, 5.0], [12.0, 9.0]], np.float32),
                           kind=kind, grasp_start=6, onset=8)


def test_slip_on_videos_counts_detections_and_delays() -> None:
    grasps = [_video("slip"), _video("hold"), _video("vibration")]

    def still(img: np.ndarray, ref: np.ndarray, rest: np.ndarray) -> np.ndarray:
        return np.zeros((len(rest), 2), np.float32)

    calls = {"n": 0}

    def sliding(img: np.ndarray, ref: np.ndarray, rest: np.ndarray) -> np.ndarray:
        # 7 px to the right from the 4th frame the detector sees (index 9 of the video) on.
        calls["n"] += 1
        k = (calls["n"] - 1) % 6
        return np.full((len(rest), 2), [7.0 if k >= 3 else 0.0, 0.0], np.float32)

    res = slip_on_videos({"still": still, "sliding": sliding}, grasps,
                         criteria={"displacement": {}}, smooth_frames=1)
    s = res[("still", "displacement")]
    assert (s["correct"], s["n"], s["slips_found"], s["fa_hold"], s["fa_vibration"]) == \
        (2, 3, 0, 0, 0)
    m = res[("sliding", "displacement")]
    assert (m["slips_found"], m["fa_hold"], m["fa_vibration"], m["correct"]) == (1, 1, 1, 1)
    assert m["delays"] == [9 - 8]
    with pytest.raises(ValueError, match="smooth_frames"):
        slip_on_videos({"still": still}, grasps, smooth_frames=0)


def test_slip_on_videos_judges_only_the_markers_near_the_contact() -> None:
    """Motion far from the contact (a compressed video's drifting texture) raises no alarm when
    ``near_contact_only``; over all markers it does."""
    frames = np.full((10, 120, 160, 3), 120, np.uint8)
    frames[3:, 40:80, 20:60] = 200  # the contact, from frame 3 on; frame 0 has none
    rest = np.array([[30, 50], [40, 60], [50, 70], [130, 20], [140, 100], [120, 60]], np.float32)
    hold = SimpleNamespace(frames=frames, rest=rest, kind="hold", grasp_start=4, onset=6)

    calls = [0]

    def drifting(img: np.ndarray, ref: np.ndarray, pts: np.ndarray) -> np.ndarray:
        # The far markers drift 2 px more every frame after the grasp start.
        m = np.zeros((len(pts), 2), np.float32)
        m[3:] = (2.0 * calls[0], 0.0)
        calls[0] += 1
        return m

    crit: dict[str, dict[str, Any]] = {"displacement": {}}
    gated = slip_on_videos({"d": drifting}, [hold], criteria=crit, near_contact_only=True)
    calls[0] = 0
    every = slip_on_videos({"d": drifting}, [hold], criteria=crit)
    assert gated[("d", "displacement")]["fa_hold"] == 0
    assert every[("d", "displacement")]["fa_hold"] == 1
    bad = SimpleNamespace(frames=frames, rest=rest, kind="drop", grasp_start=4, onset=6)
    with pytest.raises(ValueError, match="kind"):
        slip_on_videos({"d": drifting}, [bad])
    late = SimpleNamespace(frames=frames, rest=rest, kind="hold", grasp_start=10, onset=6)
    with pytest.raises(ValueError, match="grasp_start"):
        slip_on_videos({"d": drifting}, [late])
