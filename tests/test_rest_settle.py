"""The rest frame waits for the camera to settle: an exposure still changing, or stale frames
from before the recording ended by a jump of the whole image (seen on real GelSight Mini slip
recordings: frame 0 darker in 56 of 300 videos, a jump at frame 5 in 33), are not rest.

Checked on synthetic thumbnails (``settled_index``), the commands' look-ahead
(``choose_rest_frame``) and the slip data's tracking (``track_clip``) on rendered GelSight Mini
frames (``tacswitch.sim``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from video_files import write_video

from tacswitch import MarkerTracker, extract_markers, sim
from tacswitch.cli import main
from tacswitch.cli.rest_frame import choose_rest_frame
from tacswitch.grasp.dataset import track_clip
from tacswitch.tracking import (
    REST_STALE_FRAMES,
    REST_THUMBNAIL,
    lattice_irregularity,
    rest_thumbnail,
    settled_index,
)

W, H = REST_THUMBNAIL


def _scene(seed: int, level: float = 120.0) -> np.ndarray:
    """A textured thumbnail (grey levels around ``level``)."""
    rng = np.random.default_rng(seed)
    return (level + 40.0 * rng.random((H, W))).astype(np.float32)


def _noisy(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``img`` with a codec's worth of noise (about 0.5 grey levels)."""
    return (img + rng.normal(0.0, 0.6, img.shape)).astype(np.float32)


def test_a_steady_stream_is_settled_from_its_first_frame() -> None:
    rng = np.random.default_rng(0)
    a = _scene(1)
    assert settled_index([_noisy(a, rng) for _ in range(30)]) == 0
    assert settled_index([a]) == 0
    assert settled_index([]) == 0


def test_a_dark_first_frame_is_passed_over() -> None:
    rng = np.random.default_rng(0)
    a = _scene(1)
    thumbs = [0.7 * a, 0.97 * a] + [_noisy(a, rng) for _ in range(20)]
    assert settled_index(thumbs) == 1


@settings(max_examples=30, deadline=None)
@given(jump=st.integers(1, REST_STALE_FRAMES), seed=st.integers(0, 1000))
def test_stale_frames_ended_by_a_jump_are_passed_over(jump: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    stale, now = _scene(seed), _scene(seed + 1)
    thumbs = [_noisy(stale, rng) for _ in range(jump)] + [_noisy(now, rng) for _ in range(20)]
    assert settled_index(thumbs) == jump


@settings(max_examples=30, deadline=None)
@given(jump=st.integers(1, REST_STALE_FRAMES), seed=st.integers(0, 1000))
def test_stale_frames_are_passed_over_under_a_flickering_light(jump: int, seed: int) -> None:
    # Every other frame 4.5 % brighter (below the exposure step): each frame's brightness changes
    # by about 6 grey levels, which hides the jump from a test of the image as it is, but not
    # from the test of its content.
    rng = np.random.default_rng(seed)
    stale, now = _scene(seed), _scene(seed + 1)
    scenes = [stale] * jump + [now] * 20
    thumbs = [_noisy(x * (1.045 if k % 2 else 1.0), rng) for k, x in enumerate(scenes)]
    assert settled_index(thumbs) == jump
    # A stronger flicker (every other frame 20 % brighter) changes the brightness by more than
    # the exposure step to the last frame: a light, not a settling exposure, so the rest frame
    # is still the first after the jump, not the last frame looked at.
    thumbs = [_noisy(x * (1.1 if k % 2 else 0.9), rng) for k, x in enumerate(scenes)]
    assert settled_index(thumbs) == jump


def test_a_change_building_over_frames_is_not_a_jump() -> None:
    # A press: the image changes over six frames, not in one.
    rng = np.random.default_rng(0)
    a, b = _scene(1), _scene(2)
    ramp = [a + (b - a) * k / 6.0 for k in range(7)]
    thumbs = [_noisy(a, rng)] * 3 + [_noisy(x, rng) for x in ramp] + [_noisy(b, rng)] * 10
    assert settled_index(thumbs) == 0


def test_a_jump_later_than_the_stale_frames_is_the_scene() -> None:
    rng = np.random.default_rng(0)
    a, b = _scene(1), _scene(2)
    late = REST_STALE_FRAMES + 3
    thumbs = [_noisy(a, rng) for _ in range(late)] + [_noisy(b, rng) for _ in range(10)]
    assert settled_index(thumbs) == 0


def test_thumbnails_of_grey_and_bgr_frames_agree() -> None:
    grey = np.tile(np.arange(320, dtype=np.uint8)[None, :], (240, 1))
    bgr = np.repeat(grey[..., None], 3, axis=2)
    assert rest_thumbnail(grey).shape == (H, W)
    np.testing.assert_allclose(rest_thumbnail(grey), rest_thumbnail(bgr), atol=1.0)
    with pytest.raises(TypeError, match="frame: expected dtype uint8"):
        rest_thumbnail(np.zeros((4, 4, 3), np.float64))


# --- rendered GelSight Mini frames ---------------------------------------------------------

@pytest.fixture(scope="module")
def seq() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "hold", n_frames=16, seed=3)


