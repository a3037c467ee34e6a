"""User mistakes on the command line: wrong models, unusable paths, ignored options, noise.

Each case must end in one line on stderr that names the option, with the documented exit code
(2: an option's value cannot be used; 1: the inputs cannot be processed), never a traceback.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tacswitch import sim
from tacswitch.cli import main

SHIPPED = Path(__file__).resolve().parents[1] / "python" / "tacswitch" / "models"


@pytest.fixture(scope="module")
def grasp() -> sim.GraspSequence:
    return sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=2)


@pytest.fixture
def image(tmp_path: Path, grasp: sim.GraspSequence) -> Path:
    path = tmp_path / "frame.png"
    cv2.imwrite(str(path), grasp.frames[3])
    return path


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    """The installed entry point in a fresh process (what a user sees, OpenCV's log included)."""
    return subprocess.run([sys.executable, "-m", "tacswitch", *args], capture_output=True,
                          text=True)


def one_line(run: subprocess.CompletedProcess[str], *needles: str) -> None:
    err = run.stderr.strip()
    assert "Traceback" not in run.stderr, run.stderr
    assert err.count("\n") == 0, run.stderr
    assert "[Errno" not in err, err
    for needle in needles:
        assert needle in err, err


def test_an_image_given_as_a_model_is_one_line(tmp_path: Path, image: Path) -> None:
    run = cli("remove-markers", str(image), "-o", str(tmp_path / "o"), "--method", "tacdiff",
              "--model", str(image))
    assert run.returncode == 2
    one_line(run, "--model", "frame.png", "not an ONNX model")
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_a_tacdiff_model_given_to_motion_is_refused(tmp_path: Path, image: Path) -> None:
    tacdiff = SHIPPED / "tacdiff_unet.onnx"
    assert tacdiff.is_file()
    run = cli("motion", str(image), "--ref", str(image), "--model", str(tacdiff), "-o",
              str(tmp_path / "m"))
    assert run.returncode == 2
    one_line(run, "--model", "TacDiff", "marker-motion model")
    assert not (tmp_path / "m").exists()


def test_a_motion_model_given_to_tacdiff_is_refused(tmp_path: Path, image: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    motion = SHIPPED / "motion_unet.onnx"
    assert main(["remove-markers", str(image), "-o", str(tmp_path / "o"), "--method", "hybrid",
                 "--model", str(motion), "-q"]) == 2
    err = capsys.readouterr().err
    assert "--model" in err and "marker-motion model" in err and "expected a TacDiff" in err


def test_the_library_refuses_a_model_of_the_wrong_kind(grasp: sim.GraspSequence) -> None:
    import tacswitch as ts

    frame = grasp.frames[3]
    with pytest.raises(ValueError, match=r"^model: .*TacDiff marker-removal model"):
        ts.predict_motion(frame, grasp.reference, model=SHIPPED / "tacdiff_unet.onnx")
    with pytest.raises(ValueError, match=r"^model: .*marker-motion model"):
        ts.remove_markers(frame, method="tacdiff", model=SHIPPED / "motion_unet.onnx")


def test_a_model_file_that_is_not_onnx_is_one_line_in_the_library(tmp_path: Path,
                                                                   image: Path) -> None:
    from tacswitch._ort import open_session

    with pytest.raises(ValueError, match=r"^model: .*not an ONNX model") as info:
        open_session(image)
    assert "\n" not in str(info.value)
    with pytest.raises(FileNotFoundError, match=r"^model: no ONNX file"):
        open_session(tmp_path / "missing.onnx")


def test_unwritable_output_paths_name_the_option(tmp_path: Path, image: Path) -> None:
    # track -o existing-file/t.csv: a file where a folder must be.
    run = cli("track", str(image), "-o", str(image / "t.csv"))
    assert run.returncode == 2
    one_line(run, "--out", "is a file, not a folder")
    # -o file/out for a folder output.
    run = cli("remove-markers", str(image), "-o", str(image / "out"))
    assert run.returncode == 2
    one_line(run, "--out", "is a file, not a folder")
    run = cli("markers", str(image), "-o", str(image))
    assert run.returncode == 2
    one_line(run, "--out", "is a file; give a folder")
    run = cli("slip", str(image), "--log", str(tmp_path))
    assert run.returncode == 2
    one_line(run, "--log", "is a folder")


def test_missing_option_files_name_the_option(tmp_path: Path, image: Path) -> None:
    run = cli("motion", str(image), "--ref", str(image), "--centres",
              str(tmp_path / "missing.csv"), "-o", str(tmp_path / "m"))
    assert run.returncode == 2
    one_line(run, "--centres", "missing.csv")
    run = cli("remove-markers", str(image), "-o", str(tmp_path / "o"), "--method", "hybrid",
              "--ref", str(tmp_path / "nope.png"))
    assert run.returncode == 2
    one_line(run, "--ref", "nope.png")


def test_system_errors_have_no_errno_prefix() -> None:
    from tacswitch.cli import _one_line

    exc = FileNotFoundError(2, "No such file or directory", "x.csv")
    assert _one_line(exc) == "no such file or directory: 'x.csv'"
    assert _one_line(ValueError("a\n  b")) == "a b"


def test_options_the_method_ignores_are_a_warning(tmp_path: Path, image: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["remove-markers", str(image), "-o", str(tmp_path / "o"), "--steps", "4",
                 "--ref", str(image), "-q"]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "--steps is ignored by --method telea" in err
    assert "--ref is ignored by --method telea" in err
    assert main(["remove-markers", str(image), "-o", str(tmp_path / "p"), "-q"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("command", ["slip", "track"])
def test_max_frames_zero_is_a_proper_message(tmp_path: Path, image: Path, command: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = ["--log", str(tmp_path / "l.csv")] if command == "slip" else ["-o",
                                                                          str(tmp_path / "t.csv")]
    assert main([command, str(image.parent), *out, "--max-frames", "0", "-q"]) == 2
    err = capsys.readouterr().err
    assert "--max-frames: must be >= 1" in err and "no readable frames" not in err


@pytest.mark.parametrize("command", ["slip", "track"])
def test_a_blank_first_frame_says_no_markers(tmp_path: Path, command: str,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "blank"
    folder.mkdir()
    for i in range(3):
        cv2.imwrite(str(folder / f"{i}.png"), np.full((60, 80, 3), 128, np.uint8))
    out = ["--log", str(tmp_path / "l.csv")] if command == "slip" else ["-o",
                                                                          str(tmp_path / "t.csv")]
    assert main([command, str(folder), *out, "-q"]) == 1
    assert "no markers found in the first frame" in capsys.readouterr().err


def test_opencv_and_libpng_messages_do_not_leak(tmp_path: Path, grasp: sim.GraspSequence) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(3):
        cv2.imwrite(str(folder / f"{i}.png"), grasp.frames[i])
    _, buf = cv2.imencode(".png", grasp.frames[4])
    data = bytearray(buf.tobytes())
    data[len(data) // 2] ^= 0xFF  # a CRC error inside the image data: libpng complains
    (folder / "3.png").write_bytes(bytes(data))
    (folder / "4.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 20)  # OpenCV warns
    for args in (["remove-markers", str(folder), "-o", str(tmp_path / "o"), "-q"],
                 ["markers", str(folder), "-o", str(tmp_path / "m"), "-q"],
                 ["slip", str(folder), "--log", str(tmp_path / "l.csv"), "-q"],
                 ["track", str(folder), "-o", str(tmp_path / "t.csv"), "-q"]):
        run = cli(*args)
        assert run.returncode == 0, run.stderr
        # Only the command's own lines: the skipped files named in one warning.
        lines = run.stderr.splitlines()
        assert all(line.startswith("tacswitch ") for line in lines), run.stderr
        assert "libpng error" not in run.stderr and "WARN:" not in run.stderr, run.stderr
        if args[0] in ("remove-markers", "markers"):
            assert len(lines) == 1 and "skipped 2 inputs that could not be used" in lines[0]
            assert "3.png" in lines[0] and "4.png" in lines[0]


def test_exit_codes_are_documented() -> None:
    for name in ("remove-markers", "markers"):
        text = " ".join(cli(name, "--help").stdout.split())
        assert "Exit status: 0" in text and "1 when no input could be read" in text


@pytest.mark.parametrize("args, says", [
    (["--gain", "digit_x"], "--gain: unknown sensor 'digit_x'"),
    (["--gain", "-1"], "--gain:"),
    (["--gain", "0.3", "--method", "flow", "--ref", "IMG"],
     "--gain: applies to method='mechanics'"),
])
def test_motion_gain_errors_name_the_option(tmp_path: Path, image: Path, args: list[str],
                                            says: str) -> None:
    argv = [str(image) if a == "IMG" else a for a in args]
    run = cli("motion", str(image), *argv, "-o", str(tmp_path / "o"))
    assert run.returncode == 2, run.stderr
    one_line(run, says)
    assert not (tmp_path / "o").exists()


def test_motion_ensemble_refuses_a_model_that_needs_a_reference(tmp_path: Path,
                                                                image: Path) -> None:
    """The ensemble's learned half must predict from one frame: a model recorded as needing a
    reference is refused up front, naming --model (exit 2, nothing written)."""
    onnx = pytest.importorskip("onnx")
    from tacswitch.motion.infer import model_path

    m = onnx.load(str(model_path("single")))
    for prop in m.metadata_props:
        if prop.key == "tacswitch.use_ref":
            prop.value = "true"
            break
    else:
        m.metadata_props.add(key="tacswitch.use_ref", value="true")
    path = tmp_path / "needs_ref.onnx"
    onnx.save(m, str(path))
    run = cli("motion", str(image), "--method", "ensemble", "--model", str(path), "-o",
              str(tmp_path / "o"))
    assert run.returncode == 2, run.stderr
    one_line(run, "--model: needs_ref.onnx predicts motion since a reference frame")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["slip", "track"])
def test_a_source_that_fails_leaves_an_existing_log_alone(
        tmp_path: Path, image: Path, command: str, capsys: pytest.CaptureFixture[str]) -> None:
    # The log of an earlier run must survive a typo in the next run's source, or a video that
    # does not decode: the log is opened only at its first row.
    log = tmp_path / "log.csv"
    out = ["--log", str(log)] if command == "slip" else ["-o", str(log)]
    assert main([command, str(image.parent), *out, "-q"]) == 0
    kept = log.read_bytes()
    assert kept.count(b"\n") >= 2  # header and rows
    broken = tmp_path / "broken.avi"
    broken.write_bytes(b"not a video" * 50)
    for source in (str(tmp_path / "typo.avi"), str(broken)):
        assert main([command, source, *out, "-q"]) != 0
        assert "error:" in capsys.readouterr().err
        assert log.read_bytes() == kept, source


def test_library_argument_names_become_the_commands_options(
        tmp_path: Path, image: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.cli import _as_option

    assert _as_option("dilate: too large", {"--dilate"}) == "--dilate: too large"
    assert _as_option("rest_frames: must be >= 1", {"--rest-frames"}) == \
        "--rest-frames: must be >= 1"
    assert _as_option("source: no frames", {"--dilate"}) == "source: no frames"
    assert _as_option("no colon here", {"--no"}) == "no colon here"
    # remove_markers(dilate=...) refuses a mask that covers every pixel: the command's option.
    assert main(["remove-markers", str(image), "-o", str(tmp_path / "r"), "--dilate", "1000",
                 "-q"]) == 1
    assert "error: --dilate: " in capsys.readouterr().err
    # Centres that do not fit the image: --centres, not the input, is the cause.
    centres = tmp_path / "c.csv"
    centres.write_text("x,y\n-50,-50\n9999,9999\n")
    assert main(["motion", str(image), "--centres", str(centres), "-o", str(tmp_path / "m"),
                 "-q"]) == 1
    assert "error: --centres: point 0" in capsys.readouterr().err


def test_evaluate_slip_refuses_fewer_than_two_folds(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # --cv 0 used to run the shipped scorer as if --cv were not given.
    for k in ("0", "1", "-2"):
        assert main(["evaluate", "slip", str(tmp_path), "--cv", k]) == 2
        assert "--cv: at least 2 folds" in capsys.readouterr().err
