"""The downstream perception study: data, splits, statistics, and the CLI end to end."""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from tacswitch.cli import main
from tacswitch.downstream import data as ddata
from tacswitch.downstream import study


def test_split_is_stratified_disjoint_and_seeded():
    labels = np.repeat(np.arange(7), 6)
    train, test = study.split(labels, "texture", 0)
    assert not set(train) & set(test) and len(train) + len(test) == len(labels)
    assert all((labels[train] == c).sum() == 3 for c in range(7))
    again = study.split(labels, "texture", 0)
    assert np.array_equal(train, again[0])
    assert not np.array_equal(train, study.split(labels, "texture", 1)[0])
    tr, te = study.split(np.zeros(40, np.int64), "contact", 3)
    assert len(tr) == 34 and len(te) == 6


def test_downsample_matches_opencv_area_resize():
    rng = np.random.default_rng(0)
    imgs = rng.integers(0, 256, (2, 24, 32, 3), dtype=np.uint8)
    contact = np.zeros((2, 24, 32), bool)
    contact[:, 4:13, 6:20] = True
    small, mask = study.downsample(imgs, contact, 2)
    for i in range(2):
        ref = cv2.resize(imgs[i], (16, 12), interpolation=cv2.INTER_AREA)
        assert np.abs(small[i].astype(int) - ref).max() <= 1  # ties round differently
    # Majority vote: 2x2 blocks at least half inside the contact.
    assert mask[0, 2:6, 3:10].all() and not mask[0, :2].any() and mask[0, 6].any()


def test_crop_at_stays_inside_the_frame():
    img = np.arange(20 * 30 * 3, dtype=np.uint8).reshape(20, 30, 3)
    for cy, cx in ((0, 0), (19, 29), (10, 15), (-5, 100)):
        assert study.crop_at(img, cy, cx, 8).shape == (8, 8, 3)
    centres = study.contact_centres(np.pad(np.ones((1, 4, 4), bool), ((0, 0), (2, 14), (6, 20))))
    assert centres.tolist() == [[3, 7]] or centres.tolist() == [[4, 8]]


def _records(deltas: list[float], base: float = 0.8) -> list[dict]:
    ctx: dict = {}
    recs = []
    for s, d in enumerate(deltas):
        b = base + 0.01 * s
        recs.append({"task": "texture", "input": "none", "seed": s, "context": ctx,
                     "metrics": {"accuracy": b, "classes_with_errors": 2.0}})
        recs.append({"task": "texture", "input": "telea", "seed": s, "context": ctx,
                     "metrics": {"accuracy": b + d, "classes_with_errors": 1.0}})
    return recs


def test_verdict_tells_a_paired_difference_from_noise():
    better = {r["input"]: r for r in study.summarise(_records([0.05, 0.06, 0.05]))}
    assert better["telea"]["delta"] == pytest.approx(0.0533, abs=1e-3)
    assert study.verdict(better["telea"]) == "better"
    assert study.verdict(better["none"]) == "baseline"
    noisy = {r["input"]: r for r in study.summarise(_records([0.05, -0.06, 0.02]))}
    assert study.verdict(noisy["telea"]) == "within noise"
    worse = {r["input"]: r for r in study.summarise(_records([-0.04, -0.05, -0.045]))}
    assert study.verdict(worse["telea"]) == "worse"
    two = {r["input"]: r for r in study.summarise(_records([0.05, 0.06]))}
    assert study.verdict(two["telea"]) == "too few seeds"
    assert "TELEA" in study.markdown(study.summarise(_records([0.05, 0.06, 0.05])))


SMALL = ["--quick", "--per-class", "2", "--contact-samples", "6", "--seeds", "2",
         "--inputs", "none,telea", "--threads", "1", "-q"]


@pytest.fixture(scope="module")
def study_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("torch")
    pytest.importorskip("torchvision")
    root = tmp_path_factory.mktemp("downstream")
    assert main(["evaluate", "downstream", "--data", str(root / "data"), *SMALL]) == 0
    return root


