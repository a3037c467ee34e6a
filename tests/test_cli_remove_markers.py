"""``tacswitch remove-markers`` end to end on generated images and a short synthetic video."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from video_files import decode, frame_rate, write_video

import tacswitch as ts
from tacswitch import sim
from tacswitch.cli import main

N_FRAMES = 9  # the reference frame and an 8-frame slip grasp


@pytest.fixture(scope="module")
def grasp() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=1)


@pytest.fixture
def video(tmp_path: Path, grasp: sim.GraspSequence) -> Path:
    """A short mp4v video with markers, 30 fps."""
    return write_video(tmp_path / "grasp.mp4", [grasp.reference, *grasp.frames], "mp4v", 30)


def marker_mask(frame: np.ndarray) -> np.ndarray:
    """The mask remove_markers fills (markers cut by the border included, adaptive growth)."""
    return ts.extract_markers(frame, dilate="auto").mask


def test_video_becomes_a_markerless_video(tmp_path: Path, video: Path) -> None:
    out = tmp_path / "out"
    assert main(["remove-markers", str(video), "-o", str(out), "-q"]) == 0
    # No temporary file left; the record of the options that made each output.
    assert sorted(p.name for p in out.iterdir()) == [".tacswitch-remove-markers.json",
                                                     "grasp.mp4"]
    src, got = decode(video), decode(out / "grasp.mp4")
    assert len(got) == len(src) == N_FRAMES
    assert frame_rate(out / "grasp.mp4") == pytest.approx(frame_rate(video))
    for before, after in zip(src, got, strict=True):
        assert after.shape == before.shape
        mask = marker_mask(before)
        far = cv2.dilate(mask.view(np.uint8), np.ones((7, 7), np.uint8)) == 0
        diff = np.abs(after.astype(np.int16) - before).mean(axis=2)
        # The markers are gone (dark dots filled with gel); elsewhere only mp4 re-encoding noise.
        assert diff[mask].mean() > 20
        assert diff[far].mean() < 6


def test_video_frames_are_exact_and_resume_frame_by_frame(tmp_path: Path, video: Path) -> None:
    out = tmp_path / "out"
    assert main(["remove-markers", str(video), "-o", str(out), "--frames", "-q"]) == 0
    names = sorted(p.name for p in (out / "grasp").iterdir())
    assert names == [f"{i:06d}.png" for i in range(N_FRAMES)]
    src = decode(video)
    for i, frame in enumerate(src):
        png = cv2.imread(str(out / "grasp" / f"{i:06d}.png"))
        assert png is not None
        np.testing.assert_array_equal(png, ts.remove_markers(frame, method="telea"))
        mask = marker_mask(frame)
        np.testing.assert_array_equal(png[~mask], frame[~mask])  # untouched off the markers
        assert (png[mask] != frame[mask]).any()
    (out / "grasp" / "000004.png").unlink()
    stamps = {p.name: p.stat().st_mtime_ns for p in (out / "grasp").iterdir()}
    assert main(["remove-markers", str(video), "-o", str(out), "--frames", "-q"]) == 0
    png = cv2.imread(str(out / "grasp" / "000004.png"))
    np.testing.assert_array_equal(png, ts.remove_markers(src[4], method="telea"))
    assert {p: (out / "grasp" / p).stat().st_mtime_ns for p in stamps} == stamps


def test_video_resumes_and_an_interrupted_video_is_redone(
        tmp_path: Path, video: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    calls = 0
    real = ts.remove_markers

    def interrupted(img: np.ndarray, **kw: object) -> np.ndarray:
        nonlocal calls
        calls += 1
        if calls == 5:
            raise KeyboardInterrupt
        return real(img, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(ts, "remove_markers", interrupted)
    assert main(["remove-markers", str(video), "-o", str(out), "--workers", "2", "-q"]) == 130
    assert list(out.iterdir()) == []  # no half video under the final name, no temporary file
    monkeypatch.setattr(ts, "remove_markers", real)
    (out / ".grasp.x1y2.part.mp4").write_bytes(b"left by a killed run")
    assert main(["remove-markers", str(video), "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".tacswitch-remove-markers.json", "grasp.mp4"]
    assert len(decode(out / "grasp.mp4")) == N_FRAMES
    stamp = (out / "grasp.mp4").stat().st_mtime_ns
    capsys.readouterr()
    assert main(["remove-markers", str(video), "-o", str(out)]) == 0
    assert (out / "grasp.mp4").stat().st_mtime_ns == stamp
    assert "0 written, 1 already done" in capsys.readouterr().out


def test_undecodable_frames_are_skipped_and_counted(tmp_path: Path, video: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    data = bytearray(video.read_bytes())
    start = len(data) // 3
    data[start:start + 3000] = bytes(3000)  # damages frames in the middle of the stream
    video.write_bytes(bytes(data))
    out = tmp_path / "out"
    assert main(["remove-markers", str(video), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    got = decode(out / "grasp.mp4")
    assert 0 < len(got) < N_FRAMES
    assert f"({len(got)} frames, {N_FRAMES - len(got)} unreadable skipped)" in text


@pytest.mark.parametrize("damage", ["garbage", "truncated"])
def test_corrupt_video_is_a_one_line_error(tmp_path: Path, video: Path, damage: str) -> None:
    data = video.read_bytes()
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video" * 100 if damage == "garbage" else data[:len(data) // 2])
    out = tmp_path / "out"
    assert main(["remove-markers", str(bad), "-o", str(out), "-q"]) == 1
    run = subprocess.run([sys.executable, "-m", "tacswitch", "remove-markers", str(bad), "-o",
                          str(out)], capture_output=True, text=True)
    assert run.returncode == 1
    assert "Traceback" not in run.stderr
    assert run.stderr.strip().count("\n") == 0  # one line: FFmpeg's own log is silenced
    assert "inputs: cannot decode video" in run.stderr and "bad.mp4" in run.stderr
    assert not out.exists() or not any(out.iterdir())


def test_two_inputs_with_one_output_name_are_refused(tmp_path: Path, grasp) -> None:
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        cv2.imwrite(str(tmp_path / folder / "0.png"), grasp.frames[0])
    args = ["remove-markers", str(tmp_path / "a"), str(tmp_path / "b"), "-o",
            str(tmp_path / "o"), "-q"]
    assert main(args) == 1
    assert not (tmp_path / "o").exists()


def test_workers_give_the_same_bytes_as_a_serial_run(tmp_path: Path, video: Path,
                                                     grasp) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    for i, f in enumerate(grasp.frames[:6]):
        cv2.imwrite(str(folder / f"img{i}.png"), f)
    video.rename(folder / video.name)  # a folder with images and a video
    outputs = {}
    for workers in (1, 3):
        for method in ("telea", "ns"):
            out = tmp_path / f"{method}-{workers}"
            assert main(["remove-markers", str(folder), "-o", str(out), "--method", method,
                         "--workers", str(workers), "-q"]) == 0
            assert main(["remove-markers", str(folder), "-o", str(out / "frames"), "--frames",
                         "--method", method, "--workers", str(workers), "-q"]) == 0
            outputs[method, workers] = {p.relative_to(out): p.read_bytes()
                                        for p in sorted(out.rglob("*")) if p.is_file()}
    for method in ("telea", "ns"):
        serial = outputs[method, 1]
        # The images twice (both runs), the video, its frames, each folder's record.
        assert len(serial) == 2 * 6 + 1 + N_FRAMES + 2
        assert Path("grasp.mp4") in serial and Path("frames/grasp/000008.png") in serial
        assert outputs[method, 3] == serial


def test_hybrid_video_uses_its_first_frame_as_the_reference(
        tmp_path: Path, video: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["remove-markers", str(video), "-o", str(out), "--method", "hybrid",
                 "--frames"]) == 0
    assert "hybrid reference (no contact) = frame 0" in capsys.readouterr().out
    src = decode(video)
    png = cv2.imread(str(out / "grasp" / f"{N_FRAMES - 1:06d}.png"))
    np.testing.assert_array_equal(png, ts.remove_markers(src[-1], method="hybrid", ref=src[0]))
    help_text = subprocess.run([sys.executable, "-m", "tacswitch", "remove-markers", "--help"],
                               capture_output=True, text=True).stdout
    help_text = " ".join(help_text.split())
    assert "first frame" in help_text and "--workers" in help_text and "--frames" in help_text


def test_an_output_never_replaces_its_input(tmp_path: Path, video: Path) -> None:
    before = video.read_bytes()
    # An unusable --out is a usage error (exit code 2, as argparse's).
    assert main(["remove-markers", str(video), "-o", str(video.parent), "--overwrite",
                 "-q"]) == 2
    assert video.read_bytes() == before
