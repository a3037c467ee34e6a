"""The command line, end to end on generated data in temporary folders."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tacswitch import sim
from tacswitch.cli import main


@pytest.fixture(scope="module")
def grasp() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "slip", n_frames=24, seed=4)


@pytest.fixture
def frame_folder(tmp_path: Path, grasp: sim.GraspSequence) -> Path:
    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "0000.png"), grasp.frames[grasp.grasp_start - 1])
    for i, f in enumerate(grasp.frames[grasp.grasp_start:], start=1):
        cv2.imwrite(str(folder / f"{i:04d}.png"), f)
    return folder


@pytest.fixture
def video(tmp_path: Path, grasp: sim.GraspSequence) -> Path:
    path = tmp_path / "grasp.avi"
    h, w = grasp.reference.shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 30, (w, h))
    assert writer.isOpened()
    for f in [grasp.reference, *grasp.frames]:
        writer.write(f)
    writer.release()
    return path


def test_demo_writes_a_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "-o", str(tmp_path / "d"), "--frames", "16"]) == 0
    out = capsys.readouterr().out
    report = cv2.imread(str(tmp_path / "d" / "report.png"))
    assert report is not None and report.shape[0] > 400
    assert "slip detected at frame" in out and "no slip" in out
    assert "marker removal (TELEA) on a simulated" in out
    assert "marker removal (TacDiff hybrid) on a simulated" in out
    assert "motion from markerless frames" in out
    assert "for zero motion" in out


@pytest.mark.parametrize("preset", ["gelsight", "gelsight_mini"])
def test_demo_motion_panel_agrees_with_its_truth(preset: str) -> None:
    import re

    from tacswitch.cli.demo import _motion_panel

    _, lines = _motion_panel(preset, 0, 640)
    found = re.search(r"direction cosine (-?[0-9.]+), error mean ([0-9.]+) px against "
                      r"([0-9.]+) px for zero motion", lines[0])
    assert found, lines[0]
    cos, err, zero = map(float, found.groups())
    assert cos >= 0.8
    assert err < zero


def test_markers_command_writes_csv_json_and_overlay(tmp_path: Path, grasp) -> None:
    img = tmp_path / "ref.png"
    cv2.imwrite(str(img), grasp.reference)
    assert main(["markers", str(img), "-o", str(tmp_path / "o"), "--overlay", "-q"]) == 0
    with open(tmp_path / "o" / "ref.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(grasp.rest)
    assert (tmp_path / "o" / "ref_markers.png").is_file()
    assert main(["markers", str(img), "-o", str(tmp_path / "j"), "--format", "json", "-q"]) == 0
    data = json.loads((tmp_path / "j" / "ref.json").read_text())
    assert len(data["markers"]) == len(grasp.rest)


def test_slip_on_a_folder_detects_the_slip(tmp_path: Path, frame_folder: Path, grasp) -> None:
    log = tmp_path / "log.csv"
    # The folder starts in the established grasp (no contact onset to find): --start 0; the
    # paper's rule (its detection delay is what is checked).
    assert main(["slip", str(frame_folder), "--log", str(log), "-q", "--start", "0",
                 "--rule", "paper"]) == 0
    with open(log) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(grasp.frames) - grasp.grasp_start + 1
    first = next(int(r["frame"]) for r in rows if r["slip"] == "1")
    onset = grasp.slip.index(True) - grasp.grasp_start + 1
    assert onset <= first <= onset + 3


def test_slip_rigid_only_still_detects_the_slip(tmp_path: Path, frame_folder: Path) -> None:
    log = tmp_path / "log.csv"
    args = ["slip", str(frame_folder), "--log", str(log), "-q", "--rigid-threshold-px", "auto",
            "--rigid-only", "--start", "0"]
    assert main(args) == 0
    with open(log) as fh:
        rows = list(csv.DictReader(fh))
    assert any(r["slip"] == "1" and r["criterion"] == "rigid" for r in rows)

def test_slip_rigid_only_without_its_threshold_names_the_flags(
        tmp_path: Path, frame_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "log.csv"
    assert main(["slip", str(frame_folder), "--log", str(log), "-q", "--rigid-only"]) == 2
    err = capsys.readouterr().err
    assert "--rigid-only" in err and "--rigid-threshold-px" in err
    assert "use_displacement" not in err and err.count("\n") == 1


def test_slip_survives_corrupt_frames(tmp_path: Path, frame_folder: Path) -> None:
    (frame_folder / "0005.png").write_bytes(b"not a png")
    log = tmp_path / "log.csv"
    assert main(["slip", str(frame_folder), "--log", str(log), "-q"]) == 0
    assert sum(1 for _ in open(log)) > 10


def test_a_video_cut_short_is_said_to_be_not_just_skipped_frames(
        tmp_path: Path, video: Path, frame_folder: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    import re

    data = video.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: int(len(data) * 0.6)])  # the container still counts every frame
    for command in (["track", str(cut), "-o", str(tmp_path / "t.csv")],
                    ["slip", str(cut), "--log", str(tmp_path / "s.csv")]):
        capsys.readouterr()
        assert main(command) == 0
        out = capsys.readouterr().out
        m = re.search(r"\((\d+) skipped, the last (\d+) at the end of the source: a video cut "
                      r"short\?\)", out)
        assert m and int(m.group(1)) == int(m.group(2)) > 0, out
    # A damaged frame in the middle is only skipped.
    (frame_folder / "0005.png").write_bytes(b"not a png")
    assert main(["track", str(frame_folder), "-o", str(tmp_path / "f.csv")]) == 0
    out = capsys.readouterr().out
    assert "(1 skipped)" in out and "cut short" not in out


def test_track_video_writes_motion_per_frame(tmp_path: Path, video: Path, grasp) -> None:
    out = tmp_path / "track.csv"
    assert main(["track", str(video), "-o", str(out), "-q"]) == 0
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    n_markers = len(grasp.rest)
    assert len(rows) == n_markers * (len(grasp.frames) + 1)
    last = [r for r in rows if int(r["frame"]) == len(grasp.frames)]
    moved = np.array([float(r["dx"]) for r in last if r["valid"] == "1"])
    assert len(moved) > 0.9 * n_markers and np.abs(moved).max() > 5


def test_remove_markers_resumes(tmp_path: Path, grasp) -> None:
    src = tmp_path / "in"
    src.mkdir()
    for i in range(3):
        cv2.imwrite(str(src / f"{i}.png"), grasp.frames[i])
    out = tmp_path / "out"
    assert main(["remove-markers", str(src), "-o", str(out), "-q"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".tacswitch-remove-markers.json", "0.png",
                                                     "1.png", "2.png"]
    stamp = (out / "1.png").stat().st_mtime_ns
    assert main(["remove-markers", str(src), "-o", str(out), "-q"]) == 0
    assert (out / "1.png").stat().st_mtime_ns == stamp
    clean = cv2.imread(str(out / "0.png"))
    assert clean is not None and clean.shape == grasp.frames[0].shape


def test_progress_bars_go_to_stderr_and_quiet_silences_them(
        tmp_path: Path, frame_folder: Path, video: Path, grasp,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.cli import progress

    monkeypatch.setattr(progress, "DELAY_S", 0.0)  # draw at once (the real runs wait 1 s)
    monkeypatch.setattr(progress, "stderr_is_terminal", lambda: True)  # as on a terminal
    n_folder = len(list(frame_folder.iterdir()))
    runs = {
        "remove-markers": (["remove-markers", str(frame_folder), "-o", str(tmp_path / "rm"),
                            "--overwrite"], n_folder),
        "markers": (["markers", str(frame_folder), "-o", str(tmp_path / "mk")], n_folder),
        "track": (["track", str(video), "-o", str(tmp_path / "t.csv")], len(grasp.frames) + 1),
        "slip": (["slip", str(frame_folder), "--log", str(tmp_path / "s.csv")], n_folder),
    }
    for name, (args, n) in runs.items():
        capsys.readouterr()
        assert main(args) == 0, name
        loud = capsys.readouterr()
        assert "100%|" in loud.err and f"{n}/{n}" in loud.err, name
        assert "%|" not in loud.out and "\r" not in loud.out, name  # stdout stays parseable
        assert main([*args, "-q"]) == 0, name
        quiet = capsys.readouterr()
        assert quiet.err == "" and quiet.out == "", name
    with open(tmp_path / "t.csv") as fh:
        assert next(csv.reader(fh)) == ["frame", "marker", "x_ref", "y_ref", "dx", "dy", "valid"]
    # stderr redirected to a file or a pipe: no bar at all (the summary is on stdout).
    monkeypatch.setattr(progress, "stderr_is_terminal", lambda: False)
    for name, (args, _) in runs.items():
        assert main(args) == 0, name
        assert capsys.readouterr().err == "", name


def test_no_bar_for_a_short_job(tmp_path: Path, frame_folder: Path,
                                monkeypatch: pytest.MonkeyPatch,
                                capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.cli import progress

    monkeypatch.setattr(progress, "stderr_is_terminal", lambda: True)
    one = tmp_path / "one"
    one.mkdir()
    (one / "a.png").write_bytes((frame_folder / "0001.png").read_bytes())
    assert main(["markers", str(one), "-o", str(tmp_path / "m")]) == 0  # well under 1 s
    assert capsys.readouterr().err == ""


def test_user_mistakes_are_one_line_errors(tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "tacswitch", "slip", str(tmp_path / "missing.mp4"),
           "--log", str(tmp_path / "l.csv")]
    out = subprocess.run(cmd, capture_output=True, text=True)
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    assert out.stderr.strip().count("\n") == 0 and "missing.mp4" in out.stderr
    out = subprocess.run([sys.executable, "-m", "tacswitch", "nope"], capture_output=True,
                         text=True)
    assert out.returncode == 2


def test_every_command_has_help() -> None:
    from tacswitch.cli import COMMANDS

    for name in COMMANDS:
        out = subprocess.run([sys.executable, "-m", "tacswitch", name, "--help"],
                             capture_output=True, text=True)
        assert out.returncode == 0 and "usage" in out.stdout


def test_bench_writes_table_and_plot(tmp_path: Path) -> None:
    assert main(["bench", "-o", str(tmp_path / "b"), "--quick", "-q"]) == 0
    table = (tmp_path / "b" / "bench.md").read_text()
    # The simulated table, then (since --quick has real-frame proxy cases) the real-frame one.
    sim_part, _, real_part = table.partition("## Real frames")
    assert sim_part.count("TELEA (tacswitch)") == 2 and "NS (OpenCV)" in sim_part
    assert real_part.count("TELEA (tacswitch)") == 2
    assert "yes" in table  # a Pareto-optimal setting is marked
    assert cv2.imread(str(tmp_path / "b" / "bench.png")) is not None


def test_train_and_evaluate_subcommands_have_help() -> None:
    for cmd in (["train", "motion"], ["evaluate", "motion"]):
        out = subprocess.run([sys.executable, "-m", "tacswitch", *cmd, "--help"],
                             capture_output=True, text=True)
        assert out.returncode == 0 and "usage" in out.stdout and "--data" in out.stdout


@pytest.fixture(scope="module")
def motion_pair() -> dict:
    """A contact under two loads, an indenter never seen in training: markerless frames."""
    from tacswitch.motion import data as mdata

    classes, _ = mdata.split_spec("test_indenter")
    return mdata.render_pair_sample("gelsight_mini", np.random.SeedSequence([5, 1]),
                                    classes=classes)


def _read_motion_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    pts = np.array([[float(r["x"]), float(r["y"])] for r in rows], np.float32)
    return pts, np.array([[float(r["dx"]), float(r["dy"])] for r in rows], np.float32)


def test_motion_command_matches_predict_motion(tmp_path: Path, motion_pair: dict) -> None:
    import tacswitch as ts
    from tacswitch.motion.infer import load_model

    img, ref, rest = motion_pair["image"], motion_pair["reference"], motion_pair["rest"]
    cv2.imwrite(str(tmp_path / "img.png"), img)
    cv2.imwrite(str(tmp_path / "ref.png"), ref)
    centres = tmp_path / "centres.csv"
    centres.write_text("x,y\n" + "".join(f"{x},{y}\n" for x, y in rest))
    out = tmp_path / "o"
    assert main(["motion", str(tmp_path / "img.png"), "--ref", str(tmp_path / "ref.png"),
                 "--centres", str(centres), "-o", str(out), "-q"]) == 0
    pts, motion = _read_motion_csv(out / "img.csv")
    np.testing.assert_allclose(pts, rest, atol=1e-3)
    np.testing.assert_allclose(motion, ts.predict_motion(img, ref, rest), atol=1e-3)
    assert np.abs(motion).max() > 0.5  # a loaded contact: the markers moved
    drawn = cv2.imread(str(out / "img_motion.png"))
    assert drawn is not None and drawn.shape == img.shape
    # Without --centres: the model's grid scaled to the frame.
    assert main(["motion", str(tmp_path / "img.png"), "--ref", str(tmp_path / "ref.png"),
                 "-o", str(tmp_path / "g"), "-q"]) == 0
    pts, _ = _read_motion_csv(tmp_path / "g" / "img.csv")
    np.testing.assert_allclose(pts, load_model().centres_for(*img.shape[:2]), atol=1e-3)
    # The shipped model's reference is optional: without --ref, the single-frame motion.
    assert main(["motion", str(tmp_path / "img.png"), "-o", str(tmp_path / "n"), "-q"]) == 0
    # Every method of predict_motion is reachable, with the same numbers.
    assert main(["motion", str(tmp_path / "img.png"), "--centres", str(centres),
                 "--method", "mechanics", "-o", str(tmp_path / "k"), "-q"]) == 0
    _, motion = _read_motion_csv(tmp_path / "k" / "img.csv")
    np.testing.assert_allclose(motion, ts.predict_motion(img, None, rest, method="mechanics"),
                               atol=1e-3)
    # --method ensemble: --model names its learned part (here not the default one).
    assert main(["motion", str(tmp_path / "img.png"), "--centres", str(centres),
                 "--method", "ensemble", "--model", "default", "-o", str(tmp_path / "e"),
                 "-q"]) == 0
    _, motion = _read_motion_csv(tmp_path / "e" / "img.csv")
    other = ts.predict_motion(img, None, rest, method="ensemble", model="default")
    np.testing.assert_allclose(motion, other, atol=1e-3)
    assert np.abs(other - ts.predict_motion(img, None, rest, method="ensemble")).max() > 0.01
    # --gain: a sensor name or a number, as predict_motion takes it.
    for gain, value in (("gelsight_mini", "gelsight_mini"), ("0.5", 0.5)):
        assert main(["motion", str(tmp_path / "img.png"), "--centres", str(centres),
                     "--gain", gain, "-o", str(tmp_path / "k"), "-q"]) == 0
        _, motion = _read_motion_csv(tmp_path / "k" / "img.csv")
        np.testing.assert_allclose(motion, ts.predict_motion(img, None, rest, gain=value),
                                   atol=1e-3)
    centres.write_bytes(b"\x93NUMPY")
    assert main(["motion", str(tmp_path / "img.png"), "--ref", str(tmp_path / "ref.png"),
                 "--centres", str(centres), "-o", str(out), "-q"]) == 2  # names --centres


def test_motion_sequence_is_the_markerless_tracker(tmp_path: Path, mini,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.motion.sequence import MarkerlessTracker

    frames = tmp_path / "video"
    frames.mkdir()
    video = [mini.f0, mini.imgs[6], np.roll(mini.imgs[6], 3, axis=1)]
    for k, f in enumerate(video):
        cv2.imwrite(str(frames / f"{k:03d}.png"), f)
    cv2.imwrite(str(tmp_path / "ref.png"), mini.f0)
    # --ref; without it the first frame is the no-contact frame, or with --starts-in-contact
    # the anchor (the rule on it).
    for k, (opts, first) in enumerate([(["--ref", str(tmp_path / "ref.png")], mini.f0),
                                       ([], video[0]),
                                       (["--starts-in-contact", "--gain", "gelsight"], None)]):
        out = tmp_path / f"o{k}"
        assert main(["motion", str(frames), *opts, "--sequence", "-o", str(out), "-q"]) == 0
        tr = MarkerlessTracker(first, gain="gelsight")
        for k, f in enumerate(video):
            pts, motion = _read_motion_csv(out / f"{k:03d}.csv")
            np.testing.assert_allclose(motion, tr.update(f), atol=1e-3)
            assert tr.centres is not None
            np.testing.assert_allclose(pts, tr.centres, atol=1e-3)
    assert main(["motion", str(frames), "--sequence", "--method", "flow", "--ref",
                 str(tmp_path / "ref.png"), "-o", str(tmp_path / "x"), "-q"]) == 2
    # Options that would be ignored are refused, naming themselves.
    for src, opts, flag in (
            (frames, ["--sequence", "--starts-in-contact", "--ref", str(tmp_path / "ref.png")],
             "--starts-in-contact"),
            (frames, ["--sequence", "--starts-in-contact", "--anchor", "rest"], "--anchor"),
            (frames, ["--sequence", "--gain", "gelsight"], "--gain"),
            (frames, ["--sequence", "--ref", str(tmp_path / "ref.png"), "--gain", "0.3"],
             "--gain"),
            (frames / "001.png", ["--starts-in-contact"], "--starts-in-contact")):
        capsys.readouterr()
        assert main(["motion", str(src), *opts, "-o", str(tmp_path / "x"), "-q"]) == 2
        assert capsys.readouterr().err.startswith(f"tacswitch motion: error: {flag}:")


def test_motion_anchor_reaches_the_tracker(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    from gel_fixtures import _gel, _moved, _pressed_and_sheared

    from tacswitch.motion.sequence import MarkerlessTracker

    f0 = _gel()
    press, _ = _pressed_and_sheared(f0, 3.0)
    video = [press, _moved(press, (3.0, -2.0))[0]]
    frames = tmp_path / "video"
    frames.mkdir()
    for k, f in enumerate(video):
        cv2.imwrite(str(frames / f"{k:03d}.png"), f)
    ref = tmp_path / "ref.png"
    cv2.imwrite(str(ref), f0)
    got = {}
    for anchor in ("contact", "rest"):
        out = tmp_path / anchor
        assert main(["motion", str(frames), "--ref", str(ref), "--sequence", "--anchor", anchor,
                     "-o", str(out), "-q"]) == 0
        pts, got[anchor] = _read_motion_csv(out / "001.csv")
        tr = MarkerlessTracker(f0, pts, anchor=anchor)
        tr.update(video[0])
        np.testing.assert_allclose(got[anchor], tr.update(video[1]), atol=1e-3)
    assert np.abs(got["contact"] - got["rest"]).max() > 0.1  # the option changed the motion
    capsys.readouterr()
    for extra, says in ((["--sequence", "--starts-in-contact"], "with --starts-in-contact"),
                        (["--ref", str(ref)], "applies to a video, a bag or --sequence")):
        src = str(frames) if "--sequence" in extra else str(frames / "001.png")
        assert main(["motion", src, *extra, "--anchor", "rest", "-o", str(tmp_path / "x"),
                     "-q"]) == 2
        err = capsys.readouterr().err
        assert "--anchor" in err and says in err, err


def test_motion_rest_frames_reaches_the_tracker(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    from gel_fixtures import _gel, _pressed_and_sheared

    from tacswitch.motion.sequence import MarkerlessTracker

    clean = _gel(3, grain_sd=2.0)
    rng = np.random.default_rng(1)
    noisy = [np.clip(np.rint(f + rng.normal(0, 4.0, f.shape)), 0, 255).astype(np.uint8)
             for f in [clean] * 6 + [_pressed_and_sheared(clean, 3.0)[0]]]
    frames = tmp_path / "video"
    frames.mkdir()
    for k, f in enumerate(noisy):
        cv2.imwrite(str(frames / f"{k:03d}.png"), f)
    got = {}
    for n in (None, 16):
        out = tmp_path / f"n{n}"
        extra = [] if n is None else ["--rest-frames", str(n)]
        assert main(["motion", str(frames), "--sequence", *extra, "-o", str(out), "-q"]) == 0
        pts, got[n] = _read_motion_csv(out / f"{len(noisy) - 1:03d}.csv")
        tr = MarkerlessTracker(noisy[0], pts, **({} if n is None else {"rest_frames": n}))
        for f in noisy[:-1]:
            tr.update(f)
        # Still frames 1-5 of 6: the three followed by two more still frames are averaged in.
        assert tr.rest_count == (1 if n is None else 4)
        np.testing.assert_allclose(got[n], tr.update(noisy[-1]), atol=1e-3)
    assert np.abs(got[None] - got[16]).max() > 0.01  # the averaged reference changed the motion
    for extra, says in ((["--sequence", "--starts-in-contact"], "with --starts-in-contact"),
                        ([], "applies to a video, a bag or --sequence")):
        src = str(frames) if "--sequence" in extra else str(frames / "001.png")
        capsys.readouterr()
        assert main(["motion", src, *extra, "--rest-frames", "4", "-o", str(tmp_path / "x"),
                     "-q"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("tacswitch motion: error: --rest-frames:") and says in err, err
    for bad in ("0", "99999999999"):
        with pytest.raises(SystemExit):
            main(["motion", str(frames), "--sequence", "--rest-frames", bad, "-o",
                  str(tmp_path / "x"), "-q"])
        err = capsys.readouterr().err
        assert "--rest-frames" in err and "expected a whole number in [1, " in err, err


def test_motion_flow_preset_reaches_the_tracker_and_the_pairwise_flow(
        tmp_path: Path, mini, capsys: pytest.CaptureFixture[str]) -> None:
    import tacswitch as ts
    from tacswitch.motion.sequence import MarkerlessTracker

    frames = tmp_path / "video"
    frames.mkdir()
    video = [mini.imgs[6], np.roll(mini.imgs[6], 3, axis=1)]
    for k, f in enumerate(video):
        cv2.imwrite(str(frames / f"{k:03d}.png"), f)
    ref = tmp_path / "ref.png"
    cv2.imwrite(str(ref), mini.f0)
    out = tmp_path / "seq"
    assert main(["motion", str(frames), "--ref", str(ref), "--sequence", "--flow-preset",
                 "balanced", "-o", str(out), "-q"]) == 0
    balanced = MarkerlessTracker(mini.f0, preset="balanced")
    default = MarkerlessTracker(mini.f0)
    for tr in (balanced, default):
        tr.update(video[0])
    _, got = _read_motion_csv(out / "001.csv")
    np.testing.assert_allclose(got, balanced.update(video[1]), atol=1e-3)
    assert np.abs(got - default.update(video[1])).max() > 1e-3  # the option changed the flow
    pair = tmp_path / "pair"
    assert main(["motion", str(frames / "001.png"), "--ref", str(ref), "--method", "flow",
                 "--flow-preset", "medium", "-o", str(pair), "-q"]) == 0
    pts, got = _read_motion_csv(pair / "001.csv")
    np.testing.assert_allclose(got, ts.predict_motion(video[1], mini.f0, pts, method="flow",
                                                      preset="medium"), atol=1e-3)
    assert main(["motion", str(frames / "001.png"), "--ref", str(ref), "--method", "flow",
                 "--flow-preset", "accurate", "-o", str(pair), "-q"]) == 0
    pts, got = _read_motion_csv(pair / "001.csv")
    np.testing.assert_allclose(got, ts.predict_motion(video[1], mini.f0, pts, method="flow",
                                                      preset="accurate"), atol=1e-3)
    capsys.readouterr()
    assert main(["motion", str(frames / "001.png"), "--method", "mechanics", "--flow-preset",
                 "balanced", "-o", str(pair), "-q"]) == 2
    err = capsys.readouterr().err
    assert "--flow-preset" in err and "runs no optical flow" in err
    with pytest.raises(SystemExit):  # argparse refuses an unknown preset
        main(["motion", str(frames), "--flow-preset", "quick", "-o", str(pair), "-q"])


def test_motion_on_a_video_tracks_it_as_one_sequence(tmp_path: Path) -> None:
    from gel_fixtures import _gel, _pressed_and_sheared

    from tacswitch.cli.sources import video_frames
    from tacswitch.motion.sequence import MarkerlessTracker

    f0 = _gel()
    path = tmp_path / "press.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (320, 240))
    for a in (0.0, 3.0, 6.0):
        writer.write(f0 if a == 0 else _pressed_and_sheared(f0, a)[0])
    writer.release()
    cv2.imwrite(str(tmp_path / "ref.png"), f0)
    out = tmp_path / "o"
    assert main(["motion", str(path), "--ref", str(tmp_path / "ref.png"), "-o", str(out),
                 "-q"]) == 0
    with open(out / "press.csv") as fh:
        rows = list(csv.DictReader(fh))
    tr = MarkerlessTracker(f0)
    frames = list(video_frames(path))
    assert len(rows) == 99 * len(frames) == 297  # the default grid, every frame
    for t, img in enumerate(frames):
        want = tr.update(img)
        got = np.array([[float(r["dx"]), float(r["dy"])] for r in rows if int(r["frame"]) == t])
        np.testing.assert_allclose(got, want, atol=1e-3)
    assert np.hypot(*want.T).max() > 2.0  # the press shows
    assert (out / "press_motion.png").is_file()
    assert main(["motion", str(path), "--method", "mechanics", "-o", str(out), "-q"]) == 2


def test_train_motion_tiny_run_exports_a_usable_model(tmp_path: Path,
                                                      motion_pair: dict) -> None:
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.motion.infer import MotionModel

    run = tmp_path / "run"
    args = ["train", "motion", "--data", str(tmp_path / "d"), "--simulate", "4", "--split",
            "pair_train", "--use-ref", "--epochs", "1", "--max-steps", "1", "--batch", "2",
            "--out", str(run), "-q"]
    assert main(args) == 0
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["pair_train_000.npz"]
    log = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    assert [e["epoch"] for e in log] == [1]
    model = MotionModel(run / "model.onnx", threads=1)
    assert model.use_ref and model.arch == "unet" and model.default_centres.shape == (99, 2)
    assert json.loads(model.metadata["tacswitch.trained_on"])["split"] == "pair_train"
    got = model(motion_pair["image"], motion_pair["reference"], motion_pair["rest"])
    assert got.shape == (99, 2) and np.isfinite(got).all()
    # Rerunning a finished run resumes: no further epoch.
    assert main(args) == 0
    assert len((run / "log.jsonl").read_text().splitlines()) == 1
    # Pair targets without the reference frame as input cannot be learned: refused.
    assert main([a for a in args if a != "--use-ref"]) == 2


def test_evaluate_motion_tiny_run(tmp_path: Path) -> None:
    report = tmp_path / "eval.json"
    assert main(["evaluate", "motion", "--data", str(tmp_path / "d"), "--n", "4", "--slip", "1",
                 "--json", str(report), "-q"]) == 0
    res = json.loads(report.read_text())
    # The shipped model is a pair model: the pair split is evaluated too.
    for split in ("test_depth", "test_indenter", "test_press", "pair_test_indenter"):
        r = res[split]
        assert r["regressor"]["nan_pct"] == 0.0
        assert r["zero"]["e_rmse_mean"] == pytest.approx(r["zero"]["e_mag_mean"])
        # The held-out contacts moved the markers; a pure press barely moves a GelSight Mini's
        # gel (the press law measured on real presses, sim.presets), only the others do.
        assert r["zero"]["e_rmse_mean"] > (0.005 if split == "test_press" else 0.1)
        if "tracking" in r:  # tracking on the true marker images: near exact
            assert r["tracking"]["e_rmse_median"] < 0.2
    assert res["slip"]["predicted"]["n"] == 3 and res["slip"]["tracked"]["n"] == 3
    assert main(["evaluate", "motion", "--data", str(tmp_path / "d"), "--n", "1", "-q"]) == 2
