"""``tacswitch slip`` finds where the grasp starts: contact onset, established contact, release.

Recordings are rendered (``tacswitch.sim``, simulated GelSight Mini): a no-contact lead-in, the
press and shear loading of the grasp, then a hold or a slip, and for the press recording the
release back to no contact.
"""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np
import pytest

from tacswitch import sim
from tacswitch.cli import main
from tacswitch.grasp.phases import GRASP, NO_CONTACT, PRESSING, GraspSegmenter, top_statistic
from tacswitch.sim.sequences import Kind

LEAD = 4  # no-contact frames before the press


def recording(kind: Kind, seed: int, release: bool) -> tuple[list[np.ndarray], int, int | None]:
    """Frames, the true grasp start and the true slip onset (frame indices in the recording)."""
    seq = sim.grasp_sequence("gelsight_mini", kind, n_frames=24, seed=seed)
    frames = [seq.reference] * LEAD + list(seq.frames)
    if release:  # unload: the shear and the press in reverse, then no contact again
        frames += list(seq.frames[: seq.grasp_start][::-1]) + [seq.reference] * 3
    onset = seq.slip.index(True) + LEAD if any(seq.slip) else None
    return frames, seq.grasp_start + LEAD, onset


def run_slip(tmp_path: Path, frames: list[np.ndarray], *extra: str) -> tuple[list[dict], str]:
    folder = tmp_path / "rec"
    folder.mkdir(exist_ok=True)
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{i:04d}.png"), f)
    log = tmp_path / "log.csv"
    return _rows(folder, log, *extra)


def _rows(folder: Path, log: Path, *extra: str) -> tuple[list[dict], str]:
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["slip", str(folder), "--log", str(log), *extra]) == 0
    with open(log) as fh:
        return list(csv.DictReader(fh)), buf.getvalue()


@pytest.mark.parametrize("rule", ["learned", "paper"])
@pytest.mark.parametrize("seed", [4, 7])
def test_a_press_recording_is_not_flagged_as_slip(tmp_path: Path, seed: int, rule: str) -> None:
    frames, start, _ = recording("hold", seed, release=True)
    rows, out = run_slip(tmp_path, frames, "--rule", rule)
    assert len(rows) == len(frames)
    flagged = [int(r["frame"]) for r in rows if r["slip"] == "1"]
    # Frame 0 as the start flagged the whole press and hold; now only (part of) the release.
    assert len(flagged) < 0.3 * len(frames)
    hold_end = LEAD + 24  # the last frame of the hold
    assert not [t for t in flagged if t < hold_end]
    starts = {r["grasp_start"] for r in rows if r["phase"] == GRASP}
    assert len(starts) == 1
    got = int(starts.pop())
    assert start <= got <= start + 2  # the established contact (after the shear ramp)
    assert f"grasp start: frame {got} (contact onset detected)" in out
    phases = [r["phase"] for r in rows]
    assert phases[:LEAD] == [NO_CONTACT] * LEAD and PRESSING in phases
    assert phases[-1] == NO_CONTACT  # released
    # Outside the grasp the rule does not run: no displacement logged.
    assert all(r["max_displacement_px"] == "" for r in rows if r["phase"] != GRASP)


def test_slip_after_a_no_contact_lead_in_is_detected(tmp_path: Path) -> None:
    frames, start, onset = recording("slip", 9, release=False)
    assert onset is not None
    rows, _ = run_slip(tmp_path, frames, "--rule", "paper")
    first = next(int(r["frame"]) for r in rows if r["slip"] == "1")
    assert onset <= first <= onset + 2
    # The same recording from frame 0 (the old behaviour): the press itself is "slip".
    rows0, out0 = run_slip(tmp_path, frames, "--start", "0", "--rule", "paper")
    first0 = next(int(r["frame"]) for r in rows0 if r["slip"] == "1")
    assert first0 < start
    assert "grasp start: frame 0 (--start)" in out0
    assert {r["grasp_start"] for r in rows0} == {"0"}


def test_explicit_start(tmp_path: Path) -> None:
    frames, start, _ = recording("slip", 9, release=False)
    rows, out = run_slip(tmp_path, frames, "--start", str(start), "--rule", "paper")
    assert [r["phase"] for r in rows[:start]] == ["before start"] * start
    assert all(r["slip"] == "0" for r in rows[:start])
    assert rows[start]["grasp_start"] == str(start) and rows[start]["slip"] == "0"
    assert f"grasp start: frame {start} (--start)" in out
    assert main(["slip", str(tmp_path / "rec"), "--log", str(tmp_path / "l.csv"), "--start",
                 "-1", "-q"]) == 2
    assert main(["slip", str(tmp_path / "rec"), "--log", str(tmp_path / "l.csv"), "--start",
                 "5", "--max-frames", "5", "-q"]) == 2


def test_smooth_frames_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    frames, start, onset = recording("slip", 9, release=False)
    assert onset is not None
    rows, _ = run_slip(tmp_path, frames, "--start", str(start), "--rule", "paper")
    first = next(int(r["frame"]) for r in rows if r["slip"] == "1")
    rows3, _ = run_slip(tmp_path, frames, "--start", str(start), "--smooth-frames", "3")
    first3 = next(int(r["frame"]) for r in rows3 if r["slip"] == "1")
    # The mean of the last 3 frames reaches the threshold later than each frame does.
    assert first < first3 <= first + 2
    capsys.readouterr()
    for bad in ("0", "1001"):
        assert main(["slip", str(tmp_path / "rec"), "--log", str(tmp_path / "l.csv"),
                     "--smooth-frames", bad, "-q"]) == 2
        assert capsys.readouterr().err.strip() == (f"tacswitch slip: error: --smooth-frames: "
                                                   f"must be in [1, 1000]; got {bad}")