def _stale_start(seq: sim.GraspSequence, stale: int = 4) -> list[np.ndarray]:
    """A recording whose first ``stale`` frames are the gel deformed (the pressed state of the
    grasp, left in the camera's buffer), then the gel at rest, then the grasp."""
    pressed = seq.frames[-1]
    return [pressed] * stale + [seq.reference] * 6 + list(seq.frames)


def test_the_commands_rest_frame_follows_the_stale_frames(seq: sim.GraspSequence) -> None:
    frames = _stale_start(seq)
    rest, stream = choose_rest_frame(iter(frames), lambda f: len(extract_markers(f)),
                                     source="s")
    assert rest is not None and rest.index == 4 and rest.settled == 4
    assert "before the camera settled" in rest.message() and "frames 0-3" in rest.message()
    assert len(list(stream)) == len(frames)
    # A dark first frame (exposure settling) is passed over too.
    dark = [(0.6 * seq.reference).astype(np.uint8)] + [seq.reference] * 8
    rest, _ = choose_rest_frame(iter(dark), lambda f: len(extract_markers(f)), source="s")
    assert rest is not None and rest.index == 1


def test_tracking_for_the_slip_data_measures_from_the_settled_rest(
        seq: sim.GraspSequence) -> None:
    frames = _stale_start(seq)
    clip = track_clip(iter(frames))
    assert clip.motion.shape[0] == len(frames)  # frame numbers stay the video's
    # Frames before the rest frame read as rest; the still gel after it moves by nothing
    # (from frame 0, the pressed state, it would have moved by the whole press).
    assert np.all(clip.motion[:4] == 0) and clip.valid[:4].all()
    still = clip.motion[4:10][clip.valid[4:10]]
    assert np.abs(still).max() < 0.5
    # The test can fail: measured from frame 0 (the pressed state), the still gel moves.
    tracker = MarkerTracker(extract_markers(frames[0]).centres)
    m, v = tracker.update(frames[6])
    assert np.abs(m[v]).max() > 1.0


def test_scored_clips_start_their_detector_at_the_rest_frame(
        tmp_path: Path, seq: sim.GraspSequence) -> None:
    """`evaluate slip` scores a tracked clip as `tacswitch slip` runs the video: the detector
    starts at the rest frame (the rows before it are not fed as frames of rest), and the rest
    frame survives the track cache, or is found again for a cache written without it."""
    from dataclasses import replace

    from tacswitch.grasp.crossval import clip_flags
    from tacswitch.grasp.dataset import cached_clip, load_clip, save_clip
    from tacswitch.grasp.detector import run_clip

    frames = _stale_start(seq)
    clip = track_clip(iter(frames))
    assert clip.rest == 4
    # Rows before the rest frame that are not rest (as if fed): never seen, never flagged.
    noisy = clip.motion.copy()
    noisy[:4] = 30.0
    flags = clip_flags(replace(clip, motion=noisy), rule="paper")
    assert not flags[:4].any()
    alone = [s.slip for s in run_clip(clip.motion[4:], clip.valid[4:], clip.points,
                                      image_width=clip.width, rule="paper")]
    assert flags[4:].tolist() == alone
    # The test can fail: fed from frame 0, the detector sees those rows.
    fed = [s.slip for s in run_clip(noisy, clip.valid, clip.points, image_width=clip.width,
                                    rule="paper")]
    assert fed != flags.tolist()
    (tmp_path / "stale" / "e").mkdir(parents=True)
    video = write_video(tmp_path / "stale" / "e" / "camera_0.mkv", frames, fourcc="FFV1")
    cache = tmp_path / "cache"
    assert cached_clip(video, cache).rest == 4
    (path,) = cache.iterdir()
    assert load_clip(path, video).rest == 4
    # A cache file from before the rest frame was stored: found again from the video.
    with np.load(path) as z:
        old = {k: z[k] for k in z.files if k != "rest"}
    np.savez(path, **old)
    assert load_clip(path).rest == 0 and load_clip(path, video).rest == 4
    save_clip(path, replace(clip, rest=2))
    assert load_clip(path, video).rest == 2


