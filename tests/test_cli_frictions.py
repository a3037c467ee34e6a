"""The command-line frictions a newcomer hit (issue 32): each case failed before its fix.

Usage errors exit 2 with one line naming the option (``tacswitch CMD: error: --opt ...``, as
argparse's own), never a traceback; warnings and help agree with what the tool does.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

import tacswitch as ts
from tacswitch import sim
from tacswitch.cli import build_parser, main


@pytest.fixture(scope="module")
def grasp() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=2)


@pytest.fixture
def image(tmp_path: Path, grasp: sim.GraspSequence) -> Path:
    path = tmp_path / "frame.png"
    cv2.imwrite(str(path), grasp.frames[3])
    return path


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``main(argv)`` in this process: (exit code, stdout, stderr); argparse's own usage
    errors (SystemExit) included."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def usage_error(code: int, err: str, command: str, option: str) -> None:
    """Exit 2, no traceback, and the last line ``tacswitch COMMAND: error: ...`` names
    ``option`` (argparse prints its usage line above its own errors)."""
    assert code == 2, err
    assert "Traceback" not in err, err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"tacswitch {command}: error: "), err
    assert option in last, err


def help_text(*command: str) -> str:
    """The help of a (sub-)command, whitespace collapsed."""
    parser = build_parser()
    for name in command:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[name]
    return " ".join(parser.format_help().split())


# --- 1. bench in the base install (no taxim) ------------------------------------------------

def test_bench_without_taxim_skips_the_real_table_in_one_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "taxim", None)  # `import taxim` fails, as without it
    out = tmp_path / "bench"
    code, _, err = run(["bench", "--frames", "1", "--rounds", "1", "--radii", "3", "--steps", "",
                        "--real", "1", "-o", str(out), "-q"], capsys)
    assert code == 0, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "taxim" in lines[0] and "--real" in lines[0], err
    text = (out / "bench.md").read_text()
    assert "Real frames" not in text and "--real 0" in text
    assert (out / "bench.png").is_file() and not (out / "bench_real.png").exists()


def test_bench_quick_without_pyav_skips_the_real_table_in_one_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # The quick real-frame cases include an H.264 capture, which needs PyAV (the train extra).
    from tacswitch import tradeoff

    monkeypatch.setitem(sys.modules, "av", None)  # `import av` fails, as without it
    monkeypatch.setattr(tradeoff, "tacdiff_methods", lambda *a, **k: {})  # time: not the point
    out = tmp_path / "bench"
    code, _, err = run(["bench", "--quick", "-o", str(out), "-q"], capsys)
    assert code == 0, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "PyAV" in lines[0] and "--real" in lines[0], err
    assert "--quick" in (out / "bench.md").read_text()
    assert (out / "bench.png").is_file() and not (out / "bench_real.png").exists()


# --- 2. slip --show without a GUI or a display ----------------------------------------------

@pytest.mark.parametrize("build, display, says", [
    ("GUI:                           NONE\n", ":0", "opencv-contrib-python"),
    ("GUI:                           GTK3\n", None, "no display"),
])
def test_slip_show_says_what_it_needs_before_any_work(
        tmp_path: Path, image: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str], build: str, display: str | None,
        says: str) -> None:
    monkeypatch.setattr(cv2, "getBuildInformation", lambda: f"\n  {build}")
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if display is None:
        monkeypatch.delenv("DISPLAY", raising=False)
    else:
        monkeypatch.setenv("DISPLAY", display)
    log = tmp_path / "log.csv"
    code, _, err = run(["slip", str(image), "--show", "--log", str(log), "-q"], capsys)
    usage_error(code, err, "slip", "--show")
    assert says in err and err.count("\n") == 1
    assert not log.exists()  # refused before any work


# --- 4. remove-markers resumes only what the same options made ------------------------------

def test_remove_markers_redoes_outputs_of_other_options(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    argv = ["remove-markers", str(image), "-o", str(out)]
    assert run(argv, capsys)[1].startswith("")  # telea
    telea = cv2.imread(str(out / "frame.png"))
    code, stdout, _ = run([*argv, "--method", "ns"], capsys)
    assert code == 0 and "1 written, 0 already done" in stdout, stdout
    ns = cv2.imread(str(out / "frame.png"))
    assert not np.array_equal(ns, telea)
    np.testing.assert_array_equal(ns, ts.remove_markers(cv2.imread(str(image)), method="ns"))
    # Same options again: resumed (nothing redone).
    code, stdout, _ = run([*argv, "--method", "ns"], capsys)
    assert code == 0 and "0 written, 1 already done" in stdout, stdout
    # The record names the options that made each output.
    record = json.loads((out / ".tacswitch-remove-markers.json").read_text())
    key = record["outputs"]["frame.png"].split(":")[0]
    assert record["options"][key]["--method"] == "ns"
    # An output with no record (a folder from before the record) is redone.
    (out / ".tacswitch-remove-markers.json").unlink()
    code, stdout, _ = run([*argv, "--method", "ns"], capsys)
    assert code == 0 and "1 written, 0 already done" in stdout, stdout


def test_remove_markers_redoes_an_output_of_another_input_of_the_same_name(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A dataset's experiments each hold a camera_0.avi: removed one after another into one
    # folder, the second must not be "already done" with the first one's output.
    first, second = tmp_path / "exp_1" / "frame.png", tmp_path / "exp_2" / "frame.png"
    for path, img in ((first, cv2.imread(str(image))),
                      (second, cv2.flip(cv2.imread(str(image)), 1))):
        path.parent.mkdir()
        cv2.imwrite(str(path), img)
    out = tmp_path / "out"
    assert run(["remove-markers", str(first), "-o", str(out)], capsys)[0] == 0
    code, stdout, _ = run(["remove-markers", str(second), "-o", str(out)], capsys)
    assert code == 0 and "1 written, 0 already done" in stdout, stdout
    np.testing.assert_array_equal(cv2.imread(str(out / "frame.png")),
                                  ts.remove_markers(cv2.imread(str(second))))
    # The same input again: resumed; the input edited since: redone.
    code, stdout, _ = run(["remove-markers", str(second), "-o", str(out)], capsys)
    assert code == 0 and "0 written, 1 already done" in stdout, stdout
    cv2.imwrite(str(second), cv2.imread(str(first)))
    os.utime(second, ns=(second.stat().st_atime_ns, second.stat().st_mtime_ns + 10**9))
    code, stdout, _ = run(["remove-markers", str(second), "-o", str(out)], capsys)
    assert code == 0 and "1 written, 0 already done" in stdout, stdout


def test_remove_markers_warns_where_it_finds_no_marker(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((120, 160, 3), 128, np.uint8))
    video = tmp_path / "blank.mkv"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"FFV1"), 25, (160, 120))
    for _ in range(3):
        writer.write(np.full((120, 160, 3), 128, np.uint8))
    writer.release()
    out = tmp_path / "out"
    code, _, err = run(["remove-markers", str(image), str(blank), str(video), "-o",
                             str(out), "-q"], capsys)
    assert code == 0 and (out / "blank.png").exists() and (out / "blank.mp4").exists()
    warned = [line for line in err.splitlines() if "no markers found" in line]
    assert len(warned) == 2, err  # the blank image and the blank video, not the marker frame
    assert str(blank) in warned[0] and "--threshold" in warned[0]
    assert str(video) in warned[1]


def test_a_frames_folder_of_other_options_is_redone_whole(
        tmp_path: Path, grasp: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    video = tmp_path / "rec.mkv"
    h, w = grasp.reference.shape[:2]
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"FFV1"), 25, (w, h))
    frames = [grasp.reference, *grasp.frames[:2]]
    for f in frames:
        writer.write(f)
    writer.release()
    out = tmp_path / "out"
    argv = ["remove-markers", str(video), "-o", str(out), "--frames", "-q"]
    assert run(argv, capsys)[0] == 0
    assert run([*argv, "--method", "ns"], capsys)[0] == 0
    for i, f in enumerate(frames):
        np.testing.assert_array_equal(cv2.imread(str(out / "rec" / f"{i:06d}.png")),
                                      ts.remove_markers(f, method="ns"))


# --- 5. warnings that argued with the tool --------------------------------------------------

def test_the_codec_warning_says_how_remove_markers_writes_a_good_video(
        tmp_path: Path, grasp: sim.GraspSequence, capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.cli.slip import _warn_inter_frame_codec

    path = tmp_path / "clean.mp4"  # what remove-markers writes by default (mp4v)
    h, w = grasp.reference.shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), 25, (w, h))
    for f in grasp.frames[:3]:
        writer.write(f)
    writer.release()
    capsys.readouterr()
    _warn_inter_frame_codec(str(path))
    err = capsys.readouterr().err
    assert "warning" in err and "--codec ffv1" in err, err
    assert "slip --markerless" in help_text("remove-markers")


def test_the_ref_warning_does_not_ask_for_the_ref_it_was_given(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.sim.scene import render_sample

    frame = render_sample("gelsight_mini", 0).reference  # markerless, no contact
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(4):
        cv2.imwrite(str(folder / f"{i}.png"), frame)
    cv2.imwrite(str(tmp_path / "ref.png"), frame)
    code, _, err = run(["slip", str(folder), "--markerless", "--rule", "paper", "--start", "0",
                        "--ref", str(tmp_path / "ref.png"), "--log", str(tmp_path / "s.csv"),
                        "-q"], capsys)
    assert code == 0, err
    assert "shows no contact" in err, err  # still warned: every marker is judged
    assert "pass --ref" not in err, err


# --- 6. track -o never replaces a non-CSV file ----------------------------------------------

def test_track_refuses_to_write_csv_over_an_image(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = image.read_bytes()
    code, _, err = run(["track", str(image), "-o", str(image)], capsys)
    usage_error(code, err, "track", "--out")
    assert ".csv" in err and err.count("\n") == 1
    assert image.read_bytes() == before
    code, _, err = run(["slip", str(image), "--log", str(image), "-q"], capsys)
    usage_error(code, err, "slip", "--log")
    assert image.read_bytes() == before


# --- 7. help and behaviour ------------------------------------------------------------------

def test_biharmonic_is_not_recommended_over_telea_on_real_frames() -> None:
    text = help_text("remove-markers")
    assert "better on contact shading" not in text
    assert "TELEA does not" in text and "grey ghosts" in text


def test_downstream_quick_help_and_default_output(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    text = help_text("evaluate", "downstream")
    assert "about a minute" not in text and "a few minutes" in text
    pytest.importorskip("torch")
    pytest.importorskip("torchvision")
    from tacswitch.downstream import data, study

    seen = {}
    monkeypatch.setattr(data, "build_dataset", lambda *a, **k: None)
    monkeypatch.setattr(study, "run_study",
                        lambda data_dir, out, *a, **k: seen.setdefault("out", out) and [])
    monkeypatch.setattr(study, "summarise", lambda records: {})
    monkeypatch.setattr(study, "markdown", lambda summary: "report")
    code, _, err = run(["evaluate", "downstream", "--data", str(tmp_path / "study"), "--quick",
                        "-q"], capsys)
    assert code == 0, err
    assert seen["out"] == tmp_path / "study"  # not study/study
    assert (tmp_path / "study" / "report.md").is_file()


def test_simulate_draws_no_bar_into_a_file(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["simulate", "--preset", "gelsight_mini", "--n", "1", "--workers", "1",
                        "--out", str(tmp_path / "d")], capsys)
    assert code == 0, err
    assert "\r" not in err and "items/s" not in err, repr(err)


def test_folders_are_read_in_natural_order(tmp_path: Path, image: Path) -> None:
    from tacswitch.cli.sources import collect_images, collect_inputs, frames

    folder = tmp_path / "seq"
    folder.mkdir()
    names = ["540.png", "60.png", "frame_10.png", "frame_2.png", "7.png"]
    img = cv2.imread(str(image))
    for k, name in enumerate(names):
        cv2.imwrite(str(folder / name), np.full_like(img, 10 * k))
    want = ["7.png", "60.png", "540.png", "frame_2.png", "frame_10.png"]
    assert [p.name for p in collect_images([str(folder)])] == want
    assert [p.name for p in collect_inputs([str(folder)])[0]] == want
    levels = [int(f[0, 0, 0]) for f in frames(str(folder)) if f is not None]
    assert levels == [10 * names.index(n) for n in want]


def _cut_marker_image(x_cut: float) -> np.ndarray:
    """A 9 x 6 grid of soft dark dots on grey gel, one more dot centred at ``x_cut`` on the
    right edge (about half of it visible)."""
    h, w = 240, 320
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.full((h, w), 170.0, np.float32)
    centres = [(30.0 + 32 * i, 40.0 + 32 * j) for i in range(9) for j in range(6)]
    centres.append((x_cut, 120.0))
    for cx, cy in centres:
        d = np.hypot(xx - cx, yy - cy)
        img -= 90.0 * np.clip(6.0 - d, 0.0, 1.0)
    return cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)


@pytest.mark.parametrize("x_cut", [319.3, 319.8, 320.4])
def test_exclude_border_lists_no_centre_outside_the_frame(x_cut: float) -> None:
    img = _cut_marker_image(x_cut)
    h, w = img.shape[:2]
    m = ts.extract_markers(img, exclude_border=True)
    assert len(m) >= 54
    c = m.centres
    assert (c[:, 0] >= 0).all() and (c[:, 1] >= 0).all(), c[c.min(1) < 0]
    assert (c[:, 0] <= w - 1).all() and (c[:, 1] <= h - 1).all(), c[(c[:, 0] > w - 1)]
    # The mask still covers the cut marker (removal must fill it).
    assert m.mask[120, w - 1]


def test_track_options_have_help() -> None:
    text = help_text("track")
    assert "--max-frames N stop after the first N frames" in text
    assert "--polarity {dark,bright} markers darker" in text


# --- 8. usage errors exit 2 and name the option ---------------------------------------------

@pytest.mark.parametrize("argv, option", [
    (["demo", "--frames", "3"], "--frames"),
    (["demo", "--frames", "100000000"], "--frames"),
    (["demo", "--preset", "nope"], "--preset"),
    (["track", "IMG", "--max-dist", "-1"], "--max-dist"),
    (["track", "IMG", "--max-dist", "nan"], "--max-dist"),
    (["markers", "IMG", "--max-aspect", "0.5"], "--max-aspect"),
    (["slip", "IMG", "--rigid-threshold-px", "-2"], "--rigid-threshold-px"),
    (["slip", "IMG", "--rule", "paper", "--threshold-px", "inf"], "--threshold-px"),
    (["simulate", "--n", "-1"], "--n"),
    (["simulate", "--preset", "nope"], "--preset"),
    (["simulate", "--seed", "-1"], "--seed"),
    (["simulate", "--jpeg", "101"], "--jpeg"),
    (["simulate", "--jpeg", "-1"], "--jpeg"),
    (["simulate", "--frames", "5"], "--frames"),
    (["motion", "IMG", "--centres", "BAD"], "--centres"),
    (["motion", "IMG", "--scale", "1e308"], "--scale"),
    (["motion", "IMG", "--scale", "nan"], "--scale"),
    (["bench", "--frames", "0"], "--frames"),
    (["bench", "--preset", "nope"], "--preset"),
])
def test_usage_errors_exit_2_naming_the_option(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
        option: str) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    out = tmp_path / "out"
    args = [str(image) if a == "IMG" else str(bad) if a == "BAD" else a for a in argv]
    flag = {"demo": "-o", "track": "-o", "markers": "-o", "slip": "--log", "simulate": "--out",
            "motion": "-o", "bench": "-o"}[argv[0]]
    target = out / "x.csv" if argv[0] in ("track", "slip") else out
    code, _, err = run([*args, flag, str(target)], capsys)
    usage_error(code, err, argv[0], option)
    assert not out.exists()  # refused before any work


def test_demo_checks_its_folder_before_rendering(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "report.png"
    blocker.write_bytes(b"not a folder")
    code, _, err = run(["demo", "-q", "-o", str(blocker / "sub")], capsys)
    usage_error(code, err, "demo", "-o/--out")
    code, _, err = run(["demo", "-q", "-o", str(blocker)], capsys)
    usage_error(code, err, "demo", "-o/--out")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc")
@pytest.mark.parametrize("argv, option", [
    (["track", "IMG", "-o", "/proc/t.csv"], "--out"),
    (["slip", "IMG", "--log", "/proc/s.csv"], "--log"),
    (["simulate", "--n", "1", "--out", "/proc/tacswitch-nope/d"], "--out"),
    (["markers", "IMG", "-o", "/proc"], "--out"),
])
def test_unwritable_outputs_exit_2(image: Path, capsys: pytest.CaptureFixture[str],
                                   argv: list[str], option: str) -> None:
    # /proc refuses new files even to root (where permission bits do not).
    code, _, err = run([str(image) if a == "IMG" else a for a in argv], capsys)
    usage_error(code, err, argv[0], option)


@pytest.mark.parametrize("argv, option", [
    (["train", "motion", "--out", "OUT", "--data", "OUT", "--epochs", "0"], "--epochs"),
    (["train", "motion", "--out", "OUT"], "--data"),
    (["train", "motion", "--out", "OUT", "--data", "OUT", "--split", "pair_train"],
     "--split"),
    (["finetune", "--images", "IMG", "--out", "OUT", "--ring", "-1"], "--ring"),
    (["finetune", "--images", "IMG", "--out", "OUT", "--offset", "x"], "--offset"),
    (["train", "slip", "OUT", "--out", "OUT/s.onnx", "--epochs", "0"], "--epochs"),
    (["train", "slip", "OUT", "--out", "OUT/s.onnx", "--workers", "0"], "--workers"),
    (["train", "tacdiff", "--data", "OUT", "--out", "OUT", "--crop", "20"], "--crop"),
    (["export", "tacdiff", "OUT/none.pt", "-o", "OUT/m.onnx"], "checkpoint"),
    (["export", "motion", "IMG", "-o", "OUT/m.onnx", "--preset", "nope"], "--preset"),
    (["export", "tacdiff", "IMG", "-o", "/proc/m.onnx"], "--out"),
    (["evaluate", "downstream", "--data", "OUT", "--seeds", "1"], "--seeds"),
    (["evaluate", "tacdiff", "--fid", "--presets", "gelsight,nope"], "--presets"),
    (["evaluate", "tacdiff", "--fid", "--steps", "0"], "--steps"),
])
def test_training_commands_check_options_before_torch(
        tmp_path: Path, image: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str], argv: list[str], option: str) -> None:
    monkeypatch.setitem(sys.modules, "torch", None)  # as without the train extra
    args = [str(image) if a == "IMG" else a.replace("OUT", str(tmp_path / "o")) for a in argv]
    code, _, err = run(args, capsys)
    usage_error(code, err, argv[0], option)
    assert "torch" not in err


def test_evaluate_fid_without_torch_says_so_before_rendering(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "torch", None)
    from tacswitch import tradeoff

    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("rendered frames before looking for torch")

    monkeypatch.setattr(tradeoff, "simulated_frames", refuse)
    code, _, err = run(["evaluate", "tacdiff", "--fid", "--frames", "1"], capsys)
    assert code == 1 and "--fid needs torch" in err and "Traceback" not in err, err


def test_training_without_torch_says_so_once_the_options_pass(
        tmp_path: Path, image: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "torch", None)
    code, _, err = run(["finetune", "--images", str(image), "--out", str(tmp_path / "o")],
                       capsys)
    assert code == 1 and "needs torch" in err and "Traceback" not in err


# --- 11. package metadata -------------------------------------------------------------------

def test_package_metadata_names_home_page_and_authors() -> None:
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml")
                            .read_text())["project"]
    assert project["authors"] and project["authors"][0]["name"]
    urls = project["urls"]
    # pip show prints the "Homepage" project URL as Home-page when there is no home-page field.
    assert urls["Homepage"].startswith("https://")
    assert {"Repository", "Issues"} <= set(urls)


@pytest.mark.parametrize("command", ["markers", "motion"])
def test_two_inputs_with_one_name_are_refused_before_any_work(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str], command: str) -> None:
    other = tmp_path / "b" / image.name
    other.parent.mkdir()
    other.write_bytes(image.read_bytes())
    out = tmp_path / "out"
    code, _, err = run([command, str(image), str(other), "-o", str(out), "-q"], capsys)
    assert code == 1 and "Traceback" not in err, err
    last = err.strip().splitlines()[-1]
    assert "would both write" in last and str(other) in last, err
    assert not list(out.glob("*.csv"))


def test_the_same_input_twice_is_named_as_such(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["markers", str(image), str(image), "-o", str(tmp_path / "o")], capsys)
    assert code == 1 and f"inputs: {str(image)!r} is given twice" in err, err


def test_when_no_input_can_be_read_the_first_reason_is_given(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tiny = []
    for k in range(2):
        tiny.append(tmp_path / f"tiny{k}.png")
        cv2.imwrite(str(tiny[-1]), np.zeros((1, 1, 3), np.uint8))
    code, _, err = run(["motion", *map(str, tiny), "-o", str(tmp_path / "o"), "-q"], capsys)
    last = err.strip().splitlines()[-1]
    assert code == 1 and "none of the 2 inputs could be read" in last, err
    assert "the first: inputs: " in last and "too small" in last, err


def test_motion_skips_an_image_it_cannot_read_as_asked_and_names_it(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), np.zeros((1, 1, 3), np.uint8))
    out = tmp_path / "out"
    code, _, err = run(["motion", str(image), str(tiny), "-o", str(out), "-q"], capsys)
    assert code == 0, err
    assert "skipped 1 input that could not be used" in err and str(tiny) in err, err
    assert (out / f"{image.stem}.csv").is_file()


def test_motion_names_ref_when_its_size_differs(
        tmp_path: Path, image: Path, grasp: sim.GraspSequence,
        capsys: pytest.CaptureFixture[str]) -> None:
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), cv2.resize(grasp.frames[0], None, fx=0.5, fy=0.5))
    video = tmp_path / "clip.avi"
    h, w = grasp.frames[0].shape[:2]
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 25, (w, h))
    for f in grasp.frames:
        writer.write(f)
    writer.release()
    for inputs in ([str(image)], [str(video)]):
        code, _, err = run(["motion", *inputs, "--ref", str(small), "-o",
                            str(tmp_path / "out"), "-q"], capsys)
        assert code == 1 and "Traceback" not in err, err
        assert err.strip().splitlines()[-1].startswith("tacswitch motion: error: --ref: shape"), err


@pytest.mark.parametrize("extra, flag", [
    (["--threshold", "1e9"], "--threshold"),
    (["--block-size", "301"], "--block-size"),
    (["--min-area", "100", "--max-area", "10"], "--max-area"),
])
def test_extraction_values_the_library_refuses_name_the_flag(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str], extra: list[str],
        flag: str) -> None:
    code, _, err = run(["markers", str(image), "-o", str(tmp_path / "out"), *extra], capsys)
    usage_error(code, err, "markers", flag)


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_a_folder_that_refuses_new_files_is_named_as_such(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # /proc exists but refuses new files with "no such file or directory" (ENOENT).
    code, _, err = run(["slip", str(image), "--log", "/proc/x.csv"], capsys)
    usage_error(code, err, "slip", "--log")
    assert "does not accept new files" in err and "no such file" not in err
