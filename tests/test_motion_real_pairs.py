"""Training pairs from a marker sensor's videos: targets from the tracker, inputs without
markers, pairs within a video, the cut at a sudden slip, and errors that name the argument."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from video_files import decode, write_video

import tacswitch as ts
from tacswitch import sim
from tacswitch.motion import real_pairs as rp


@pytest.fixture(scope="module")
def videos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("marker_videos")
    for k, kind in enumerate(("hold", "slip")):
        seq = sim.grasp_sequence("gelsight_mini", kind, n_frames=10, seed=20 + k)
        (root / f"exp_{k}").mkdir()
        write_video(root / f"exp_{k}" / "camera_0.avi", [seq.reference, *seq.frames])
    return root


def test_targets_are_the_trackers_motion_on_the_kept_frames(videos: Path) -> None:
    path = videos / "exp_0" / "camera_0.avi"
    track = rp.track_video(path, every=3)
    frames = decode(path)
    tracker = ts.MarkerTracker(frames[0])
    want = []
    for t, f in enumerate(frames[:track.used]):
        m, v = tracker.update(f)
        if t % 3 == 0:
            want.append(np.where(v[:, None], m, np.nan))
    np.testing.assert_allclose(track.motion, np.stack(want), atol=1e-5)
    np.testing.assert_allclose(track.rest, tracker.reference, atol=1e-5)
    assert len(track.frames) == len(want) == -(-track.used // 3)
    assert track.frames.dtype == np.uint8 and track.frames.shape[1:] == frames[0].shape
    assert np.isnan(track.motion[0]).sum() == 0 and np.abs(track.motion[0]).max() < 1e-6


def test_inputs_show_no_marker_left(videos: Path) -> None:
    frame = decode(videos / "exp_1" / "camera_0.avi")[5]
    before = len(ts.extract_markers(frame).centres)
    after = len(ts.extract_markers(rp.markerless(frame)).centres)
    assert before > 50 and after <= 0.1 * before


def test_the_static_recipe_fills_every_frame_on_one_mask(videos: Path) -> None:
    path = videos / "exp_1" / "camera_0.avi"
    raw = decode(path)
    static = rp.track_video(path, every=4)
    per_frame = rp.track_video(path, every=4, static=False)
    union = np.zeros(raw[0].shape[:2], bool)
    for f in raw[:static.used]:
        union |= ts.extract_markers(f).mask
    hole = rp.grown(union, rp.GROW_PX)
    for k, t in enumerate(range(0, static.used, 4)):
        np.testing.assert_array_equal(static.frames[k][~hole], raw[t][~hole])
    # A frame's own mask is smaller than the union of the moving dots' masks.
    filled = [(f.frames[0] != raw[0]).any(axis=2).sum() for f in (per_frame, static)]
    assert 0 < filled[0] < filled[1]


def test_a_sudden_jump_ends_the_video_there(tmp_path: Path) -> None:
    seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=8, seed=3)
    frames = [seq.reference, *seq.frames]
    pitch = ts.estimate_pitch(ts.extract_markers(seq.reference).centres)
    shift = np.float32([[1, 0, 0.5 * pitch], [0, 1, 0]])  # half a pitch in one frame
    h, w = frames[0].shape[:2]
    jumped = [cv2.warpAffine(f, shift, (w, h), borderMode=cv2.BORDER_REFLECT) for f in frames]
    path = write_video(tmp_path / "jump.avi", frames[:5] + jumped[5:])
    track = rp.track_video(path, every=1)
    assert track.used == 5 and track.total == len(frames) and len(track.frames) == 5


def test_pairs_stay_within_a_video_and_look_back(videos: Path) -> None:
    pairs = rp.pairs_from_videos([videos], every=2, seed=1)
    assert pairs.names == sorted(str(p) for p in videos.rglob("*.avi"))
    img, ref = pairs.pairs[:, 0], pairs.pairs[:, 1]
    assert (pairs.video[img] == pairs.video[ref]).all() and (ref < img).all()
    firsts = {int(np.flatnonzero(pairs.video == v)[0]) for v in range(len(pairs.names))}
    # every kept frame against its rest frame
    assert sum(int(r) in firsts for r in ref) == len(pairs.frames) - len(pairs.names)
    b = pairs.batch(np.arange(len(pairs)))
    np.testing.assert_array_equal(b["displacement"], b["disp_image"] - b["disp_reference"])
    assert b["image"].shape == (len(pairs), *pairs.frames.shape[1:])
    held = pairs.subset([1])
    assert len(held) and (pairs.video[held.pairs[:, 0]] == 1).all()


def test_videos_of_other_sizes_or_no_video_are_refused(tmp_path: Path, videos: Path) -> None:
    frames = decode(videos / "exp_0" / "camera_0.avi")[:3]
    other = write_video(tmp_path / "big.avi", [cv2.resize(f, None, fx=1.25, fy=1.25)
                                               for f in frames])
    with pytest.raises(ValueError, match="videos: frames of one size"):
        rp.pairs_from_videos([videos / "exp_0" / "camera_0.avi", other])
    with pytest.raises(ValueError, match=r"videos: .* does not exist"):
        rp.pairs_from_videos([tmp_path / "missing"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="videos: no video"):
        rp.pairs_from_videos([tmp_path / "empty"])
    (tmp_path / "broken.avi").write_bytes(b"not a video")
    with pytest.raises(ValueError, match=r"videos: cannot open|videos: .* no readable frame"):
        rp.track_video(tmp_path / "broken.avi")
    with pytest.raises(ValueError, match="every: must be >= 1"):
        rp.track_video(videos / "exp_0" / "camera_0.avi", every=0)
    with pytest.raises(ValueError, match="grow_px"):
        rp.pairs_from_videos([videos], grow_px=-1)
    with pytest.raises(ValueError, match=r"every: the kept frames of the first 1 of 2 videos"):
        rp.pairs_from_videos([videos], max_gib=1e-4)