def test_evaluate_flags_the_frames_the_slip_log_flags(tmp_path: Path) -> None:
    """A video with stale frames before its rest frame: `evaluate slip`'s first flag is the
    first frame `tacswitch slip`'s log flags (both from the rest frame)."""
    import json

    slip = sim.grasp_sequence("gelsight_mini", "slip", n_frames=24, seed=5)
    frames = _stale_start(slip)
    # The learned rule at 60 frames/s: both resample to the scorer's 25 from the rest frame.
    for k, (rule, fps) in enumerate((([], 60), (["--rule", "paper"], 25))):
        data = tmp_path / f"data{k}"
        (data / "obj" / "e1").mkdir(parents=True)
        video = write_video(data / "obj" / "e1" / "camera_0.mkv", frames, fourcc="FFV1",
                            fps=fps)
        (data / "labels.csv").write_text("object,experiment,slip\nobj,e1,1\n")
        log = tmp_path / f"l{k}.csv"
        assert main(["slip", str(video), *rule, "--log", str(log), "-q"]) == 0
        with open(log) as fh:
            flagged = [int(r["frame"]) for r in csv.DictReader(fh) if r["slip"] == "1"]
        out = tmp_path / f"e{k}.json"
        assert main(["evaluate", "slip", str(data), *rule, "--json", str(out), "-q",
                     "--cache", str(tmp_path / f"cache{k}")]) == 0
        (exp,) = json.loads(out.read_text())["experiments"]
        assert exp["first_flag"] == [flagged[0] if flagged else None]
        if rule:
            assert flagged  # the paper rule flags this slip


