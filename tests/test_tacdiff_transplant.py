"""Fine-tune inputs that look like inference (transplanted real markers), realistic training
pairs, and continuing training from a shipped ONNX model."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tacswitch as ts
from tacswitch.cli import main
from tacswitch.tacdiff import data as tdata
from tacswitch.tacdiff import transplant as tp


def test_default_offset_is_half_pitch_on_codec_blocks():
    assert tp.default_offset(28.5) == (16, 16)
    assert tp.default_offset(83.0) == (40, 40)
    assert tp.default_offset(5.0) == (8, 8)
    with pytest.raises(ValueError, match="pitch"):
        tp.default_offset(float("nan"))


def test_shift_moves_and_drops():
    a = np.arange(12).reshape(3, 4)
    np.testing.assert_array_equal(tp.shift(a, (1, -1), -1),
                                  [[-1, 4, 5, 6], [-1, 8, 9, 10], [-1, -1, -1, -1]])
    assert (tp.shift(a, (9, 0), 0) == 0).all()


def test_transplanted_markers_carry_the_real_appearance(marker_frames):
    from tacswitch.sim import capture

    # Blur and JPEG darken a rim beyond the removal mask, as on real recordings.
    frame = capture.apply(marker_frames[0], capture.CaptureProfile(
        blur_sigma=1.5, codec="mjpeg", quality=60), 0)
    # A fixed two-dilation mask leaves part of that rim outside: the ring must move along.
    found = tdata.removal_markers(frame, dilate=2)
    offset = (16, 16)
    cond, moved, real, n = tp.transplant(frame, found.mask, offset, ring=3)
    app = tp.measure_appearance(frame, found.mask, ring=3)
    assert n > 0.4 * len(found) and moved.any()
    # The moved markers are where the originals went, and carry their darkening: the ring
    # beyond the mask is darkened as the original's ring is.
    assert (moved <= tp.shift(found.mask, offset, False)).all()
    moved_fp = ts.dilate_mask(moved, 3) & tp.shift(app.footprint, offset, False)
    want = np.clip(np.rint(app.fill.astype(np.float32) * tp.shift(app.ratio, offset, 1.0)),
                   0, 255)
    np.testing.assert_array_equal(cond[moved_fp], want[moved_fp].astype(np.uint8))
    assert cond[moved].mean() < frame[moved].mean() - 30  # dark dots landed there
    ring = moved_fp & ~moved & ~app.footprint
    orig_ring = app.footprint & ~found.mask
    # Their rim outside the mask is darkened by what the originals' rims show.
    got = (cond[ring].astype(float) - frame[ring]).mean()
    want = (frame[orig_ring].astype(float) - app.fill[orig_ring]).mean()
    assert got < -0.3 and got == pytest.approx(want, abs=1.5)
    # Loss pixels are real gel: off every original footprint, and the target is the frame.
    assert real.any() and not (real & app.footprint).any() and (real <= moved).all()
    # Away from original and moved footprints the input is the frame itself.
    away = ~(app.footprint | moved_fp | ts.dilate_mask(tp.shift(app.footprint, offset, False), 1))
    np.testing.assert_array_equal(cond[away], frame[away])


def test_border_cut_markers_are_not_moved():
    img = np.full((64, 96, 3), 180, np.uint8)
    img[20:30, 0:4] = 30  # a marker cut by the left border
    img[20:30, 40:50] = 30
    mask = img[:, :, 0] < 100
    app = tp.measure_appearance(img, mask, ring=1)
    ok = tp.movable(app, mask, (16, 16))
    left = app.labels[25, 1]
    mid = app.labels[25, 45]
    assert not ok[left] and ok[mid]
    assert not tp.movable(app, mask, (60, 0))[mid]  # would leave the frame


def test_marker_offset_pairs_transplant(marker_frames):
    pairs = tdata.marker_offset_pairs(marker_frames)
    assert set(pairs) == {"cond", "target", "mask", "loss_mask"}
    np.testing.assert_array_equal(pairs["target"], np.stack(marker_frames))
    for f, mask, loss in zip(marker_frames, pairs["mask"], pairs["loss_mask"], strict=True):
        orig = tdata.removal_markers(f).mask
        assert (mask <= tp.shift(orig, (16, 16), False)).all()
        assert loss.sum() > 0.5 * mask.sum() and not (loss & orig).any()
    with pytest.raises(ValueError, match="ring"):
        tdata.marker_offset_pairs(marker_frames, ring=-1)


def test_render_pair_realism_supervises_the_inference_mask():
    pytest.importorskip("av")
    for seed in range(3):
        pair = tdata.render_pair("gelsight_mini", seed)
        assert {"cond", "target", "mask", "loss_mask", "contact", "footprint"} <= set(pair)
        np.testing.assert_array_equal(pair["loss_mask"], pair["mask"])
        np.testing.assert_array_equal(pair["mask"], tdata.removal_markers(pair["cond"]).mask)
        # The target is the gel through the same camera: outside the markers the captured
        # frame differs from it by noise and codec only, not by a colour shift.
        away = ~ts.dilate_mask(pair["footprint"] | pair["mask"], 4)
        diff = pair["cond"][away].astype(float) - pair["target"][away]
        assert abs(diff.mean()) < 1.0 and np.abs(diff).mean() < 6
    old = tdata.render_pair("gelsight_mini", 0, realism=False)
    assert "footprint" not in old and (old["mask"] == old["loss_mask"]).all()


def test_remask_rewrites_changed_masks(tmp_path: Path):
    pytest.importorskip("av")
    tdata.render_pairs(tmp_path, 2, mix=(("gelsight_mini", 1.0),), progress=False)
    assert tdata.remask(tmp_path, progress=False) == 0
    path = next(tmp_path.glob("pairs_*.npz"))
    arrays = dict(np.load(path))
    arrays["mask"][:] = False
    np.savez(path, **arrays)
    assert tdata.remask(tmp_path, progress=False) == 1
    assert np.load(path)["mask"].any()


def test_network_from_onnx_round_trip(tmp_path: Path):
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.tacdiff.export import export_onnx, network_from_onnx
    from tacswitch.tacdiff.model import DenoiserUNet, UNetConfig

    torch.manual_seed(0)
    net = DenoiserUNet(UNetConfig(base=8, prior_radius=5))
    with torch.no_grad():  # non-trivial GroupNorm scales and shifts, zero-initialised layers
        for p in net.parameters():
            p.add_(0.1 * torch.randn_like(p))
    path = export_onnx(net, tmp_path / "m.onnx")
    back = network_from_onnx(path)
    assert back.cfg.prior_radius == 5.0  # recorded as tacswitch.prior_radius
    for k, v in net.state_dict().items():
        torch.testing.assert_close(back.state_dict()[k], v)
    with pytest.raises(ValueError, match="path"):
        network_from_onnx(ts.tacdiff.infer.default_model_path().with_name("motion_unet.onnx"))


def test_train_cli_init_continues_a_shipped_model(tmp_path: Path):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    pytest.importorskip("av")
    from tacswitch.tacdiff.train import load_network

    data = tmp_path / "d"
    tdata.render_pairs(data, 2, mix=(("gelsight_mini", 1.0),), progress=False)
    run = tmp_path / "run"
    base = ["train", "tacdiff", "--data", str(data), "--steps", "1", "--batch", "1",
            "--crop", "64", "-q"]
    assert main([*base, "--init", "fast", "--out", str(run)]) == 0
    assert load_network(run / "model.onnx").cfg.base == 16
    assert main([*base, "--init", "fast", "--base", "24", "--out", str(tmp_path / "x")]) == 2
    assert main([*base, "--init", "fast", "--prior", "telea", "--out",
                 str(tmp_path / "y")]) == 2
    assert main([*base, "--init", str(tmp_path / "nope.onnx"), "--out",
                 str(tmp_path / "z")]) == 2


def test_finetune_cli_options(tmp_path: Path, marker_frame_dir: Path):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")

    src = marker_frame_dir
    common = ["finetune", "--images", str(src), "--steps", "1", "--batch", "1", "--crop", "64",
              "-q"]
    assert main([*common, "--out", str(tmp_path / "a"), "--no-transplant", "--init",
                 "fast"]) == 0
    assert (tmp_path / "a" / "model.onnx").is_file()
    assert main([*common, "--out", str(tmp_path / "b"), "--ring", "-1"]) == 2
    assert main([*common, "--out", str(tmp_path / "c"), "--shifts", "0"]) == 2
    assert main([*common, "--out", str(tmp_path / "d"), "--shifts", "1", "--init", "fast"]) == 0
    import torch

    ck = torch.load(tmp_path / "d" / "checkpoint.pt", map_location="cpu", weights_only=False)
    # One shift is recorded as before (no "offsets"), so older run folders still resume.
    assert "offsets" not in ck["config"]["extra"] and len(ck["config"]["extra"]["offset"]) == 2


def test_cache_fills_is_reused_and_dropped_by_remask(tmp_path: Path, monkeypatch):
    pytest.importorskip("av")
    tdata.render_pairs(tmp_path, 1, mix=(("gelsight_mini", 1.0),), progress=False)
    assert tdata.cache_fills(tmp_path, "telea", progress=False) == 1
    assert tdata.cache_fills(tmp_path, "telea", progress=False) == 0
    shards = tdata.load_pairs(tmp_path)
    assert tdata.has_fills(shards[0], "telea") and not tdata.has_fills(shards[0],
                                                                       "telea+biharmonic")

    def boom(*_a, **_k):
        raise AssertionError("fills recomputed")

    monkeypatch.setattr(tdata, "classical_fills", boom)
    tdata.CropSampler(shards, 64, prior="telea").batch(1, np.random.default_rng(0))
    with pytest.raises(AssertionError, match="recomputed"):
        tdata.CropSampler(tdata.load_pairs(tmp_path), 64, prior="telea+biharmonic")
    monkeypatch.undo()
    path = next(tmp_path.glob("pairs_*.npz"))
    arrays = dict(np.load(path))
    arrays["mask"][:] = False
    np.savez(path, **arrays)
    assert tdata.remask(tmp_path, progress=False) == 1
    assert not tdata.has_fills(tdata.load_pairs(tmp_path)[0], "telea")


def test_transplants_are_built_on_the_given_pseudo_fill(marker_frames):
    frame = marker_frames[0]
    found = tdata.removal_markers(frame)
    calls = []

    def flat(img, holes):  # a fill anyone can recognise: the holes at grey 77
        calls.append(holes.sum())
        return np.where(holes[:, :, None], np.uint8(77), img)

    app = tp.measure_appearance(frame, found.mask, ring=3, pseudo_fill=flat)
    assert calls and (app.fill[app.footprint] == 77).all()
    pairs = tdata.marker_offset_pairs([frame], pseudo_fill=flat)
    cond, moved = pairs["cond"][0], pairs["mask"][0]
    # The original markers' footprints (away from the moved ones) carry that fill.
    away = app.footprint & ~ts.dilate_mask(moved, 6)
    assert away.any() and (cond[away] == 77).all()


def test_finetune_cli_pseudo_model_and_bad_choice(tmp_path: Path, marker_frame_dir: Path,
                                                   capsys):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    common = ["finetune", "--images", str(marker_frame_dir), "--steps", "1", "--batch", "1",
              "--crop", "64", "--init", "fast", "-q"]
    assert main([*common, "--out", str(tmp_path / "m"), "--pseudo", "model"]) == 0
    assert (tmp_path / "m" / "model.onnx").is_file()
    assert main([*common, "--out", str(tmp_path / "t"), "--pseudo", "telea",
                 "--no-mask-originals"]) == 0
    assert (tmp_path / "t" / "model.onnx").is_file()
    with pytest.raises(SystemExit):
        main([*common, "--out", str(tmp_path / "x"), "--pseudo", "ns"])
    assert "--pseudo" in capsys.readouterr().err
    from tacswitch.tacdiff.finetune import finetune

    with pytest.raises(ValueError, match="pseudo"):
        finetune([np.zeros((64, 64, 3), np.uint8)], tmp_path / "y", pseudo="ns")


def test_mask_originals_makes_every_marker_a_hole_and_keeps_the_loss(marker_frames):
    plain = tdata.marker_offset_pairs(marker_frames[:1])
    both = tdata.marker_offset_pairs(marker_frames[:1], mask_originals=True)
    orig = tdata.removal_markers(marker_frames[0]).mask
    np.testing.assert_array_equal(both["moved"][0], plain["mask"][0])
    np.testing.assert_array_equal(both["mask"][0], plain["mask"][0] | orig)
    np.testing.assert_array_equal(both["loss_mask"], plain["loss_mask"])  # real gel only
    np.testing.assert_array_equal(both["cond"], plain["cond"])
    assert "moved" not in plain


def test_marker_offset_pairs_several_shifts_share_one_fill_per_frame(marker_frames):
    calls: list[int] = []

    def flat(img: np.ndarray, holes: np.ndarray) -> np.ndarray:
        calls.append(1)
        out = img.copy()
        out[holes] = 128
        return out

    shifts = [(16, 16), (-16, -16), (16, 0)]
    pairs = tdata.marker_offset_pairs(marker_frames, offset=shifts, pseudo_fill=flat)
    assert len(calls) == len(marker_frames)  # the pseudo-markerless fill: once per frame
    assert len(pairs["cond"]) == len(marker_frames) * len(shifts)
    for j, sh in enumerate(shifts):  # frame by frame, its shifts in order: each as alone
        one = tdata.marker_offset_pairs(marker_frames[1:], offset=sh, pseudo_fill=flat)
        k = len(shifts) + j
        for key in ("cond", "target", "mask", "loss_mask"):
            assert np.array_equal(pairs[key][k], one[key][0]), (sh, key)
    # per_frame: each frame gets that many shifts, in rotation over the frames.
    two = tdata.marker_offset_pairs(marker_frames, offset=shifts, per_frame=1, pseudo_fill=flat)
    assert len(two["cond"]) == len(marker_frames)
    assert np.array_equal(two["mask"][1], pairs["mask"][len(shifts) + 1])  # frame 1, shift 1
    assert np.array_equal(tdata.marker_offset_pairs(marker_frames[:1], offset=[(16, 16)])["cond"],
                          tdata.marker_offset_pairs(marker_frames[:1], offset=(16, 16))["cond"])
    bads: list[Any] = [(16,), [(16, 16, 1)], [], (16.5, 16), "16,16", (np.nan, 0), ["16", "16"],
                       (True, False), [(16, 16), (0, 0)], [(16, 16), (8,)]]
    for bad in bads:
        with pytest.raises(ValueError, match=r"^offset"):
            tdata.marker_offset_pairs(marker_frames, offset=bad)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match=r"^per_frame: expected"):
            tdata.marker_offset_pairs(marker_frames, offset=shifts, per_frame=bad)
    app = tp.measure_appearance(marker_frames[0], tdata.removal_markers(marker_frames[0]).mask)
    with pytest.raises(ValueError, match=r"^appearance"):
        tp.transplant(marker_frames[0][:100], np.zeros((100, 320), bool), (16, 16),
                     appearance=app)
