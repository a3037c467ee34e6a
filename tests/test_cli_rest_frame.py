"""The rest frame of ``tacswitch track`` / ``tacswitch slip`` when the first frame is unusable.

Recordings are rendered (``tacswitch.sim``, simulated GelSight Mini) and written as lossless
FFV1 videos (the same frame decodes the same in every video, so logs compare exactly); the
unusable lead-in is blank grey frames (a camera settling) or a frame whose markers are mostly
hidden.
"""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np
import pytest

from tacswitch import sim
from tacswitch.cli import main, rest_frame
from tacswitch.cli.rest_frame import choose_rest_frame

LEAD = 4  # no-contact frames before the press
BLANK = 3  # blank frames before them


@pytest.fixture(scope="module")
def seq() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "slip", n_frames=30, seed=9)


def blank(seq: sim.GraspSequence) -> np.ndarray:
    return np.full_like(seq.reference, 128)


def write_video(path: Path, frames: list[np.ndarray]) -> Path:
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"FFV1"), 30, (w, h))
    assert writer.isOpened()
    for f in frames:
        writer.write(f)
    writer.release()
    return path


def recording(seq: sim.GraspSequence) -> list[np.ndarray]:
    return [seq.reference] * LEAD + list(seq.frames)


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path) as fh:
        return list(csv.DictReader(fh))


# --- the choice itself ---------------------------------------------------------------------

def _frames(*counts: int | None) -> list[np.ndarray | None]:
    """Stand-in frames whose first pixel is their marker count (None: unreadable), on a steady
    grey (the camera settled: :func:`tacswitch.tracking.settled_index` finds nothing)."""
    out: list[np.ndarray | None] = []
    for c in counts:
        if c is None:
            out.append(None)
            continue
        f = np.full((16, 16, 3), 128, np.uint8)
        f[0, 0] = c
        out.append(f)
    return out


def _count(frame: np.ndarray) -> int:
    return int(frame[0, 0, 0])


def test_a_usable_first_frame_is_the_rest_frame_and_the_stream_is_replayed() -> None:
    frames = _frames(40, 42, None, 44, 41)
    rest, stream = choose_rest_frame(iter(frames), _count, source="s")
    assert rest is not None and rest.index == 0 and rest.best == 44
    assert [f is None or _count(f) for f in stream] == [40, 42, True, 44, 41]


def test_the_first_frame_with_half_the_best_count_is_chosen() -> None:
    # Unreadable frames are not numbered (as in the commands' logs).
    rest, stream = choose_rest_frame(iter(_frames(0, None, 9, 30, 44, 40)), _count, source="s")
    assert rest is not None
    assert (rest.index, rest.markers, rest.first, rest.best, rest.best_index) == (2, 30, 0, 44, 3)
    assert len(list(stream)) == 6
    msg = rest.message()
    assert "frame 0 shows no markers" in msg and "so frame 2 is the rest frame (30 markers;" in msg
    assert "frames 0-1 are not tracked" in msg and "\n" not in msg


def test_the_look_ahead_is_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rest_frame, "LOOK_AHEAD", 3)
    read: list[int] = []

    def counting(frame: np.ndarray) -> int:
        read.append(_count(frame))
        return _count(frame)

    rest, _ = choose_rest_frame(iter(_frames(20, 21, 22, 50, 50)), counting, source="s")
    assert rest is not None and rest.index == 0 and read == [20, 21, 22]
    with pytest.raises(ValueError, match=r"source: no markers found in the first frame of 'v' "
                                         r"nor in the 2 after it"):
        choose_rest_frame(iter(_frames(0, 0, 0, 50)), _count, source="v")
    rest, _ = choose_rest_frame(iter(_frames(10, 50)), _count, source="s", max_frames=1)
    assert rest is not None and rest.index == 0 and rest.looked == 1


def test_a_stream_error_is_raised_where_it_happened() -> None:
    def camera():  # type: ignore[no-untyped-def]
        yield from _frames(0, 30)
        raise ConnectionError("camera 0 stopped delivering frames")

    rest, stream = choose_rest_frame(camera(), _count, source="0")
    assert rest is not None and rest.index == 1
    got = []
    with pytest.raises(ConnectionError):
        for f in stream:
            got.append(_count(f))  # type: ignore[arg-type]
    assert got == [0, 30]


# --- the commands ----------------------------------------------------------------------------