def test_no_contact_at_all_reports_no_grasp(tmp_path: Path) -> None:
    seq = sim.grasp_sequence("gelsight_mini", "hold", n_frames=8, seed=1)
    rows, out = run_slip(tmp_path, [seq.reference] * 6)
    assert all(r["phase"] == NO_CONTACT and r["slip"] == "0" for r in rows)
    assert "no grasp detected (no contact onset; pass --start FRAME)" in out


def test_segmenter_ignores_one_mistracked_marker() -> None:
    seg = GraspSegmenter(1.6)
    n = 100
    valid = np.ones(n, bool)
    for _ in range(3):
        assert seg.update(np.zeros((n, 2)), valid).phase == NO_CONTACT
    glitch = np.zeros((n, 2))
    glitch[7] = (25.0, 0.0)  # one marker jumps: not a contact
    for _ in range(4):
        assert seg.update(glitch, valid).phase == NO_CONTACT
    press = np.zeros((n, 2))
    press[:10] = (1.0, 0.5)  # ten markers move: a contact
    steps = [seg.update(press * k, valid) for k in (1, 2, 3, 3)]
    assert [s.phase for s in steps][:2] == [NO_CONTACT, PRESSING]
    assert steps[1].onset == 7 and steps[3].starts and steps[3].start == 10
    # Back to rest for two frames: released.
    assert seg.update(np.zeros((n, 2)), valid).phase == GRASP
    assert seg.update(np.zeros((n, 2)), valid).phase == NO_CONTACT


def test_segmenter_noise_floor_raises_the_onset_level() -> None:
    rng = np.random.default_rng(0)
    seg = GraspSegmenter(1.6)
    n = 80
    for _ in range(10):  # a noisy tracker: every marker jitters by ~0.3 px
        step = seg.update(rng.normal(0, 0.3, (n, 2)), np.ones(n, bool))
        assert step.phase == NO_CONTACT
    assert seg.on_level > 0.25 * 1.6  # above the plain fraction of the threshold
    assert top_statistic(np.array([])) == 0.0
    with pytest.raises(ValueError, match="threshold_px"):
        GraspSegmenter(0.0)


def test_learned_rule_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    frames, _, _ = recording("hold", 4, release=True)
    rows, out = run_slip(tmp_path, frames)  # the learned rule is the default
    assert "(learned rule)" in out
    scored = [r for r in rows if r["score"] != ""]
    assert scored and all(r["phase"] in (PRESSING, GRASP) for r in scored)
    # A threshold below every score flags every scored frame, and only those.
    rows_low, _ = run_slip(tmp_path, frames, "--score-threshold=-1e9")
    assert [r["slip"] == "1" for r in rows_low] == [r["score"] != "" for r in rows_low]
    # Every member of the committee has fired on each scored frame; unscored rows say nothing.
    from tacswitch.grasp.train import COMMITTEE

    assert {r["votes"] for r in rows_low if r["score"] != ""} == {str(COMMITTEE)}
    assert {r["votes"] for r in rows_low if r["score"] == ""} == {""}
    assert all(int(r["votes"]) <= COMMITTEE for r in rows if r["votes"] != "")
    capsys.readouterr()
    rec = str(tmp_path / "rec")
    log = str(tmp_path / "l.csv")
    for extra, msg in ((["--rule", "learned", "--threshold-px", "2"],
                        "--threshold-px: applies to --rule paper only"),
                       (["--rule", "paper", "--score-threshold", "1"],
                        "--score-threshold: applies to --rule learned only"),
                       (["--score-threshold", "nan"], "--score-threshold: must be finite"),
                       (["--rule", "paper", "--votes", "2"],
                        "--votes: applies to --rule learned only"),
                       (["--votes", "0"], "--votes: must be >= 1"),
                       (["--votes", "99"], "--votes: must be >= 1, at most the committee's"),
                       (["--slip-model", str(tmp_path / "none.onnx")], "--slip-model")):
        assert main(["slip", rec, "--log", log, "-q", *extra]) == 2
        err = capsys.readouterr().err
        assert msg in err and err.count("\n") == 1, err


def test_frame_rate_of_the_source(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    frames, _, _ = recording("hold", 4, release=True)
    # A video file states its rate; at 50 frames/s the motion is resampled to the scorer's 25.
    video = tmp_path / "fast.avi"
    out = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 50.0,
                          (frames[0].shape[1], frames[0].shape[0]))
    for f in frames:
        out.write(f)
    out.release()
    rows, text = _rows(video, tmp_path / "v.csv")
    assert len(rows) == len(frames)
    assert "50 frames/s resampled to the scorer's 25" in text
    # --fps overrides the file; a folder of images has no rate of its own.
    _, text = _rows(video, tmp_path / "v.csv", "--fps", "25")
    assert "(learned rule)" in text
    _, text = run_slip(tmp_path, frames, "--fps", "100")
    assert "100 frames/s resampled" in text
    _, text = run_slip(tmp_path, frames, "--fps", "12.5")  # slower: read frame by frame
    assert "(learned rule)" in text
    capsys.readouterr()
    rec, log = str(tmp_path / "rec"), str(tmp_path / "l.csv")
    for extra, msg in ((["--fps", "0"], "--fps: must be a frame rate"),
                       (["--fps", "nan"], "--fps: must be a frame rate"),
                       (["--rule", "paper", "--fps", "30"], "--fps: applies to --rule learned")):
        assert main(["slip", rec, "--log", log, "-q", *extra]) == 2
        err = capsys.readouterr().err
        assert msg in err and err.count("\n") == 1, err
