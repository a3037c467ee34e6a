"""``tacswitch evaluate slip`` and ``tacswitch train slip`` on a small labelled folder of rendered
grasp videos (simulated GelSight Mini; the layout of a user's own recordings)."""

from __future__ import annotations

import contextlib
import csv
import io
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from tacswitch import sim
from tacswitch.cli import main


@pytest.fixture(scope="module")
def labelled(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("grasps")
    rows = []
    for k, (obj, kind) in enumerate([("cup", "slip"), ("cup", "hold"), ("box", "slip"),
                                     ("box", "hold"), ("pen", "hold"), ("pen", "slip")]):
        seq = sim.grasp_sequence("gelsight_mini", kind, n_frames=16, seed=k)
        folder = root / obj / f"exp_{k}"
        folder.mkdir(parents=True)
        frames = [seq.reference] * 3 + list(seq.frames)
        h, w = frames[0].shape[:2]
        vw = cv2.VideoWriter(str(folder / "camera_0.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25,
                             (w, h))
        for f in frames:
            vw.write(f)
        vw.release()
        rows.append([obj, f"exp_{k}", int(kind == "slip")])
    with open(root / "labels.csv", "w", newline="") as fh:
        csv.writer(fh).writerows([["object", "experiment", "slip"], *rows])
    return root


def run(*args: str) -> tuple[int, str]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(list(args))
    return code, buf.getvalue()


def test_evaluate_slip_scores_every_experiment(labelled: Path, tmp_path: Path) -> None:
    out = tmp_path / "res.json"
    code, text = run("evaluate", "slip", str(labelled), "--json", str(out), "-q",
                     "--cache", str(tmp_path / "cache"))
    assert code == 0
    assert "| markers: learned (shipped marker scorer) |" in text
    res = json.loads(out.read_text())
    assert len(res["experiments"]) == 6
    s = res["scores"]
    assert s["n"] == 6 and s["n_slip"] == 3 and s["tp"] + s["fn"] == 3 and s["tn"] + s["fp"] == 3
    for e in res["experiments"]:
        assert e["called"] == any(f is not None for f in e["first_flag"])
    # The paper rule on the same (cached) tracks: every rendered slip moves past its threshold.
    code, text = run("evaluate", "slip", str(labelled), "--rule", "paper", "-q",
                     "--cache", str(tmp_path / "cache"))
    assert code == 0 and "| markers: paper rule |" in text
    assert (tmp_path / "cache").is_dir() and len(list((tmp_path / "cache").iterdir())) == 6


def test_evaluate_slip_markerless_scores_with_the_markerless_scorer(
        labelled: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Predicted motion is scored by the shipped markerless scorer, as `tacswitch slip
    --markerless` scores it; tracked markers by the marker scorer; --model overrides both."""
    from tacswitch.grasp import crossval

    used: list[object] = []
    real = crossval.clip_flags

    def spy(clip, **options):  # type: ignore[no-untyped-def]
        used.append(options.get("model"))
        return real(clip, **options)

    monkeypatch.setattr(crossval, "clip_flags", spy)
    cache = str(tmp_path / "cache")
    code, text = run("evaluate", "slip", str(labelled), "--markerless", "-q", "--cache", cache)
    assert code == 0 and "| markerless: learned (shipped markerless scorer) |" in text
    assert used and set(used) == {"markerless"}
    used.clear()
    code, _ = run("evaluate", "slip", str(labelled), "-q", "--cache", cache)
    assert code == 0 and set(used) == {"markers"}
    used.clear()
    from tacswitch.grasp.detector import slip_model_path

    mine = str(slip_model_path("markers"))
    capsys.readouterr()
    code, text = run("evaluate", "slip", str(labelled), "--markerless", "-q", "--cache", cache,
                     "--model", mine)
    assert code == 0 and set(used) == {mine} and f"learned ({mine})" in text
    # The shipped files say what they learned from; the marker scorer on predicted motion warns.
    assert "--model: learned from tracked markers, and this run predicts" in capsys.readouterr().err
    from tacswitch.grasp.detector import load_scorer

    assert (load_scorer("markers").motion, load_scorer("markerless").motion) == (
        "markers", "markerless")


def test_train_slip_writes_a_model_the_slip_loop_uses(labelled: Path, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    pytest.importorskip("torch")
    model = tmp_path / "mine.onnx"
    code, _ = run("train", "slip", str(labelled), "--out", str(model), "--epochs", "3", "-q",
                  "--cache", str(tmp_path / "cache"), "--simulated", "1")
    assert code == 0 and model.is_file()
    assert "6 experiments, 3 slip; 6 rendered" in _trained_on(model)
    copied = tmp_path / "copied.onnx"
    code, _ = run("train", "slip", str(labelled), "--out", str(copied), "--epochs", "1", "-q",
                  "--cache", str(tmp_path / "cache"), "--simulated", "0", "--seeds", "1",
                  "--augment", "2")
    assert code == 0 and "6 experiments, 2 rescaled copies of each" in _trained_on(copied)
    tail = tmp_path / "tail.onnx"
    code, _ = run("train", "slip", str(labelled), "--out", str(tail), "--epochs", "1", "-q",
                  "--cache", str(tmp_path / "cache"), "--simulated", "0", "--seeds", "1",
                  "--slip-tail", "0.5")
    assert code == 0 and _meta(tail, "slip_tail") == 0.5
    from tacswitch.grasp.detector import load_scorer
    from tacswitch.grasp.train import COMMITTEE, VOTES, recipe_slip_tail

    assert _meta(copied, "slip_tail") == recipe_slip_tail() == 0.5
    scorer = load_scorer(model)
    assert (scorer.committee, scorer.votes) == (COMMITTEE, VOTES)
    assert scorer.motion == "markers"
    video = next(labelled.rglob("*.avi"))
    log = tmp_path / "log.csv"
    code, _ = run("slip", str(video), "--log", str(log), "--slip-model", str(model), "-q")
    assert code == 0
    with open(log) as fh:
        assert len(list(csv.DictReader(fh))) == 19
    capsys.readouterr()
    assert main(["slip", str(video), "--log", str(log), "--slip-model", str(model), "-q",
                 "--votes", str(COMMITTEE + 1)]) != 0
    assert f"--votes: must be >= 1, at most the committee's {COMMITTEE}" in capsys.readouterr().err
    # A marker scorer fed predicted motion: said once, before any frame.
    assert main(["slip", str(video), "--log", str(log), "--slip-model", str(model), "-q",
                 "--markerless", "--max-frames", "4"]) == 0
    err = capsys.readouterr().err
    assert err.count("--slip-model: learned from tracked markers, and this run predicts") == 1
    assert main(["slip", str(video), "--log", str(log), "--slip-model", str(model), "-q",
                 "--max-frames", "4"]) == 0
    assert "learned from" not in capsys.readouterr().err


def test_errors_name_the_argument(labelled: Path, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evaluate", "slip", str(tmp_path / "nowhere"), "-q"]) != 0
    assert "data: not a folder" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("object,experiment,slip\ncup,exp_0,maybe\n")
    assert main(["evaluate", "slip", str(labelled), "--labels", str(bad), "-q"]) != 0
    assert "--labels: line 2: slip must be 0 or 1" in capsys.readouterr().err
    binary = tmp_path / "binary.csv"
    binary.write_bytes(bytes(range(256)))
    assert main(["evaluate", "slip", str(labelled), "--labels", str(binary), "-q"]) != 0
    assert "--labels: " in capsys.readouterr().err.strip().splitlines()[-1]
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    assert main(["evaluate", "slip", str(labelled), "--cache", str(blocker / "sub"), "-q"]) == 2
    assert "--cache: " in capsys.readouterr().err.strip().splitlines()[-1]
    cols = tmp_path / "cols.csv"
    cols.write_text("object,slip\ncup,1\n")
    assert main(["evaluate", "slip", str(labelled), "--labels", str(cols), "-q"]) != 0
    assert "lacks column(s) ['experiment']" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--rigid-threshold-px", "2", "-q"]) != 0
    assert "--rigid-threshold-px: applies to --rule paper only" in capsys.readouterr().err
    # A value that is not pixels > 0 is refused by the parser (exit 2), before any tracking.
    for value in ("-2", "0", "nan", "inf", "two"):
        with pytest.raises(SystemExit) as exc:
            main(["evaluate", "slip", str(labelled), "--rule", "paper", "--rigid-threshold-px",
                  value, "-q"])
        assert exc.value.code == 2
        assert "--rigid-threshold-px" in capsys.readouterr().err
    # Options --cv would ignore (it trains its own scorers) are refused, not dropped.
    for extra, name in ((["--rule", "paper"], "--rule paper"), (["--model", "m.onnx"], "--model"),
                        (["--score-threshold", "1"], "--score-threshold")):
        assert main(["evaluate", "slip", str(labelled), "--cv", "3", "-q", *extra]) != 0
        assert f"{name}: does not apply with --cv" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--rule", "paper", "--score-threshold", "1",
                 "-q"]) != 0
    assert "--score-threshold: applies to --rule learned only" in capsys.readouterr().err
    pytest.importorskip("torch")
    assert main(["train", "slip", str(labelled), "--out", str(tmp_path / "m.onnx"),
                 "--simulated", "-1", "-q"]) != 0
    assert "--simulated: must be in [0, 1000]" in capsys.readouterr().err
    assert main(["train", "slip", str(labelled), "--out", str(tmp_path / "m.onnx"),
                 "--seeds", "0", "-q"]) != 0
    assert "--seeds: must be in [1, 100]" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--seeds", "2", "-q"]) != 0
    assert "--seeds: applies to --cv (training) only" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--votes", "2", "-q"]) != 0
    assert "--votes: applies to --cv (training) only" in capsys.readouterr().err
    assert main(["train", "slip", str(labelled), "--out", str(tmp_path / "m.onnx"),
                 "--seeds", "2", "--votes", "3", "-q"]) != 0
    assert "--votes: must be in [1, --seeds=2]; got 3" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--markerless", "--no-marker-tracks",
                 "-q"]) != 0
    assert "--no-marker-tracks: applies to --cv with --markerless only" in capsys.readouterr().err
    assert main(["train", "slip", str(labelled), "--out", str(tmp_path / "m.onnx"),
                 "--no-marker-tracks", "-q"]) != 0
    assert "--no-marker-tracks: applies to --markerless only" in capsys.readouterr().err
    assert main(["train", "slip", str(labelled), "--out", str(tmp_path / "m.onnx"),
                 "--augment", "-1", "-q"]) != 0
    assert "--augment: must be in [0, 20]; got -1" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--augment", "1", "-q"]) != 0
    assert "--augment: applies to --cv (training) only" in capsys.readouterr().err
    for bad in ("0", "1.5", "nan"):
        assert main(["train", "slip", str(labelled), "--out", str(tmp_path / "m.onnx"),
                     "--slip-tail", bad, "-q"]) != 0
        assert f"--slip-tail: must be in (0, 1]; got {float(bad)}" in capsys.readouterr().err
    assert main(["evaluate", "slip", str(labelled), "--slip-tail", "0.5", "-q"]) != 0
    assert "--slip-tail: applies to --cv (training) only" in capsys.readouterr().err


def _meta(model: Path, key: str) -> object:
    import json

    import onnxruntime as ort

    meta = ort.InferenceSession(str(model), providers=["CPUExecutionProvider"]).get_modelmeta()
    return json.loads(meta.custom_metadata_map[f"tacswitch.{key}"])


def _trained_on(model: Path) -> str:
    import onnxruntime as ort

    meta = ort.InferenceSession(str(model), providers=["CPUExecutionProvider"]).get_modelmeta()
    return meta.custom_metadata_map["tacswitch.trained_on"]


def test_train_slip_markerless_also_learns_from_the_marker_tracks(labelled: Path,
                                                                   tmp_path: Path) -> None:
    """A markerless scorer trains on the markerless tracks and, by default, on the same
    videos' marker tracks (both tracked and cached); ``--no-marker-tracks`` leaves them out."""
    pytest.importorskip("torch")
    cache = tmp_path / "cache"
    model = tmp_path / "markerless.onnx"
    code, text = run("train", "slip", str(labelled), "--markerless", "--out", str(model),
                     "--epochs", "1", "--cache", str(cache))
    assert code == 0 and model.is_file()
    assert "6 experiments (markerless and marker tracks)" in text
    assert "(markerless and marker tracks)" in _trained_on(model)
    from tacswitch.grasp.detector import load_scorer
    from tacswitch.grasp.train import MARKERLESS_COMMITTEE, default_votes

    # The markerless recipe's own committee size (MARKERLESS_COMMITTEE), with the same vote
    # rule.
    scorer = load_scorer(model)
    assert (scorer.committee, scorer.votes) == (MARKERLESS_COMMITTEE,
                                                default_votes(MARKERLESS_COMMITTEE))
    # It records the frame-to-frame weight its markerless tracks were made with.
    from tacswitch.grasp.detector import SCORER_FRAME_TO_FRAME

    assert scorer.frame_to_frame == SCORER_FRAME_TO_FRAME
    names = sorted(p.name for p in cache.iterdir())
    from tacswitch.grasp.dataset import MARKER_TRACKS_TAG, MARKERLESS_TRACKS_TAG

    assert sum(MARKERLESS_TRACKS_TAG in n for n in names) == 6
    assert sum(MARKER_TRACKS_TAG in n for n in names) == 6
    alone = tmp_path / "alone.onnx"
    code, text = run("train", "slip", str(labelled), "--markerless", "--no-marker-tracks",
                     "--out", str(alone), "--epochs", "1", "--cache", str(cache))
    assert code == 0 and "marker tracks" not in _trained_on(alone)


def test_evaluate_slip_cv_trains_a_voting_committee_per_fold(labelled: Path, tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch
                                                              ) -> None:
    """``--cv K``: every fold trains a committee of ``--seeds`` scorers that flags with
    ``--votes`` of them, on the other folds' objects only."""
    pytest.importorskip("torch")
    from tacswitch.grasp import train

    seen: list[tuple[int, int | None, int]] = []
    real = train.train_committee

    def spy(features, labels, **kw):  # type: ignore[no-untyped-def]
        seen.append((kw["seeds"], kw["votes"], len(labels)))
        return real(features, labels, **{**kw, "epochs": 2})

    monkeypatch.setattr(train, "train_committee", spy)
    out = tmp_path / "cv.json"
    code, text = run("evaluate", "slip", str(labelled), "--cv", "3", "--seeds", "2", "--votes",
                     "1", "-q", "--cache", str(tmp_path / "cache"), "--json", str(out))
    assert code == 0 and "| markers: learned, 3 folds grouped by object |" in text
    # 3 objects of 2 experiments: each fold trains on the 4 experiments of the other two.
    assert seen == [(2, 1, 4)] * 3
    assert len(json.loads(out.read_text())["experiments"]) == 6
    seen.clear()
    # --augment 1: and on their rescaled copies, never on copies of the held-out object's.
    code, _ = run("evaluate", "slip", str(labelled), "--cv", "3", "--seeds", "1", "--augment",
                  "1", "-q", "--cache", str(tmp_path / "cache"))
    assert code == 0 and seen == [(1, None, 8)] * 3


def test_a_replaced_video_is_tracked_again_not_read_from_the_cache(labelled: Path,
                                                                    tmp_path: Path) -> None:
    import shutil

    import numpy as np

    from tacswitch.grasp.dataset import cached_clip

    video = tmp_path / "obj" / "exp" / "camera_0.avi"
    video.parent.mkdir(parents=True)
    shutil.copy(labelled / "cup" / "exp_0" / "camera_0.avi", video)
    cache = tmp_path / "cache"
    first = cached_clip(video, cache)
    again = cached_clip(video, cache)
    np.testing.assert_array_equal(first.motion, again.motion)
    shutil.copy(labelled / "box" / "exp_3" / "camera_0.avi", video)  # another grasp, same name
    replaced = cached_clip(video, cache)
    fresh = cached_clip(video, None)
    np.testing.assert_array_equal(replaced.motion, fresh.motion)
    assert not np.array_equal(replaced.motion, first.motion)


def test_a_copied_dataset_keeps_its_cache_and_edited_bytes_do_not(
        labelled: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import os
    import shutil

    import numpy as np

    from tacswitch.grasp import dataset

    video = tmp_path / "obj" / "exp" / "camera_0.avi"
    video.parent.mkdir(parents=True)
    shutil.copy(labelled / "cup" / "exp_0" / "camera_0.avi", video)
    cache = tmp_path / "cache"
    first = dataset.cached_clip(video, cache)
    st = video.stat()
    os.utime(video, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # copied: a new mtime

    def no_tracking(*args: object, **kw: object) -> None:
        raise AssertionError("tracked again")

    monkeypatch.setattr(dataset, "track_clip", no_tracking)
    np.testing.assert_array_equal(dataset.cached_clip(video, cache).motion, first.motion)
    # The same size, one byte changed, a new mtime: not the file the cache was made from.
    (entry,) = cache.glob("*.npz")
    data = bytearray(video.read_bytes())
    data[len(data) // 2] ^= 0xFF
    video.write_bytes(bytes(data))
    assert video.stat().st_size == st.st_size
    assert not dataset._cache_matches(entry, video)


def test_labels_with_spaces_and_repeated_experiments(labelled: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.grasp.dataset import read_labels

    spaced = tmp_path / "spaced.csv"
    spaced.write_text("object, experiment, slip\ncup, exp_0, 1\nbox,exp_3,0\n")
    exps = read_labels(labelled, spaced)
    assert [(e.object, e.name, e.slip) for e in exps] == [("cup", "exp_0", True),
                                                          ("box", "exp_3", False)]
    twice = tmp_path / "twice.csv"
    twice.write_text("object,experiment,slip\ncup,exp_0,1\ncup,exp_0,0\n")
    with pytest.raises(ValueError, match=r"^labels: line 3: cup/exp_0 is listed again"):
        read_labels(labelled, twice)
    # Only slips: the balanced accuracy is undefined, written as null, not NaN.
    slips = tmp_path / "slips.csv"
    slips.write_text("object,experiment,slip\ncup,exp_0,1\nbox,exp_2,1\n")
    out = tmp_path / "s.json"
    code, _ = run("evaluate", "slip", str(labelled), "--labels", str(slips), "--json",
                  str(out), "-q", "--cache", str(tmp_path / "c"))
    assert code == 0
    data = json.loads(out.read_text())  # strict JSON would refuse NaN
    assert data["scores"]["balanced_accuracy"] is None


def test_train_slip_help_states_the_rendered_grasps_it_adds(
        capsys: pytest.CaptureFixture[str]) -> None:
    from tacswitch.grasp.simulated import SIMULATED_PER_KIND

    with pytest.raises(SystemExit):
        main(["train", "slip", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"(default: {SIMULATED_PER_KIND}, as the shipped scorer" in text


def test_unusable_videos_are_left_out_and_named(labelled: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    # A copy of the labelled grasps where one held grasp's video is blank (no markers: it would
    # count as a grasp left alone) and another experiment gains an empty file beside its video.
    import shutil

    data = tmp_path / "data"
    shutil.copytree(labelled, data)
    blank = data / "cup" / "exp_1" / "camera_0.avi"
    vw = cv2.VideoWriter(str(blank), cv2.VideoWriter_fourcc(*"MJPG"), 25, (160, 120))
    for _ in range(12):
        vw.write(np.full((120, 160, 3), 128, np.uint8))
    vw.release()
    (data / "box" / "exp_2" / "camera_2.avi").write_bytes(b"")
    out = tmp_path / "res.json"
    code, _ = run("evaluate", "slip", str(data), "--json", str(out), "-q",
                  "--cache", str(tmp_path / "cache"))
    assert code == 0
    err = capsys.readouterr().err
    assert "2 video(s) left out" in err and str(blank) in err and "camera_2.avi" in err
    assert "1 experiment(s) with no usable video are not scored" in err
    res = json.loads(out.read_text())
    assert res["scores"]["n"] == 5 and res["scores"]["n_slip"] == 3
    assert "exp_1" not in {e["experiment"] for e in res["experiments"]}


def test_tracking_processes_never_outnumber_videos_or_cores(
        labelled: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # --workers 1000 used to start a thousand processes for a handful of videos (a hang).
    import multiprocessing
    import os

    from tacswitch.grasp import dataset

    sizes: list[int] = []
    real = multiprocessing.get_context

    class Context:
        def Pool(self, n: int) -> Any:  # multiprocessing's name
            sizes.append(n)
            return real("spawn").Pool(n)

    monkeypatch.setattr(multiprocessing, "get_context",
                        lambda kind=None: Context() if kind == "spawn" else real(kind))
    exps = dataset.read_labels(labelled)
    one = dataset.experiment_clips(exps[:1], workers=1000)  # one video: no pool at all
    assert sizes == [] and len(one[0]) == 1
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    two = dataset.experiment_clips(exps[:3], workers=1000)
    assert sizes == [2] and [len(c) for c in two] == [1, 1, 1]


def test_labels_of_one_class_say_why_the_balanced_accuracy_is_nan(
        labelled: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    only = tmp_path / "slips.csv"
    with open(only, "w", newline="") as fh:
        csv.writer(fh).writerows([["object", "experiment", "slip"], ["cup", "exp_0", 1],
                                  ["box", "exp_2", 1]])
    assert main(["evaluate", "slip", str(labelled), "--labels", str(only), "-q",
                 "--cache", str(tmp_path / "cache")]) == 0
    err = capsys.readouterr().err
    assert "--labels: every experiment is labelled slip (1)" in err, err