def test_slip_starts_after_the_stale_frames(tmp_path: Path, seq: sim.GraspSequence,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    frames = _stale_start(seq)
    video = write_video(tmp_path / "v.mkv", frames, fourcc="FFV1")
    log = tmp_path / "l.csv"
    assert main(["slip", str(video), "--log", str(log), "-q"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "frames 0-3 come before the camera settled" in err[0]
    with open(log) as fh:
        rows = list(csv.DictReader(fh))
    # The log starts at the rest frame, with the video's frame numbers, and is the log of the
    # recording without the stale frames, four frames on.
    clean = write_video(tmp_path / "c.mkv", frames[4:], fourcc="FFV1")
    assert main(["slip", str(clean), "--log", str(tmp_path / "c.csv"), "-q"]) == 0
    with open(tmp_path / "c.csv") as fh:
        ref = list(csv.DictReader(fh))
    assert [int(r["frame"]) for r in rows] == list(range(4, len(frames)))
    assert [r["phase"] for r in rows] == [r["phase"] for r in ref]
    assert [r["slip"] for r in rows] == [r["slip"] for r in ref]
    assert all(r["phase"] == "no contact" and r["slip"] != "1" for r in rows[:6])


def test_a_markerless_stream_starts_after_the_stale_frames(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    # Predicted motion needs no markers on the rest frame; the camera must still have settled.
    frames = _stale_start(seq)
    video = write_video(tmp_path / "v.mkv", frames, fourcc="FFV1")
    log = tmp_path / "l.csv"
    assert main(["slip", str(video), "--markerless", "--log", str(log), "-q"]) == 0
    err = capsys.readouterr().err
    assert "frames 0-3 come before the camera settled" in err
    assert "so frame 4 is the rest frame; frames 0-3 are not tracked" in err
    with open(log) as fh:
        assert int(next(csv.DictReader(fh))["frame"]) == 4
    clip = track_clip(iter(frames[:12]), markerless=True)
    assert clip.motion.shape[0] == 12 and np.all(clip.motion[:4] == 0)
    # With --ref the user chose the reference: every frame is measured from it, no rest frame
    # is looked for (as `motion --sequence --ref`).
    import cv2

    cv2.imwrite(str(tmp_path / "ref.png"), frames[4])
    assert main(["slip", str(video), "--markerless", "--ref", str(tmp_path / "ref.png"),
                 "--log", str(tmp_path / "r.csv"), "-q"]) == 0
    assert "rest frame" not in capsys.readouterr().err
    with open(tmp_path / "r.csv") as fh:
        assert int(next(csv.DictReader(fh))["frame"]) == 0


# --- a stale start that fades (no jump) ---------------------------------------------------

def _fading(seed: int, fade: int = 3) -> list[np.ndarray]:
    """Thumbnails of a stale deformed gel (``b``) relaxing into the gel at rest (``a``) over
    ``fade`` frames, then still: as on real Mini recordings, no single jump."""
    rng = np.random.default_rng(seed)
    a, b = _scene(1), _scene(2)
    ramp = [b + (a - b) * k / fade for k in range(1, fade + 1)]

    def still(x: np.ndarray) -> np.ndarray:  # a still MPEG-4 gel: 0.1-0.4 grey levels a frame
        return (x + rng.normal(0.0, 0.25, x.shape)).astype(np.float32)

    return [still(b)] + [still(x) for x in ramp] + [still(a) for _ in range(15)]


@pytest.mark.parametrize("fade", [2, 3, 5])
def test_a_stale_start_that_fades_into_a_regular_lattice_is_passed_over(fade: int) -> None:
    thumbs = _fading(0, fade)
    assert settled_index(thumbs) == 0  # no jump: the image tests alone keep frame 0
    relaxed = [0.05] * fade + [0.02] * (len(thumbs) - fade)  # deformed, then at rest
    assert settled_index(thumbs, relaxed) == fade
    # A press (the lattice gets less regular) and markers not counted keep the first frame.
    pressed = [0.02] * fade + [0.04] * (len(thumbs) - fade)
    assert settled_index(thumbs, pressed) == 0
    assert settled_index(thumbs, [float("nan")] * len(thumbs)) == 0
    with pytest.raises(ValueError, match=r"^irregularity:"):
        settled_index(thumbs, [0.02])


def test_lattice_irregularity_reads_a_deformed_grid() -> None:
    xs, ys = np.meshgrid(np.arange(12) * 20.0 + 15, np.arange(9) * 20.0 + 15)
    grid = np.stack([xs.ravel(), ys.ravel()], 1)
    rng = np.random.default_rng(0)
    rest = grid + rng.normal(0, 0.2, grid.shape)
    # A press: markers pushed outward from the centre by up to 6 px.
    d = grid - grid.mean(0)
    r = np.linalg.norm(d, axis=1, keepdims=True)
    pressed = rest + 6.0 * np.exp(-(r / 40.0) ** 2) * d / np.maximum(r, 1e-9)
    assert lattice_irregularity(rest) < 0.02
    assert lattice_irregularity(pressed) > 1.25 * lattice_irregularity(rest)
    assert lattice_irregularity(rest + 7.0) == pytest.approx(lattice_irregularity(rest))
    assert np.isnan(lattice_irregularity(grid[:5]))


def test_motion_of_a_video_starts_after_the_stale_frames(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    frames = _stale_start(seq)
    video = write_video(tmp_path / "v.mkv", frames, fourcc="FFV1")
    assert main(["motion", str(video), "-o", str(tmp_path / "out")]) == 0
    assert "frames 0-3 come before the camera settled" in capsys.readouterr().out
    with open(tmp_path / "out" / "v.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert min(int(r["frame"]) for r in rows) == 4


def test_motion_of_an_image_sequence_starts_after_the_stale_frames(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    # The same frames as a folder of images (`--sequence`): the same settle check as a video's.
    import cv2

    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in enumerate(_stale_start(seq)):
        cv2.imwrite(str(folder / f"{i:04d}.png"), frame)
    out = tmp_path / "out"
    assert main(["motion", str(folder), "--sequence", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "the first 4 readable image(s) come before the camera settled" in said
    assert sorted(p.name for p in out.glob("*.csv"))[0] == "0004.csv"
    # With --ref the user chose the reference: every image is measured from it.
    assert main(["motion", str(folder), "--sequence", "--ref", str(folder / "0004.png"), "-o",
                 str(tmp_path / "out_ref"), "-q"]) == 0
    assert sorted(p.name for p in (tmp_path / "out_ref").glob("*.csv"))[0] == "0000.csv"


def test_a_hybrid_removal_takes_the_settled_frame_as_its_reference(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    import tacswitch as ts

    frames = _stale_start(seq)[:12]
    video = write_video(tmp_path / "v.mkv", frames, fourcc="FFV1")
    out = tmp_path / "out"
    assert main(["remove-markers", str(video), "-o", str(out), "--method", "hybrid",
                 "--frames"]) == 0
    said = capsys.readouterr().out
    assert "hybrid reference (no contact) = frame 4 (the first after the camera settled)" in said
    assert len(list((out / "v").glob("*.png"))) == len(frames)  # every frame is still removed
    got = cv2.imread(str(out / "v" / f"{len(frames) - 1:06d}.png"))
    np.testing.assert_array_equal(got, ts.remove_markers(frames[-1], method="hybrid",
                                                         ref=frames[4]))