def test_track_starts_at_the_first_frame_with_markers(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    frames = [blank(seq)] * BLANK + recording(seq)
    video = write_video(tmp_path / "v.mkv", frames)
    out = tmp_path / "t.csv"
    assert main(["track", str(video), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tacswitch track: warning: source: frame 0 shows "
                                               "no markers")
    assert f"so frame {BLANK} is the rest frame (" in err[0]
    assert f"frames 0-{BLANK - 1} are not tracked" in err[0]
    rows = read_csv(out)
    # Frame numbers are the video's: the blank frames have no rows, the rest frame has no motion.
    assert sorted({int(r["frame"]) for r in rows}) == list(range(BLANK, len(frames)))
    first = [r for r in rows if int(r["frame"]) == BLANK]
    assert len(first) >= 0.9 * len(seq.rest)
    assert all(float(r["dx"]) == 0 and float(r["dy"]) == 0 for r in first)
    # The same motion as the recording without the blank lead-in.
    clean = write_video(tmp_path / "c.mkv", recording(seq))
    assert main(["track", str(clean), "-o", str(tmp_path / "c.csv"), "-q"]) == 0
    assert capsys.readouterr().err == ""
    ref = read_csv(tmp_path / "c.csv")
    assert [{**r, "frame": str(int(r["frame"]) + BLANK)} for r in ref] == rows


@pytest.mark.parametrize("extra", [[], ["--rule", "paper"], ["--rule", "paper", "--start", "9"]])
def test_slip_log_keeps_the_video_frame_numbers(tmp_path: Path, seq: sim.GraspSequence,
                                                capsys: pytest.CaptureFixture[str],
                                                extra: list[str]) -> None:
    frames = [blank(seq)] * BLANK + recording(seq)
    video = write_video(tmp_path / "v.mkv", frames)
    log = tmp_path / "l.csv"
    assert main(["slip", str(video), "--log", str(log), "-q", *extra]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tacswitch slip: warning: source: frame 0 shows "
                                               "no markers")
    rows = read_csv(log)
    assert [int(r["frame"]) for r in rows] == list(range(BLANK, len(frames)))
    # The recording without the lead-in, --start moved with it: the same log, BLANK frames on.
    shifted = list(extra)
    if "--start" in shifted:
        i = shifted.index("--start") + 1
        shifted[i] = str(int(shifted[i]) - BLANK)
    clean = write_video(tmp_path / "c.mkv", recording(seq))
    assert main(["slip", str(clean), "--log", str(tmp_path / "c.csv"), "-q", *shifted]) == 0
    ref = read_csv(tmp_path / "c.csv")
    assert any(r["grasp_start"] for r in ref) and any(r["slip"] == "1" for r in ref)

    def moved(r: dict[str, str]) -> dict[str, str]:
        return {**r, "frame": str(int(r["frame"]) + BLANK), "time_s": "",
                "grasp_start": r["grasp_start"] and str(int(r["grasp_start"]) + BLANK)}

    assert [moved(r) for r in ref] == [{**r, "time_s": ""} for r in rows]


def test_slip_start_before_the_rest_frame_starts_there(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    video = write_video(tmp_path / "v.mkv", [blank(seq)] * BLANK + recording(seq))
    log = tmp_path / "l.csv"
    assert main(["slip", str(video), "--log", str(log), "--start", "1"]) == 0
    cap = capsys.readouterr()
    rows = read_csv(log)
    assert {r["grasp_start"] for r in rows} == {str(BLANK)}
    assert f"grasp start: frame {BLANK} (--start 1, before the rest frame)" in cap.out


def test_a_first_frame_with_most_markers_hidden_is_passed_over(
        tmp_path: Path, seq: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    covered = seq.reference.copy()
    w = covered.shape[1]
    covered[:, : 3 * w // 4] = 128  # three quarters of the gel show no marker
    video = write_video(tmp_path / "v.mkv", [covered, *recording(seq)])
    out = tmp_path / "t.csv"
    assert main(["track", str(video), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err
    assert "source: frame 0 shows only " in err and "so frame 1 is the rest frame (" in err
    assert "frame 0 is not tracked" in err
    assert min(int(r["frame"]) for r in read_csv(out)) == 1


@pytest.mark.parametrize("command", ["track", "slip"])
def test_no_usable_frame_within_the_look_ahead_is_a_one_line_error(
        tmp_path: Path, seq: sim.GraspSequence, command: str,
        capsys: pytest.CaptureFixture[str]) -> None:
    # The markers appear only after the look-ahead: the command stops, naming the source.
    n = rest_frame.LOOK_AHEAD
    video = write_video(tmp_path / "v.mkv", [blank(seq)] * n + recording(seq)[:3])
    out = ["--log", str(tmp_path / "l.csv")] if command == "slip" else ["-o",
                                                                          str(tmp_path / "t.csv")]
    assert main([command, str(video), *out, "-q"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(video) in err
    assert f"no markers found in the first frame of {str(video)!r} nor in the {n - 1} after it" \
        in err


def test_usable_rest_frame_rule() -> None:
    """The one rule behind the CLI's chooser and the ROS processor."""
    from tacswitch.tracking import usable_rest_frame

    assert usable_rest_frame([]) is None
    assert usable_rest_frame([0, 0, 0]) is None
    assert usable_rest_frame([40, 42, 41]) == 0
    assert usable_rest_frame([0, 25, 41]) == 1   # 25 >= half of 41
    assert usable_rest_frame([10, 20, 41]) == 2  # 10 and 20 below half of 41
    assert usable_rest_frame([10, 20, 41], fraction=0.4) == 1
