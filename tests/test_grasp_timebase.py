"""The slip detector's time base: a stream at another frame rate is resampled to the scorer's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tacswitch.grasp.detector import GraspSlipDetector, run_clip
from tacswitch.grasp.features import FEATURE_NAMES
from tacswitch.grasp.timebase import TRAINED_FPS, TimeBase, needs_resampling, resample_field


def field(frames: int, markers: int = 12, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    motion = np.cumsum(rng.normal(0, 0.3, (frames, markers, 2)), axis=0).astype(np.float32)
    valid = rng.random((frames, markers)) > 0.1
    return motion, valid


def twice_as_fast(motion: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The same clip at twice the frame rate: a frame between every two, interpolated."""
    mid = (motion[:-1] + motion[1:]) / 2
    m = np.empty((2 * len(motion) - 1, *motion.shape[1:]), np.float32)
    m[0::2], m[1::2] = motion, mid
    v = np.empty((2 * len(valid) - 1, valid.shape[1]), bool)
    v[0::2], v[1::2] = valid, valid[:-1] & valid[1:]
    return m, v


def test_the_time_base_rate_passes_every_frame_through() -> None:
    motion, valid = field(20)
    m, v = resample_field(motion, valid, TRAINED_FPS)
    np.testing.assert_array_equal(m, motion)
    np.testing.assert_array_equal(v, valid)
    assert not needs_resampling(None) and not needs_resampling(25.3)
    # Only a faster stream, beyond the 30 frames/s of the rendered training grasps; a slower one
    # is read frame by frame.
    assert needs_resampling(50.0) and needs_resampling(32.0)
    assert not needs_resampling(30.0) and not needs_resampling(12.5)


def test_a_faster_stream_keeps_the_frames_on_the_time_base() -> None:
    motion, valid = field(21)
    fast_m, fast_v = twice_as_fast(motion, valid)
    m, v = resample_field(fast_m, fast_v, 2 * TRAINED_FPS)
    np.testing.assert_allclose(m, motion, atol=1e-6)
    np.testing.assert_array_equal(v, valid)


def test_a_slower_stream_gets_the_frames_between_interpolated_causally() -> None:
    motion, valid = field(11)
    tb = TimeBase(TRAINED_FPS / 2)
    ticks = [tb.push(m, v) for m, v in zip(motion, valid, strict=True)]
    # Frame 0 is tick 0; every later frame brings the tick before it (interpolated) and its own.
    assert [len(t) for t in ticks] == [1] + [2] * 10
    mid = ticks[3][0]
    assert mid[0] == 5
    np.testing.assert_allclose(mid[1], (motion[2] + motion[3]) / 2, atol=1e-6)
    np.testing.assert_array_equal(mid[2], valid[2] & valid[3])
    assert tb.frame_of(5) == 3 and tb.frame_of(6) == 3 and tb.frame_of(0) == 0


@settings(max_examples=40, deadline=None)
@given(fps=st.floats(1.0, 500.0), frames=st.integers(1, 40))
def test_ticks_are_counted_once_and_in_order_at_any_rate(fps: float, frames: int) -> None:
    motion, valid = field(frames, markers=3)
    tb = TimeBase(fps)
    ticks = [t for m, v in zip(motion, valid, strict=True) for t in tb.push(m, v)]
    assert [t[0] for t in ticks] == list(range(len(ticks)))
    # Tick j lies at j / 25 s, no later than the last frame's time.
    assert len(ticks) == int(np.floor((frames - 1) * TRAINED_FPS / fps + 1e-9)) + 1
    for j, m, v in ticks:
        at = j * fps / TRAINED_FPS
        lo = int(np.floor(at + 1e-9))
        hi = min(lo + 1, frames - 1)
        assert np.all(np.isfinite(m))
        # Between its two frames, and valid only where both are.
        assert np.all(m >= np.minimum(motion[lo], motion[hi]) - 1e-4)
        assert np.all(m <= np.maximum(motion[lo], motion[hi]) + 1e-4)
        assert not np.any(v & ~valid[lo]) or at == hi


def _states(states: list) -> list[tuple]:
    return [tuple(repr(x) for x in dataclasses.astuple(s)) for s in states]


def velocity_scorer(threshold: float):  # type: ignore[no-untyped-def]
    """Fires where the 90th-percentile marker speed (pitches a frame) exceeds ``threshold``:
    a cue that reads the frame rate."""
    col = FEATURE_NAMES.index("v1_p90")
    return lambda x: (x[:, col] - threshold).astype(np.float32) * 10


