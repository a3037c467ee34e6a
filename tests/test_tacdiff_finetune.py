"""The fine-tune's ground-truth-free validation: held-out frames and gel, the noise test, and
the choice between the starting model and a checkpoint (training parts skip without torch)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tacswitch.cli import main
from tacswitch.tacdiff import finetune as ft
from tacswitch.tacdiff.transplant import shift


def square_grid(pitch: int = 40, radius: int = 6, size: int = 320) -> np.ndarray:
    yy, xx = np.mgrid[:size, :size]
    mask = np.zeros((size, size), bool)
    for cy in range(pitch // 2, size, pitch):
        for cx in range(pitch // 2, size, pitch):
            mask |= (yy - cy) ** 2 + (xx - cx) ** 2 <= radius ** 2
    return mask


def test_split_frames_holds_out_spread_frames():
    tr, va = ft.split_frames(40)
    assert len(va) == 8 and not set(tr) & set(va) and sorted(tr + va) == list(range(40))
    assert va[0] > 0 and va[-1] < 39  # spread over the recording, not its tail
    assert ft.split_frames(10) == ([0, 1, 2, 4, 5, 7, 8, 9], [3, 6])
    assert ft.split_frames(3) == ([0, 1, 2], [0, 1, 2])  # too few: all train, other gel validates
    with pytest.raises(ValueError, match="frames"):
        ft.split_frames(0)
    with pytest.raises(ValueError, match="val_share"):
        ft.split_frames(5, val_share=1.0)
    with pytest.raises(ValueError, match="val_frames"):
        ft.split_frames(5, val_frames=0)


def test_validation_offset_avoids_the_training_gel():
    mask = square_grid()
    d = 20  # half the pitch
    val, overlap = ft.validation_offset(mask, (d, d))
    # The mirrored shift lands on the very gel the training shift uses (a neighbour's spot).
    mirrored = shift(mask, (-d, d), False) & shift(mask, (d, d), False)
    assert mirrored.sum() > 0.8 * shift(mask, (-d, d), False).sum()
    assert val != (-d, d) and overlap == 0.0
    moved = shift(mask, val, False)
    assert (moved & shift(mask, (d, d), False)).sum() == 0 and not (moved & mask).any()
    # A dense grid: half-pitch axis shifts land on the neighbours' footprints, only diagonals
    # move markers, and the overlap with the training gel is reported.
    dense = square_grid(pitch=20, radius=6)
    val, overlap = ft.validation_offset(dense, (10, 10))
    assert val[0] != 0 and val[1] != 0 and overlap > 0.8
    with pytest.raises(ValueError, match="offset"):
        ft.validation_offset(mask, (0, 0))


def test_training_shifts_add_the_opposite_and_horizontal_shifts_that_land_on_gel():
    mask = square_grid()
    d = 20
    assert ft.training_shifts(mask, (d, d), 4) == [(d, d), (-d, -d), (d, 0), (-d, 0)]
    assert ft.training_shifts(mask, (d, d), 2) == [(d, d), (-d, -d)]
    assert ft.training_shifts(mask, (d, d), 1) == [(d, d)]
    # The validation shift is chosen first; the extra shifts keep off its gel.
    val, overlap = ft.validation_offset(mask, (d, d))
    assert val[0] * val[1] == 0 and overlap == 0.0  # an axis shift, on gel between two markers
    trained = ft.training_shifts(mask, (d, d), 4, avoid=val)
    free = [(d, 0), (-d, 0)] if val[0] == 0 else [(0, d), (0, -d)]  # the other axis
    assert trained == [(d, d), (-d, -d), *free]
    assert ft.training_shifts(mask, (d, d), 4, avoid=(0, d)) == [(d, d), (-d, -d), (d, 0),
                                                                  (-d, 0)]
    # A shift on the validation gel is kept out of training: (d, 0) shares (-d, 0)'s gel.
    assert (d, 0) not in ft.training_shifts(mask, (d, d), 4, avoid=(-d, 0))
    # Holes that would crowd the originals (median gap under the separation of crowded holes)
    # are never met at inference: on a dense grid only the diagonals train.
    dense = square_grid(pitch=20, radius=6)
    assert ft.training_shifts(dense, (10, 10), 4) == [(10, 10), (-10, -10)]
    tight = square_grid(pitch=24, radius=7)  # axis shifts leave 5 px of gel; under 4 px: out
    assert ft.training_shifts(tight, (12, 12), 4) == [(12, 12), (-12, -12)]
    # An axis offset has no distinct axis part beyond itself and its opposite.
    assert ft.training_shifts(mask, (0, d), 4) == [(0, d), (0, -d)]
    for bad in (0, -1):
        with pytest.raises(ValueError, match=r"^shifts"):
            ft.training_shifts(mask, (d, d), bad)
    with pytest.raises(ValueError, match=r"^offset"):
        ft.training_shifts(mask, (0, 0), 2)


def test_summary_cautions_on_a_dense_grid_only_when_a_checkpoint_was_chosen():
    kw = {"model": Path("m.onnx"), "start_score": 2.0, "scores": {100: 1.9}, "noise": 0.05,
          "val_frames": [1], "val_markers": 50}
    chosen = ft.FinetuneResult(chosen_step=100, dense=True, **kw)  # type: ignore[arg-type]
    assert "chosen step 100" in chosen.summary() and "caution: a dense" in chosen.summary()
    assert "caution" not in ft.FinetuneResult(chosen_step=100, **kw).summary()  # type: ignore[arg-type]
    kept = ft.FinetuneResult(chosen_step=0, dense=True, **kw)  # type: ignore[arg-type]
    assert "starting model" in kept.summary() and "caution" not in kept.summary()
    assert "dense marker grid" in kept.summary()
    # It names the noise test: per marker with fewer than 3 validation frames.
    assert "per-marker test" in kept.summary()
    three = ft.FinetuneResult(chosen_step=100, **{**kw, "val_frames": [2, 5, 9]})  # type: ignore[arg-type]
    assert "per-frame test over 3 frames" in three.summary()


def test_marker_frames_line_up_with_the_per_marker_scores(marker_frames):
    from tacswitch.sim.scene import render_sample

    frames = [*marker_frames, render_sample("gelsight_mini", 42).image_markers]
    val = ft.validation_set(frames, (0, -16))
    # marker_scores' order: per frame, its labels with scored pixels, ascending.
    per = [int((np.bincount(lab[lm]) > 0).sum()) for lab, lm
           in zip(val.labels, val.pairs["loss_mask"], strict=True)]
    assert min(per) > 0 and np.bincount(val.marker_frames).tolist() == per
    assert val.markers == sum(per)
    with pytest.raises(ValueError, match=r"^offset: expected one"):
        ft.validation_set(frames, [(0, -16), (0, 16)])  # type: ignore[arg-type]


def test_the_check_scores_one_orientation(marker_frames, monkeypatch):
    from tacswitch.tacdiff import infer

    seen = []
    real = infer.inpaint_tacdiff

    def spy(*a, **kw):  # type: ignore[no-untyped-def]
        seen.append(kw.get("orientations"))
        return real(*a, **kw)

    monkeypatch.setattr(infer, "inpaint_tacdiff", spy)
    val = ft.validation_set(marker_frames[:1], (0, -16))
    scores = ft.marker_scores("fast", val)
    assert len(scores) == val.markers and seen and set(seen) == {1}


def test_beats_needs_an_improvement_beyond_noise():
    rng = np.random.default_rng(0)
    start = rng.uniform(1, 3, 400)
    noisy = start + rng.normal(0, 0.5, 400)  # no systematic change
    better = start - 0.1 + rng.normal(0, 0.05, 400)
    assert not ft.beats(start, noisy)[0]
    ok, noise = ft.beats(start, better)
    assert ok and 0 < noise < 0.1
    assert not ft.beats(start, start + 0.1)[0]
    with pytest.raises(ValueError, match="cand"):
        ft.beats(start, start[:3])


def test_t975_matches_scipy():
    from scipy import stats

    for df in (1, 2, 3, 7, 30, 31, 60, 500):
        assert ft.t975(df) == pytest.approx(stats.t.ppf(0.975, df), rel=2e-3)
    with pytest.raises(ValueError, match=r"^df"):
        ft.t975(0)


def test_beats_counts_frames_not_markers_when_groups_are_given():
    rng = np.random.default_rng(1)
    start = rng.uniform(1, 3, 300)
    groups = np.repeat(np.arange(3), 100)
    # One frame much better, two unchanged: many markers agree, but one frame is not evidence.
    cand = start - np.where(groups == 0, 0.3, 0.0) + rng.normal(0, 0.05, 300)
    assert ft.beats(start, cand)[0]  # the per-marker test is fooled
    ok, noise = ft.beats(start, cand, groups=groups)
    assert not ok and noise > 0.1
    # Every frame better: passes either way.
    cand = start - 0.1 - 0.01 * groups + rng.normal(0, 0.05, 300)
    assert ft.beats(start, cand, groups=groups)[0]
    # Fewer than MIN_CLUSTER_FRAMES frames: the per-marker test.
    two = np.repeat(np.arange(2), 150)
    assert ft.beats(start, cand, groups=two) == ft.beats(start, cand)
    with pytest.raises(ValueError, match="groups"):
        ft.beats(start, cand, groups=groups[:10])


def test_finetune_keeps_the_start_model_when_nothing_beats_it(tmp_path: Path,
                                                             marker_frame_dir: Path):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")

    from tacswitch.tacdiff.infer import model_path

    src = marker_frame_dir
    run = tmp_path / "ft"
    # Two steps at a learning rate of zero: the checkpoints equal the start, none beats it.
    args = ["finetune", "--images", str(src), "--out", str(run), "--steps", "2", "--batch", "1",
            "--crop", "64", "--lr", "0", "--val-every", "2", "--init", "fast", "-q"]
    assert main(args) == 0
    assert (run / "model.onnx").read_bytes() == model_path("fast").read_bytes()
    state = json.loads((run / "finetune.json").read_text())
    assert state["chosen"] == 0 and set(state["scores"]) == {"2"}
    assert len(state["start"]) == len(state["per_marker"]["2"]) > 10
    # Validation on the start model's own weights reproduces its score (same inference).
    assert abs(state["scores"]["2"] - np.mean(state["start"])) < 0.05
    # It trained with the fast model's own objective (recorded in its ONNX), not the defaults.
    import torch

    ck = torch.load(run / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert (ck["config"]["loss"], ck["config"]["terminal_fraction"]) == ("v_mse", 0.9)
    assert ft.start_objective(model_path("default")) == ("x0_l1", 0.9)
    for bad in (["--val-every", "0"], ["--val-frames", "0"], ["--steps", "0"]):
        assert main([*args[:4], str(tmp_path / "x"), *args[5:], *bad]) == 2


def _dense_frames(n: int = 2) -> list[np.ndarray]:
    """Frames of a dense grid like a GelSight Mini's: 16 px dark dots every 28 px on smooth gel
    (their masks leave room for one training shift only)."""
    from conftest import disc_mask
    from tacswitch import sim

    out = []
    for i in range(n):
        gel = np.clip(sim.gel_background(192, 256, seed=i), 0, 255).astype(np.uint8)
        cs = [(x, y) for y in np.arange(14.0, 192, 28.0) for x in np.arange(14.0, 256, 28.0)]
        m = disc_mask((192, 256), cs, 8.0)
        img = gel.copy()
        img[m] = (img[m] * 0.25).astype(np.uint8)
        out.append(img)
    return out


def test_a_dense_grid_keeps_the_start_model_without_training(tmp_path: Path, capsys):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.tacdiff.data import removal_markers
    from tacswitch.tacdiff.infer import model_path
    from tacswitch.tacdiff.transplant import default_offset
    from tacswitch.tracking import estimate_pitch

    frames = _dense_frames()
    first = removal_markers(frames[0])
    pitch = estimate_pitch(first.centres)
    assert pitch is not None
    off = default_offset(pitch)
    vo, _ = ft.validation_offset(first.mask, off)
    assert len(ft.training_shifts(first.mask, off, ft.DEFAULT_SHIFTS, avoid=vo)) == 1
    run = tmp_path / "dense"
    res = ft.finetune(frames, run, init="fast", steps=2, batch=1, crop=64, val_every=2,
                      progress=False)
    assert res.skipped and res.dense and res.kept_start and not res.scores
    assert (run / "model.onnx").read_bytes() == model_path("fast").read_bytes()
    assert not (run / "checkpoint.pt").exists()  # nothing trained
    assert "no training ran" in res.summary() and "--trust-dense" in res.summary()
    assert np.isfinite(res.start_score) and res.val_markers > 0
    # Trusted, it trains and validates as on any grid; the summary still cautions.
    res2 = ft.finetune(frames, tmp_path / "trusted", init="fast", steps=2, batch=1, crop=64,
                       val_every=2, progress=False, trust_dense=True)
    assert not res2.skipped and res2.dense and set(res2.scores) == {2}
    assert (tmp_path / "trusted" / "checkpoint.pt").is_file()
    # That trained run is not overwritten by a rerun that does not trust the grid.
    before = (tmp_path / "trusted" / "finetune.json").read_bytes()
    with pytest.raises(ValueError, match=r"^out: .*trust_dense=True"):
        ft.finetune(frames, tmp_path / "trusted", init="fast", steps=2, batch=1, crop=64,
                    val_every=2, progress=False)
    assert (tmp_path / "trusted" / "finetune.json").read_bytes() == before
    with pytest.raises(ValueError, match=r"^trust_dense: "):
        ft.finetune(frames, tmp_path / "bad", init="fast", steps=1, progress=False,
                    trust_dense="yes")  # type: ignore[arg-type]
    # The CLI flag reaches it.
    import cv2

    from tacswitch.cli import main

    src = tmp_path / "frames"
    src.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(src / f"{i}.png"), f)
    assert main(["finetune", "--images", str(src), "--out", str(tmp_path / "cli"), "--init",
                 "fast", "--steps", "2", "--batch", "1", "--crop", "64", "--val-every", "2",
                 "-q"]) == 0
    assert "no training ran" in capsys.readouterr().out
    assert not (tmp_path / "cli" / "checkpoint.pt").exists()


def test_train_callback_sees_the_ema_at_its_steps(tmp_path: Path, marker_frames):
    pytest.importorskip("torch")
    from tacswitch.tacdiff.data import marker_offset_pairs
    from tacswitch.tacdiff.train import TrainConfig, train

    pairs = marker_offset_pairs(marker_frames, offset=(16, 16))
    seen: list[tuple[int, bool]] = []
    cfg = TrainConfig(base=8, mults=(1, 2), steps=5, batch=1, crop=64, warmup=1, threads=1,
                      prior="telea", save_every=100, log_every=100)
    train([pairs], tmp_path / "r", cfg, progress=False,
          callback=lambda step, ema: seen.append((step, ema.training)), callback_every=2)
    assert seen == [(2, False), (4, False), (5, False)]


def test_finetune_trains_at_the_start_models_prior_radius(tmp_path: Path, marker_frames):
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.tacdiff.infer import TacDiffModel
    from tacswitch.tacdiff.model import DenoiserUNet, UNetConfig
    from tacswitch.tacdiff.train import save_weights

    arch = UNetConfig(base=8, mults=(1, 2), prior_radius=7)
    start = save_weights(DenoiserUNet(arch), tmp_path / "start.safetensors", arch.to_dict())
    res = ft.finetune(marker_frames, tmp_path / "ft", init=start, steps=1, batch=1, crop=64,
                      lr=0.0, val_every=1, threads=1, progress=False)
    ck = torch.load(tmp_path / "ft" / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert ck["config"]["prior_radius"] == 7.0  # the sampler's fills and the EMA's record
    extra = ck["config"]["extra"]
    shifts = extra.get("offsets", [extra["offset"]])  # recorded when several train
    assert shifts[0] == extra["offset"] and list(res.val_offset) not in shifts
    assert [list(o) for o in res.train_offsets] == shifts
    assert TacDiffModel(tmp_path / "ft" / "start.onnx").prior_radius == 7.0
    assert TacDiffModel(res.model).prior_radius == 7.0
    # A start exported without a recorded objective trains with the defaults; an explicit one
    # overrides it, and a bad one is refused by name.
    assert (ck["config"]["loss"], ck["config"]["terminal_fraction"]) == ("v_mse", 0.2)
    assert res.recompress.startswith("none (no JPEG source recognised")  # PNG frames
    res = ft.finetune(marker_frames, tmp_path / "ft2", init=start, steps=1, batch=1, crop=64,
                      lr=0.0, val_every=1, threads=1, progress=False, loss="x0_l1",
                      terminal_fraction=0.5, recompress="jpeg:80")
    ck = torch.load(tmp_path / "ft2" / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert (ck["config"]["loss"], ck["config"]["terminal_fraction"]) == ("x0_l1", 0.5)
    assert res.recompress == ck["config"]["extra"]["recompress"] == "jpeg:80"
    assert "re-compressed: jpeg:80" in res.summary()
    with pytest.raises(ValueError, match=r"^recompress: expected"):
        ft.finetune(marker_frames, tmp_path / "ft5", init=start, steps=1, progress=False,
                    recompress="jpeg:101")
    with pytest.raises(ValueError, match=r"^terminal_fraction: must be in"):
        ft.finetune(marker_frames, tmp_path / "ft3", init=start, steps=1, progress=False,
                    terminal_fraction=1.5)
    with pytest.raises(ValueError, match=r"^loss: expected one of"):
        ft.finetune(marker_frames, tmp_path / "ft4", init=start, steps=1, progress=False,
                    loss="l2")
    bads: list[Any] = [0, 1.5, True]
    for bad in bads:
        with pytest.raises(ValueError, match=r"^shifts: expected"):
            ft.finetune(marker_frames, tmp_path / "ft6", init=start, steps=1, progress=False,
                        shifts=bad)


def test_shipped_weights_record_their_models_prior_radius():
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.tacdiff.infer import load_model
    from tacswitch.tacdiff.train import load_network

    # What `tacswitch finetune` starts from must train at the radius the shipped model runs at.
    for name in ("default", "fast"):
        arch = load_network(ft.init_weights(name)).cfg
        assert arch.prior_radius == load_model(name).prior_radius
