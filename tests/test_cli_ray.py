"""``tacswitch remove-markers --ray``: files as Ray tasks on a local Ray instance, outputs byte for
byte those of the single-machine run, resumable per file (needs the ``cluster`` extra)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from tacswitch import sim
from tacswitch.cli import main
from tacswitch.grasp.dataset import read_video

pytestmark = pytest.mark.cluster


def content(path: Path) -> bytes:
    """A file's bytes; for Matroska (``--codec ffv1``), its decoded frames: the container
    holds a random segment ID, so two single-machine runs differ there too."""
    if path.suffix != ".mkv":
        return path.read_bytes()
    frames = [f.tobytes() for f in read_video(path)]
    assert frames, path
    return b"".join(frames)


def digests(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` but the resume record, by relative path."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(content(p)).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.name.startswith(".")}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of 5 marker frames (PNG and JPEG), a short video and a file that is not an
    image."""
    folder = tmp_path_factory.mktemp("inputs")
    g = sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=3)
    for i, f in enumerate(g.frames[:4]):
        cv2.imwrite(str(folder / f"frame_{i}.png"), f)
    cv2.imwrite(str(folder / "frame_j.jpg"), g.frames[4])
    (folder / "broken.png").write_bytes(b"not a png")
    h, w = g.reference.shape[:2]
    writer = cv2.VideoWriter(str(folder / "grasp.avi"), cv2.VideoWriter.fourcc(*"MJPG"), 25,
                             (w, h))
    assert writer.isOpened()
    for f in [g.reference, *g.frames]:
        writer.write(f)
    writer.release()
    return folder


def test_ray_option_errors_are_one_line(tmp_path: Path, inputs: Path, capsys) -> None:
    pytest.importorskip("ray")
    # Nothing listens there: a one-line usage error naming --ray, exit 2, no traceback.
    code = main(["remove-markers", str(inputs / "frame_0.png"), "-o", str(tmp_path / "o"),
                 "--ray", "ray://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 2 and "--ray" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_without_ray_installed_the_error_names_the_extra(tmp_path: Path, inputs: Path,
                                                         monkeypatch, capsys) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    code = main(["remove-markers", str(inputs / "frame_0.png"), "-o", str(tmp_path / "o"),
                 "--ray", "local"])
    err = capsys.readouterr().err
    assert code == 2 and "--ray" in err and "tacswitch[cluster]" in err


def test_local_instance_starts_and_stops(tmp_path: Path, inputs: Path) -> None:
    ray = pytest.importorskip("ray")
    assert not ray.is_initialized()
    out = tmp_path / "o"
    assert main(["remove-markers", str(inputs / "frame_2.png"), "-o", str(out), "-q",
                 "--ray", "local", "--workers", "1"]) == 0
    assert not ray.is_initialized()
    single = tmp_path / "s"
    assert main(["remove-markers", str(inputs / "frame_2.png"), "-o", str(single), "-q"]) == 0
    assert digests(out) == digests(single)
    assert np.array_equal(cv2.imread(str(out / "frame_2.png")),
                          cv2.imread(str(single / "frame_2.png")))


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray instance (2 CPUs) for the module: the command joins it instead of
    starting its own (the same path as ``--ray auto`` on a cluster)."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             object_store_memory=128 * 1024**2)
    yield ray
    ray.shutdown()


@pytest.mark.parametrize("extra", [[], ["--codec", "ffv1"], ["--frames"]])
def test_ray_output_equals_the_single_machine_run(tmp_path: Path, inputs: Path, ray_local,
                                                  extra: list[str]) -> None:
    single, on_ray = tmp_path / "single", tmp_path / "ray"
    # Exit 0: every readable input done; the unreadable one is named in a warning.
    assert main(["remove-markers", str(inputs), "-o", str(single), "-q", *extra]) == 0
    assert main(["remove-markers", str(inputs), "-o", str(on_ray), "-q", "--ray", "auto",
                 *extra]) == 0
    want = digests(single)
    assert len(want) >= 6 and "broken.png" not in want
    assert digests(on_ray) == want
    # The resume record names the same outputs with the same options.
    rec = json.loads((on_ray / ".tacswitch-remove-markers.json").read_text())
    ref = json.loads((single / ".tacswitch-remove-markers.json").read_text())
    assert rec["outputs"] == ref["outputs"]


def test_ray_resumes_per_file(tmp_path: Path, inputs: Path, ray_local, capsys) -> None:
    out = tmp_path / "out"
    assert main(["remove-markers", str(inputs / "frame_0.png"), str(inputs / "grasp.avi"),
                 "-o", str(out), "-q", "--ray", "auto"]) == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if not p.name.startswith(".")}
    capsys.readouterr()
    assert main(["remove-markers", str(inputs), "-o", str(out), "--ray", "auto"]) == 0
    said = capsys.readouterr().out
    assert "2 already done" in said and "4 written" in said
    after = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name in before}
    assert after == before  # what was done was not redone
    # Other options redo every output.
    assert main(["remove-markers", str(inputs / "frame_0.png"), "-o", str(out), "-q",
                 "--ray", "auto", "--radius", "5"]) == 0
    assert (out / "frame_0.png").stat().st_mtime_ns != before["frame_0.png"]


def test_ray_names_unreadable_inputs_by_their_path(tmp_path: Path, inputs: Path, ray_local,
                                                   capsys) -> None:
    assert main(["remove-markers", str(inputs / "broken.png"), str(inputs / "frame_1.png"),
                 "-o", str(tmp_path / "o"), "--ray", "auto"]) == 0
    err = capsys.readouterr().err
    assert repr(str(inputs / "broken.png")) in err
    assert "tacswitch-ray-" not in err  # never the task's temporary copy