def slipping_field() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A grid pressed (frames 5-10), held, then its contact sliding at 3 px a frame."""
    xs, ys = np.meshgrid(np.arange(40, 300, 30.0), np.arange(40, 220, 30.0))
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    centre = np.array([160.0, 120.0])
    near = np.exp(-np.sum((pts - centre) ** 2, 1) / (2 * 50.0**2))[:, None]
    frames = []
    for t in range(60):
        press = np.clip((t - 5) / 5, 0, 1) * 4.0
        slide = max(0, t - 30) * 3.0
        m = near * (press * (pts - centre) / 60.0) + near * np.array([slide, 0.0])
        frames.append(m.astype(np.float32))
    return np.stack(frames), np.ones((60, len(pts)), bool), pts


def test_the_detector_reads_a_faster_stream_as_the_scorer_was_trained() -> None:
    motion, valid, pts = slipping_field()
    scorer = velocity_scorer(0.07)  # 3 px a frame at a 30 px pitch is 0.1
    opts = {"image_width": 320, "model": scorer, "threshold": 0.0, "votes": 1}
    at_25 = run_clip(motion, valid, pts, **opts)
    assert _states(run_clip(motion, valid, pts, fps=25.0, **opts)) == _states(at_25)
    first = next(s.frame for s in at_25 if s.slip)
    assert 30 < first < 40
    fast_m, fast_v = twice_as_fast(motion, valid)
    # Fed at 50 frames/s the markers move half as far a frame: the scorer never fires ...
    assert not any(s.slip for s in run_clip(fast_m, fast_v, pts, **opts))
    # ... unless the detector knows the rate; it then flags the same moment, counted in
    # the faster stream's frames.
    fast = run_clip(fast_m, fast_v, pts, fps=50.0, **opts)
    assert len(fast) == len(fast_m)
    assert next(s.frame for s in fast if s.slip) == 2 * first
    # A frame between two ticks holds the last tick's state.
    assert [s.slip for s in fast[1::2]] == [s.slip for s in at_25[:-1]]
    assert [s.phase for s in fast[0::2]] == [s.phase for s in at_25]
    starts = {s.grasp_start for s in at_25} - {None}
    assert {s.grasp_start for s in fast} - {None} == {2 * s for s in starts}


def test_the_shipped_scorers_read_25_frames_per_second() -> None:
    from tacswitch.grasp.detector import load_scorer

    assert load_scorer("markers").fps == load_scorer("markerless").fps == TRAINED_FPS


@pytest.mark.parametrize("fps", [0, -25.0, float("nan"), float("inf"), 1e9, True, "25"])
def test_a_bad_frame_rate_is_refused_naming_fps(fps: object) -> None:
    pts = np.array([[10.0, 10.0], [40.0, 10.0]], np.float32)
    with pytest.raises((ValueError, TypeError), match="fps"):
        GraspSlipDetector(pts, model=velocity_scorer(0.1), fps=fps)  # type: ignore[arg-type]


def test_a_faster_training_clip_is_featured_on_the_time_base() -> None:
    from tacswitch.grasp.crossval import clip_flags
    from tacswitch.grasp.dataset import TrackedClip

    motion, valid, pts = slipping_field()
    fast_m, fast_v = twice_as_fast(motion, valid)
    at_25 = TrackedClip(motion, valid, pts, 30.0, 320)
    fast = TrackedClip(fast_m, fast_v, pts, 30.0, 320, fps=50.0)
    # What a scorer trains on is what the detector reads online: the 25 frames/s field.
    np.testing.assert_allclose(fast.features(), at_25.features(), atol=1e-5)
    assert TrackedClip(fast_m, fast_v, pts, 30.0, 320).features().shape[0] == len(fast_m)
    # And evaluation runs the detector at the clip's rate.
    opts = {"model": velocity_scorer(0.07), "threshold": 0.0, "votes": 1}
    flags = clip_flags(fast, **opts)
    assert len(flags) == len(fast_m) and flags.argmax() == 2 * clip_flags(at_25, **opts).argmax()


def test_the_frame_rate_from_time_stamps() -> None:
    from tacswitch.grasp.timebase import fps_from_stamps

    t0, dt = 1_700_000_000_000_000_000, 16_666_667  # 60 frames/s
    stamps = [t0 + i * dt for i in range(20)]
    assert fps_from_stamps(stamps) == pytest.approx(1e9 / dt, rel=1e-9)
    # Dropped frames and repeated stamps do not move it; too few intervals give None.
    gappy = stamps[:5] + stamps[8:] + [stamps[-1]] * 3
    assert fps_from_stamps(gappy) == pytest.approx(1e9 / dt, rel=1e-9)
    assert fps_from_stamps(stamps[:5]) is None and fps_from_stamps([t0] * 10) is None


def test_a_saved_clip_keeps_its_frame_rate(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from tacswitch.grasp.dataset import TrackedClip, load_clip, save_clip

    motion, valid, pts = slipping_field()
    for fps in (50.0, None):
        save_clip(tmp_path / "c.npz", TrackedClip(motion, valid, pts, 30.0, 320, fps=fps))
        back = load_clip(tmp_path / "c.npz")
        assert back.fps == fps and back.width == 320 and back.pitch == 30.0
        np.testing.assert_array_equal(back.motion, motion)
        np.testing.assert_array_equal(back.valid, valid)


@pytest.mark.parametrize("fps", [50.0, 60.0, 100.0])
def test_an_explicit_start_on_a_fast_stream_is_never_before_the_frame_asked_for(
        fps: float) -> None:
    motion, valid, pts = slipping_field()
    for start in range(0, 13):
        states = run_clip(motion, valid, pts, image_width=320, model=velocity_scorer(0.07),
                          threshold=0.0, votes=1, start=start, fps=fps)
        begun = next(s.grasp_start for s in states if s.grasp_start is not None)
        # The first frame on the scorer's 25 frames/s clock at or after the one asked for.
        assert start <= begun <= start + np.ceil(fps / 25.0)
