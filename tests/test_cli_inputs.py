"""Inputs and outputs of ``remove-markers``, ``markers`` and ``motion``: unreadable files in a
folder, videos given to ``markers``, lossless video output, the marker extraction options."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from video_files import decode, write_video

import tacswitch as ts
from tacswitch import sim
from tacswitch.cli import main


@pytest.fixture(scope="module")
def grasp() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=3)


@pytest.fixture
def folder(tmp_path: Path, grasp: sim.GraspSequence) -> Path:
    """Four good frames and, between them, a damaged PNG and a file that is not an image."""
    path = tmp_path / "in"
    path.mkdir()
    for i in (0, 1, 3, 4):
        cv2.imwrite(str(path / f"{i}.png"), grasp.frames[i])
    _, buf = cv2.imencode(".png", grasp.frames[2])
    (path / "2.png").write_bytes(buf.tobytes()[: len(buf) // 3])  # truncated
    (path / "5.png").write_bytes(b"not an image at all")
    return path


def read_csv(path: Path) -> np.ndarray:
    with open(path) as fh:
        return np.array([[float(r["x"]), float(r["y"])] for r in csv.DictReader(fh)])


def test_remove_markers_skips_and_names_unreadable_images(
        tmp_path: Path, folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["remove-markers", str(folder), "-o", str(out), "--workers", "2"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".tacswitch-remove-markers.json", "0.png",
                                                     "1.png", "3.png", "4.png"]
    cap = capsys.readouterr()
    assert "4 written, 0 already done, 2 unreadable skipped" in cap.out
    assert "warning: skipped 2 inputs that could not be used" in cap.err
    assert "2.png" in cap.err and "5.png" in cap.err
    src = cv2.imread(str(folder / "4.png"))
    assert src is not None
    np.testing.assert_array_equal(cv2.imread(str(out / "4.png")), ts.remove_markers(src))


def test_nothing_readable_is_an_error(tmp_path: Path, folder: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    for p in folder.glob("[0134].png"):
        p.unlink()
    assert main(["remove-markers", str(folder), "-o", str(tmp_path / "o"), "-q"]) == 1
    assert "none of the 2 inputs could be read" in capsys.readouterr().err
    assert main(["markers", str(folder / "5.png"), "-o", str(tmp_path / "m"), "-q"]) == 1
    assert "cannot read an image from" in capsys.readouterr().err


def test_markers_skips_and_names_unreadable_images(
        tmp_path: Path, folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m"
    assert main(["markers", str(folder), "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["0.csv", "1.csv", "3.csv", "4.csv"]
    err = capsys.readouterr().err
    assert "skipped 2 inputs that could not be used" in err and "2.png" in err and "5.png" in err


def test_motion_skips_and_names_unreadable_images(
        tmp_path: Path, folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mo"
    ref = str(folder / "0.png")
    assert main(["motion", str(folder), "--ref", ref, "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.glob("*.csv")) == ["0.csv", "1.csv", "3.csv", "4.csv"]
    err = capsys.readouterr().err
    assert "skipped 2 inputs that could not be used" in err and "2.png" in err and "5.png" in err
    assert main(["motion", str(folder / "5.png"), "-o", str(tmp_path / "x"), "-q"]) == 1
    assert "cannot read an image from" in capsys.readouterr().err


def test_motion_skips_and_names_a_video_that_does_not_decode(
        tmp_path: Path, grasp: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    videos = tmp_path / "videos"
    videos.mkdir()
    (videos / "a_empty.avi").write_bytes(b"")
    write_video(videos / "b.mkv", [grasp.reference, *grasp.frames[:4]], "FFV1", fps=30)
    out = tmp_path / "mo"
    assert main(["motion", str(videos), "-o", str(out), "-q"]) == 0
    assert [p.name for p in out.glob("*.csv")] == ["b.csv"]
    err = capsys.readouterr().err
    assert "skipped 1 input that could not be used" in err and "a_empty.avi" in err
    (videos / "b.mkv").unlink()
    assert main(["motion", str(videos), "-o", str(out), "-q"]) == 1


def test_markers_reads_a_video_frame(tmp_path: Path, grasp: sim.GraspSequence,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    # A lossless video, so the frames are exactly the images extracted from.
    video = write_video(tmp_path / "rec.mkv", [grasp.reference, *grasp.frames], "FFV1", fps=30)
    out = tmp_path / "m"
    assert main(["markers", str(video), "-o", str(out)]) == 0
    assert "rec.mkv (frame 0):" in capsys.readouterr().out
    np.testing.assert_allclose(read_csv(out / "rec.csv"),
                               ts.extract_markers(grasp.reference).centres, atol=1e-3)
    assert main(["markers", str(video), "-o", str(out), "--frame", "5", "--format", "json",
                 "-q"]) == 0
    data = json.loads((out / "rec.json").read_text())
    assert data["frame"] == 5
    got = np.array([[m["x"], m["y"]] for m in data["markers"]])
    np.testing.assert_allclose(got, ts.extract_markers(grasp.frames[4]).centres, atol=1e-3)
    # A frame past the end: the video is skipped with a message naming --frame.
    assert main(["markers", str(video), "-o", str(out), "--frame", "99", "-q"]) == 1
    assert "--frame" in capsys.readouterr().err


def test_a_named_file_without_a_known_suffix_is_told_by_its_contents(
        tmp_path: Path, grasp: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    # A camera dump without an extension is a video; an image renamed without one stays an
    # image; anything else fails as a video that does not decode, named.
    video = write_video(tmp_path / "rec.mkv", [grasp.reference, *grasp.frames], "FFV1", fps=30)
    bare = video.rename(tmp_path / "rec")
    image = tmp_path / "still"
    image.write_bytes(cv2.imencode(".png", grasp.frames[2])[1].tobytes())
    out = tmp_path / "m"
    assert main(["markers", str(bare), str(image), "-o", str(out), "-q"]) == 0
    np.testing.assert_allclose(read_csv(out / "rec.csv"),
                               ts.extract_markers(grasp.reference).centres, atol=1e-3)
    np.testing.assert_allclose(read_csv(out / "still.csv"),
                               ts.extract_markers(grasp.frames[2]).centres, atol=1e-3)
    junk = tmp_path / "junk"
    junk.write_bytes(b"neither an image nor a video")
    assert main(["markers", str(junk), "-o", str(out), "-q"]) == 1
    assert "junk" in capsys.readouterr().err


def test_rest_centres_from_a_video_feed_motion(tmp_path: Path, grasp: sim.GraspSequence) -> None:
    video = write_video(tmp_path / "rec.mkv", [grasp.reference, *grasp.frames], "FFV1", fps=30)
    assert main(["markers", str(video), "-o", str(tmp_path / "m"), "-q"]) == 0
    cv2.imwrite(str(tmp_path / "img.png"), grasp.frames[-1])
    cv2.imwrite(str(tmp_path / "ref.png"), grasp.reference)
    assert main(["motion", str(tmp_path / "img.png"), "--ref", str(tmp_path / "ref.png"),
                 "--centres", str(tmp_path / "m" / "rec.csv"), "-o", str(tmp_path / "o"),
                 "-q"]) == 0
    np.testing.assert_allclose(read_csv(tmp_path / "o" / "img.csv"),
                               read_csv(tmp_path / "m" / "rec.csv"), atol=1e-3)


def test_ffv1_video_output_is_bit_exact(tmp_path: Path, grasp: sim.GraspSequence) -> None:
    frames = [grasp.reference, *grasp.frames[:5]]
    video = write_video(tmp_path / "rec.mkv", frames, "FFV1", fps=30)
    out = tmp_path / "out"
    assert main(["remove-markers", str(video), "-o", str(out), "--codec", "ffv1", "-q"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".tacswitch-remove-markers.json", "rec.mkv"]
    got = decode(out / "rec.mkv")
    assert len(got) == len(frames)
    for before, after in zip(frames, got, strict=True):
        np.testing.assert_array_equal(after, ts.remove_markers(before))
    # The default mp4v output is lossy: not the in-memory result.
    assert main(["remove-markers", str(video), "-o", str(out), "-q"]) == 0
    lossy = decode(out / "rec.mp4")
    assert any(not np.array_equal(a, ts.remove_markers(b))
               for a, b in zip(lossy, frames, strict=True))


def test_help_says_which_video_output_is_lossy() -> None:
    import subprocess
    import sys

    text = subprocess.run([sys.executable, "-m", "tacswitch", "remove-markers", "--help"],
                          capture_output=True, text=True).stdout
    text = " ".join(text.split())
    assert "LOSSY" in text and "lossless, bit-exact" in text and "--codec" in text


def test_extraction_options_reach_remove_markers(tmp_path: Path, grasp: sim.GraspSequence,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    img = tmp_path / "f.png"
    cv2.imwrite(str(img), grasp.frames[2])
    seen: list[dict] = []

    def spy(image: np.ndarray, **kw: object) -> np.ndarray:
        seen.append(kw)  # what the command asked for; the fill itself is tested below
        return image.copy()

    monkeypatch.setattr(ts, "remove_markers", spy)
    args = ["remove-markers", str(img), "-o", str(tmp_path / "o"), "--overwrite", "-q"]
    assert main(args) == 0
    assert set(seen[-1]) == {"method", "radius"}  # nothing set: the library's defaults
    assert main([*args, "--polarity", "dark", "--threshold", "12", "--block-size", "31",
                 "--min-area", "5", "--max-area", "900", "--min-fill", "0.3",
                 "--max-aspect", "2.5", "--dilate", "3", "--exclude-border"]) == 0
    assert seen[-1] == {"method": "telea", "radius": None, "polarity": "dark", "threshold": 12.0,
                        "block_size": 31, "min_area": 5, "max_area": 900, "min_fill": 0.3,
                        "max_aspect": 2.5, "dilate": 3, "exclude_border": True}
    assert main([*args, "--keep-border", "--dilate", "auto"]) == 0
    assert seen[-1]["exclude_border"] is False and seen[-1]["dilate"] == "auto"


def test_extraction_options_change_the_result(tmp_path: Path, grasp: sim.GraspSequence) -> None:
    img = tmp_path / "f.png"
    frame = grasp.frames[2]
    cv2.imwrite(str(img), frame)
    out = tmp_path / "o"
    assert main(["remove-markers", str(img), "-o", str(out / "a"), "--dilate", "0", "-q"]) == 0
    assert main(["remove-markers", str(img), "-o", str(out / "b"), "--dilate", "4", "-q"]) == 0
    a, b = cv2.imread(str(out / "a" / "f.png")), cv2.imread(str(out / "b" / "f.png"))
    assert a is not None and b is not None
    np.testing.assert_array_equal(a, ts.remove_markers(frame, dilate=0))
    np.testing.assert_array_equal(b, ts.remove_markers(frame, dilate=4))
    assert (a != frame).any(axis=2).sum() < (b != frame).any(axis=2).sum()
    # markers: a huge minimum area finds none (and says so), bright polarity finds none here.
    m = tmp_path / "m"
    assert main(["markers", str(img), "-o", str(m), "-q"]) == 0
    assert len(read_csv(m / "f.csv")) == len(ts.extract_markers(frame))
    assert main(["markers", str(img), "-o", str(m), "-q", "--min-area", "100000"]) == 0
    assert len(read_csv(m / "f.csv")) == 0
    assert main(["markers", str(img), "-o", str(m), "-q", "--keep-border"]) == 0
    assert len(read_csv(m / "f.csv")) == len(ts.extract_markers(frame, exclude_border=False))


@pytest.mark.parametrize("bad", [["--block-size", "4"], ["--min-area", "-1"],
                                 ["--threshold", "abc"], ["--min-fill", "2"],
                                 ["--dilate", "x"], ["--keep-border", "--exclude-border"]])
def test_bad_extraction_options_are_usage_errors(tmp_path: Path, bad: list[str],
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["remove-markers", "x.png", "-o", str(tmp_path), *bad])
    assert info.value.code == 2
    assert bad[0].split("=")[0] in capsys.readouterr().err or "--exclude-border" in bad


def test_motion_runs_a_model_over_a_video_from_its_first_frame(
        tmp_path: Path, grasp: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    frames = [ts.remove_markers(f) for f in [grasp.reference, *grasp.frames]]
    video = write_video(tmp_path / "clean.mkv", frames, "FFV1", fps=30)
    assert main(["motion", str(video), "--method", "model", "-o", str(tmp_path / "o"),
                 "-q"]) == 0
    with open(tmp_path / "o" / "clean.csv") as fh:
        rows = list(csv.DictReader(fh))
    t = np.array([int(r["frame"]) for r in rows])
    d = np.array([[float(r["dx"]), float(r["dy"])] for r in rows])
    assert sorted(set(t)) == list(range(len(frames)))
    assert np.abs(d[t == 0]).max() == 0.0  # the consistent model: the anchor against itself
    # The same as the model on each frame against the first, as the Python API gives it.
    pts = np.array([[float(r["x"]), float(r["y"])] for r in rows if r["frame"] == "0"])
    last = ts.predict_motion(frames[-1], frames[0], pts, method="model")
    np.testing.assert_allclose(d[t == len(frames) - 1], last, atol=1e-3)
    capsys.readouterr()
    cv2.imwrite(str(tmp_path / "ref.png"), frames[0])
    assert main(["motion", str(video), "--method", "flow", "--ref", str(tmp_path / "ref.png"),
                 "-o", str(tmp_path / "p")]) == 2
    assert "--method model" in capsys.readouterr().err
