"""Training the consistent motion model on marker videos (``tacswitch train motion --videos``):
a tiny CPU run end to end, its outputs, resuming, and the options' errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")

from video_files import write_video  # noqa: E402

import tacswitch as ts  # noqa: E402
from tacswitch import sim  # noqa: E402
from tacswitch.motion.real_pairs import pairs_from_videos  # noqa: E402
from tacswitch.motion.train_real import RealTrainConfig, split_videos, train_real  # noqa: E402


@pytest.fixture(scope="module")
def videos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("train_videos")
    for k, kind in enumerate(("hold", "slip", "vibration")):
        seq = sim.grasp_sequence("gelsight_mini", kind, n_frames=8, seed=40 + k)
        write_video(root / f"grasp_{k}.avi", [seq.reference, *seq.frames])
    return root


def test_videos_are_split_whole_and_reproducibly() -> None:
    train, val = split_videos(20, 0.15, seed=3)
    assert len(val) == 3 and sorted(train + val) == list(range(20))
    assert split_videos(20, 0.15, seed=3) == (train, val)
    assert split_videos(1, 0.15, seed=0) == ([0], [])
    assert split_videos(2, 0.9, seed=0)[0]  # at least one video left to train on


def test_a_tiny_run_writes_models_that_predict_and_resumes(videos: Path, tmp_path: Path
                                                         ) -> None:
    pairs = pairs_from_videos([videos], every=2, static=False)
    cfg = RealTrainConfig(steps=4, batch=2, crop=(96, 64), eval_every=2, device="cpu",
                          val_fraction=0.3)
    out = tmp_path / "run"
    last = train_real(pairs, out, cfg, progress=False)
    assert {"pair_e_rmse", "zero_pair_e_rmse", "single_e_rmse"} <= set(last)
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert [e["step"] for e in log] == [2, 4]
    ref, img = pairs.frames[0], pairs.frames[3]
    centres = pairs.rest[0][np.isfinite(pairs.motion[0]).all(1)]
    pair = ts.predict_motion(img, ref, centres, method="model", model=str(out / "model.onnx"))
    same = ts.predict_motion(ref, ref, centres, method="model", model=str(out / "model.onnx"))
    single = ts.predict_motion(img, None, centres, method="model",
                               model=str(out / "single.onnx"))
    assert pair.shape == single.shape == (len(centres), 2)
    assert np.isfinite(pair).all() and np.isfinite(single).all()
    assert np.abs(same).max() == 0.0  # the consistent design: identical frames, no motion
    # Rerunning the finished run resumes at its end: the same weights, no step more.
    before = torch.load(out / "model.pt", weights_only=False)["model"]
    train_real(pairs, out, cfg, progress=False)
    after = torch.load(out / "model.pt", weights_only=False)["model"]
    assert len((out / "log.jsonl").read_text().splitlines()) == 3  # only the final evaluation
    assert before.keys() == after.keys()
    assert all(torch.equal(v, after[k]) for k, v in before.items())
    with pytest.raises(ValueError, match=r"out: .* another configuration"):
        train_real(pairs, out, RealTrainConfig(steps=5, batch=2, device="cpu"), progress=False)


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tacswitch", *args], capture_output=True,
                          text=True)


def test_the_command_trains_on_videos(videos: Path, tmp_path: Path) -> None:
    run = cli("train", "motion", "--videos", str(videos), "--out", str(tmp_path / "r"),
              "--steps", "2", "--batch", "2", "--every", "3", "--device", "cpu")
    assert run.returncode == 0, run.stderr
    assert "validation (held-out videos)" in run.stdout
    assert (tmp_path / "r" / "model.onnx").is_file() and (tmp_path / "r" / "single.onnx").is_file()


@pytest.mark.parametrize(("args", "needle"), [
    (["--videos", "V", "--data", "D"], "--videos: give either"),
    (["--videos", "V", "--every", "0"], "--every: must be >= 1"),
    (["--videos", "V", "--steps", "0"], "--steps: must be >= 1"),
    (["--videos", "V", "--grow-px", "-1"], "--grow-px: must be >= 0"),
])
def test_option_errors_are_one_line(tmp_path: Path, args: list[str], needle: str) -> None:
    run = cli("train", "motion", "--out", str(tmp_path / "r"), *args)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert needle in run.stderr.strip() and run.stderr.strip().count("\n") == 0


def test_a_missing_video_names_the_option(tmp_path: Path) -> None:
    run = cli("train", "motion", "--videos", str(tmp_path / "nope.avi"), "--out",
              str(tmp_path / "r"), "--steps", "1")
    assert run.returncode != 0 and "Traceback" not in run.stderr
    assert "videos:" in run.stderr and "nope.avi" in run.stderr