def test_cli_end_to_end_writes_every_run_and_a_report(study_run: Path):
    out = study_run / "data"  # the report lies next to the frames
    lines = (out / "results.jsonl").read_text().splitlines()
    assert len(lines) == 2 * 2 * 2  # tasks x seeds x inputs
    recs = [json.loads(x) for x in lines]
    for r in recs:
        for v in r["metrics"].values():
            assert np.isfinite(v) and 0 <= v <= 7
    report = (out / "report.md").read_text()
    assert "Texture classification" in report and "Contact segmentation" in report
    data = ddata.load_dataset(study_run / "data", "texture")
    assert {f"img_{i}" for i in ddata.INPUTS} <= set(data)
    # Every input is the same scene: identical outside the markers' neighbourhood.
    assert data["img_none"].shape == data["img_truth"].shape == (14, 240, 320, 3)
    same = (data["img_telea"] == data["img_none"]).all(axis=-1).mean()
    assert 0.6 < same < 1.0
    assert not np.array_equal(data["img_telea"], data["img_none"])


def test_cli_resumes_and_redoes_only_runs_whose_frames_changed(study_run: Path):
    data_dir = study_run / "data"
    results = data_dir / "results.jsonl"
    before = results.read_text()
    assert main(["evaluate", "downstream", "--data", str(data_dir), *SMALL]) == 0
    assert results.read_text() == before  # nothing redone
    shard = data_dir / "contact_000.npz"
    arrays = dict(np.load(shard))
    arrays["img_telea"] = arrays["img_telea"] // 2 + 1
    np.savez(shard, **arrays)
    assert main(["evaluate", "downstream", "--data", str(data_dir), *SMALL]) == 0
    new = results.read_text().splitlines()[len(before.splitlines()):]
    assert sorted((json.loads(x)["task"], json.loads(x)["input"]) for x in new) == \
        [("contact", "telea"), ("contact", "telea")]


def test_cli_refuses_a_folder_built_with_other_settings(study_run: Path, capsys):
    code = main(["evaluate", "downstream", "--data", str(study_run / "data"), *SMALL,
                 "--preset", "digit"])
    assert code == 1
    assert "data:" in capsys.readouterr().err


@pytest.mark.parametrize("torch_installed", [True, False])
def test_cli_rejects_bad_arguments(tmp_path: Path, capsys, monkeypatch, torch_installed: bool):
    # The options are checked before torch is looked for: without torch a mistake is still
    # named, with exit code 2 (issue 32, item 8).
    if torch_installed:
        pytest.importorskip("torch")
    else:
        monkeypatch.setitem(sys.modules, "torch", None)  # as without the train extra
        monkeypatch.setitem(sys.modules, "torchvision", None)
    (tmp_path / "file").write_text("x")
    for extra, needle in ((["--tasks", "texture,colour"], "--tasks"),
                          (["--inputs", "telea,magic"], "--inputs"),
                          (["--seeds", "1"], "--seeds"),
                          (["--epochs", "0"], "--epochs"),
                          (["--threads", "0"], "--threads"),
                          (["--model", str(tmp_path / "none.onnx")], "--model"),
                          (["--preset", "nope"], "preset")):
        assert main(["evaluate", "downstream", "--data", str(tmp_path / "d"), "--quick",
                     *extra]) == 2  # usage errors
        err = capsys.readouterr().err
        assert needle in err and "torch" not in err, err
    assert main(["evaluate", "downstream", "--data", str(tmp_path / "file")]) == 2
    assert "--data" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()  # refused before any work


def test_cli_without_torch_says_so_once_the_options_pass(tmp_path: Path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)
    assert main(["evaluate", "downstream", "--data", str(tmp_path / "d"), "--quick"]) == 1
    err = capsys.readouterr().err
    assert "needs torch" in err and "Traceback" not in err
    assert not (tmp_path / "d").exists()


def test_default_scale_is_the_documented_one():
    from tacswitch.inpaint import DEFAULT_DILATE

    s = ddata.StudyScale()
    assert (s.preset, s.seeds) == ("gelsight_mini", 3)
    assert s.dilate == DEFAULT_DILATE  # the frames are what remove_markers gives a user
    assert dataclasses.replace(s, seeds=5).data_key() == s.data_key()
