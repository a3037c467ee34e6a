"""TacDiff training, export and the CLI commands around it (training parts skip without torch)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

import tacswitch as ts
from tacswitch.cli import main
from tacswitch.sim.scene import render_sample
from tacswitch.tacdiff import data as tdata


def test_marker_offset_pairs_follow_the_paper(marker_frames):
    pairs = tdata.marker_offset_pairs(marker_frames, transplant=False)
    # The mask remove_markers fills (adaptive growth, border-cut markers included).
    orig = ts.extract_markers(marker_frames[0], dilate="auto").mask
    mask, loss = pairs["mask"][0], pairs["loss_mask"][0]
    # Shifted by half the pitch (28.5 px / 2 -> 14) on both axes; pixels shifted out are dropped.
    shift = tdata._shift(orig, (14, 14))
    np.testing.assert_array_equal(mask, shift)
    # The loss only sees real gel: shifted pixels that land on an original marker are dropped.
    assert not (loss & orig).any() and (loss <= mask).all() and loss.sum() > 0.5 * mask.sum()
    # The condition is the TELEA pseudo-markerless frame (never the loss target on a hole).
    np.testing.assert_array_equal(pairs["cond"][0], ts.inpaint_telea(marker_frames[0], orig, 3))


def test_marker_offset_pairs_bad_input(marker_frames):
    with pytest.raises(ValueError, match="frames"):
        tdata.marker_offset_pairs([])
    with pytest.raises(ValueError, match=r"frames\[1\]"):
        tdata.marker_offset_pairs([marker_frames[0], marker_frames[1][:100]])
    flat = np.full((64, 64, 3), 128, np.uint8)
    with pytest.raises(ValueError, match="pitch"):
        tdata.marker_offset_pairs([flat])


def test_crop_sampler_shapes_and_ranges(marker_frames):
    pairs = tdata.marker_offset_pairs(marker_frames, offset=(14, 14))
    batch = tdata.CropSampler([pairs], 64).batch(3, np.random.default_rng(0))
    for key in ("cond", "target", "prior"):
        assert batch[key].shape == (3, 3, 64, 64) and batch[key].dtype == np.float32
        assert batch[key].min() >= -1 and batch[key].max() <= 1
    assert set(np.unique(batch["mask"])) <= {0.0, 1.0}
    with pytest.raises(ValueError, match="size"):
        tdata.CropSampler([pairs], 512)


def test_crop_sampler_contact_share_centres_crops_on_contact_holes():
    pair = tdata.render_pair("gelsight_mini", 3)
    assert (pair["mask"] & pair["contact"]).any()
    shard = {k: v[None] for k, v in pair.items()}
    size = 32

    def contact_hole_share(*, contact_share: float, hole_share: float) -> float:
        sampler = tdata.CropSampler([dict(shard)], size, augment=False,
                                    contact_share=contact_share, hole_share=hole_share)
        rng = np.random.default_rng(1)
        hits = 0
        for _ in range(40):
            b = sampler.batch(1, rng)
            # The crop's pixels in contact are recovered from the (unaugmented) frame position
            # of the crop: find it by matching the condition crop against the frame.
            crop = ((b["cond"][0].transpose(1, 2, 0) + 1) * 127.5).round().astype(np.uint8)
            ys, xs = np.nonzero(pair["cond"][:, :, 0] == crop[0, 0, 0])
            for y, x in zip(ys, xs, strict=True):
                win = pair["cond"][y:y + size, x:x + size]
                if win.shape[:2] == (size, size) and np.array_equal(win, crop):
                    hits += bool((pair["mask"] & pair["contact"])[y:y + size, x:x + size].any())
                    break
        return hits / 40

    assert contact_hole_share(contact_share=1.0, hole_share=0.0) == 1.0
    assert contact_hole_share(contact_share=0.0, hole_share=0.0) < 0.8
    with pytest.raises(ValueError, match="contact_share"):
        tdata.CropSampler([shard], size, contact_share=0.8, hole_share=0.5)


def test_remove_markers_cli_tacdiff_and_hybrid(tmp_path: Path):
    s = render_sample("gelsight_mini", 5)
    src = tmp_path / "in"
    src.mkdir()
    cv2.imwrite(str(src / "a.png"), s.image_markers)
    cv2.imwrite(str(tmp_path / "ref.png"), s.reference)
    for method in ("tacdiff", "hybrid"):
        out = tmp_path / method
        extra = ["--ref", str(tmp_path / "ref.png")] if method == "hybrid" else []
        assert main(["remove-markers", str(src), "-o", str(out), "--method", method,
                     "--steps", "1", *extra, "-q"]) == 0
        got = cv2.imread(str(out / "a.png"))
        assert got is not None
        mask = ts.extract_markers(s.image_markers, dilate="auto").mask
        np.testing.assert_array_equal(got[~mask], s.image_markers[~mask])


def test_evaluate_tacdiff_tiny(tmp_path: Path):
    pytest.importorskip("skimage")
    report = tmp_path / "e.json"
    assert main(["evaluate", "tacdiff", "--frames", "1", "--presets", "gelsight_mini",
                 "--steps", "1", "--json", str(report), "-q"]) == 0
    rows = json.loads(report.read_text())["gelsight_mini"]
    names = {(r["method"], r["setting"]) for r in rows}
    assert ("TacDiff", "K=1, 4 orientations") in names and ("TELEA (OpenCV)", "r=3") in names
    assert ("TacDiff", "K=1, 1 orientation") in names
    assert all(0 < r["ssim"] <= 1 and r["masked_mae"] > 0 for r in rows)
    assert main(["evaluate", "tacdiff", "--frames", "1", "--presets", "gelsight_mini",
                 "--steps", "1", "--mask", "extracted", "--json", str(report), "-q"]) == 0
    extracted = {(r["method"], r["setting"]): r for r in
                 json.loads(report.read_text())["gelsight_mini"]}
    # The extracted mask is scored on its union with the true footprint: a larger area.
    assert extracted[("TacDiff", "K=1, 4 orientations")]["masked_mae"] > 0


def test_train_tacdiff_tiny_run_resumes_and_exports(tmp_path: Path):
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.tacdiff.infer import TacDiffModel, inpaint_tacdiff
    from tacswitch.tacdiff.model import network_input
    from tacswitch.tacdiff.train import load_network

    run = tmp_path / "run"
    args = ["train", "tacdiff", "--data", str(tmp_path / "d"), "--simulate", "4", "--steps",
            "2", "--batch", "2", "--crop", "64", "--base", "8", "--out", str(run), "-q"]
    assert main(args) == 0
    shards = sorted(p.name for p in (tmp_path / "d").iterdir())
    assert shards and all(n.startswith("pairs_") for n in shards)
    assert (run / "checkpoint.pt").is_file() and (run / "model.safetensors").is_file()
    umask = os.umask(0)
    os.umask(umask)
    assert (run / "model.safetensors").stat().st_mode & 0o777 == 0o666 & ~umask  # not private
    before = (run / "log.jsonl").read_text()
    assert main(args) == 0  # finished run: resumes, trains no further
    assert (run / "log.jsonl").read_text() == before
    import onnx

    meta = {p.key: p.value for p in onnx.load(str(run / "model.onnx")).metadata_props}
    assert meta["tacswitch.loss"] == "v_mse"  # the CLI defaults, recorded in the model
    assert json.loads(meta["tacswitch.terminal_fraction"]) == 0.3
    # onnxruntime matches torch.
    net = load_network(run / "model.safetensors")
    model = TacDiffModel(run / "model.onnx", threads=1)
    rng = np.random.default_rng(0)
    assert model.prior == net.cfg.prior == "telea+biharmonic-grown"  # DEFAULT_PRIOR
    assert model.prior_radius == net.cfg.prior_radius == 12  # DEFAULT_PRIOR_RADIUS
    arrs = [rng.standard_normal((1, c, 32, 48)).astype(np.float32) for c in (3, 1, 3, 3, 3, 3)]
    arrs[1] = (arrs[1] > 0.5).astype(np.float32)
    with torch.no_grad():
        want = net(network_input(*[torch.from_numpy(a) for a in arrs]),
                   torch.tensor([0.7])).numpy()
    got = model.v(arrs[0], arrs[1], arrs[2], arrs[3], arrs[4], 0.7, arrs[5])
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-5 * np.abs(want).max())
    img = render_sample("digit", 3).image_markers
    mask = ts.extract_markers(img, dilate=1, exclude_border=False).mask
    out = inpaint_tacdiff(img, mask, 2, model=run / "model.onnx")
    np.testing.assert_array_equal(out[~mask], img[~mask])


def test_fp16_export_is_refused(tmp_path: Path):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.model import DenoiserUNet, UNetConfig

    with pytest.raises(ValueError, match="fp16"):
        export_onnx(DenoiserUNet(UNetConfig(base=8)), tmp_path / "m.onnx", fp16=True)


def test_finetune_on_marker_frames(tmp_path: Path, marker_frames, marker_frame_dir: Path):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    src = marker_frame_dir
    run = tmp_path / "ft"
    assert main(["finetune", "--images", str(src), "--out", str(run), "--steps", "2",
                 "--batch", "2", "--crop", "64", "-q"]) == 0
    out = ts.remove_markers(marker_frames[0], method="tacdiff", steps=1,
                            model=run / "model.onnx")
    assert out.shape == marker_frames[0].shape
    assert main(["finetune", "--images", str(src), "--out", str(tmp_path / "x"), "--offset",
                 "nope", "-q"]) == 2


def test_fills_follow_the_prior_radius(marker_frames):
    from tacswitch.tacdiff.prior import PRIOR_RADIUS

    prior = "telea+biharmonic-grown"
    shard = tdata.marker_offset_pairs(marker_frames, offset=(14, 14))
    # A cache as written before radii were recorded: r = 3, no fills_radius.
    shard["telea"], shard["smooth"] = tdata.classical_fills(shard["cond"], shard["mask"], prior,
                                                            PRIOR_RADIUS)
    shard["fills_prior"] = np.array(prior)
    assert tdata.has_fills(shard, prior, 3) and not tdata.has_fills(shard, prior, 12)
    smooth = shard["smooth"]
    sampler = tdata.CropSampler([shard], 64, prior=prior, prior_radius=12)
    assert sampler.prior_radius == 12.0 and tdata.has_fills(shard, prior, 12)
    assert shard["smooth"] is smooth  # the biharmonic fill has no radius: kept
    want = tdata.classical_fills(shard["cond"], shard["mask"], prior, 12)[0]
    np.testing.assert_array_equal(shard["telea"], want)
    assert not np.array_equal(want, tdata.classical_fills(shard["cond"], shard["mask"], "telea",
                                                          3)[0])
    for bad in (0, 0.5, 65, float("nan"), "wide"):
        with pytest.raises(ValueError, match="prior_radius"):
            tdata.CropSampler([shard], 64, prior=prior, prior_radius=bad)  # type: ignore[arg-type]


def test_train_records_the_prior_radius(tmp_path: Path, marker_frames):
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    import onnx

    from tacswitch.tacdiff.export import export_onnx
    from tacswitch.tacdiff.infer import TacDiffModel
    from tacswitch.tacdiff.train import TrainConfig, load_network, train

    pairs = tdata.marker_offset_pairs(marker_frames, offset=(14, 14))
    cfg = TrainConfig(base=8, steps=1, batch=1, crop=64, warmup=1, threads=1, prior_radius=7,
                      save_every=100, log_every=100)
    net = train([pairs], tmp_path / "r", cfg, progress=False)
    assert float(pairs["fills_radius"]) == 7.0  # the sampler's fills used it
    path = export_onnx(net, tmp_path / "m.onnx")
    meta = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    assert meta["tacswitch.prior_radius"] == "7"
    assert TacDiffModel(path).prior_radius == 7.0
    assert load_network(tmp_path / "r" / "model.safetensors").cfg.prior_radius == 7.0
    with pytest.raises(ValueError, match="prior_radius"):
        train([pairs], tmp_path / "bad", TrainConfig(base=8, steps=1, prior_radius=0),
              progress=False)
    assert main(["train", "tacdiff", "--data", str(tmp_path / "none"), "--prior-radius", "200",
                 "--out", str(tmp_path / "x"), "-q"]) == 2


def test_x0_l1_loss_is_the_absolute_error_of_the_x0_estimate(marker_frames):
    torch = pytest.importorskip("torch")
    from tacswitch.tacdiff.model import RESIDUAL_SCALE
    from tacswitch.tacdiff.schedule import alpha_sigma
    from tacswitch.tacdiff.train import draw_noise, masked_v_loss

    pairs = tdata.marker_offset_pairs(marker_frames, offset=(14, 14))
    batch = tdata.CropSampler([pairs], 64, hole_share=1.0).batch(3, np.random.default_rng(0))
    pred = np.random.default_rng(1).standard_normal(batch["target"].shape).astype(np.float32)

    def net(x, s):  # a fixed prediction, whatever the input
        return torch.from_numpy(pred)

    t = np.array([1.0, 0.5, 0.1], np.float32)
    r0 = RESIDUAL_SCALE * (batch["target"] - batch["prior"]) * batch["mask"]
    eps = draw_noise(batch, np.random.default_rng(7))  # what masked_v_loss draws
    a, s = (u.astype(np.float32)[:, None, None, None] for u in alpha_sigma(t))
    x0_hat = a * (a * r0 + s * eps) - s * pred  # the sampler's x0 estimate from v
    v = a * eps - s * r0
    lm = np.broadcast_to(batch["loss_mask"], r0.shape)
    assert lm.sum() > 0
    got = {k: float(masked_v_loss(net, batch, t, np.random.default_rng(7), k))
           for k in ("v_mse", "x0_l1")}
    assert got["x0_l1"] == pytest.approx(np.abs(x0_hat - r0)[lm > 0].mean(), rel=1e-4)
    assert got["v_mse"] == pytest.approx(((pred - v) ** 2)[lm > 0].mean(), rel=1e-4)
    with pytest.raises(ValueError, match="loss"):
        masked_v_loss(net, batch, t, np.random.default_rng(7), "l2")


def test_train_records_the_loss_and_checks_its_options(tmp_path: Path, marker_frames):
    torch = pytest.importorskip("torch")
    from tacswitch.tacdiff.train import TrainConfig, train

    pairs = tdata.marker_offset_pairs(marker_frames, offset=(14, 14))
    cfg = TrainConfig(base=8, mults=(1, 2), steps=1, batch=1, crop=64, warmup=1, threads=1,
                      loss="x0_l1", terminal_fraction=1.0, save_every=100, log_every=100)
    train([pairs], tmp_path / "r", cfg, progress=False)
    ck = torch.load(tmp_path / "r" / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert ck["config"]["loss"] == "x0_l1" and ck["config"]["terminal_fraction"] == 1.0
    for bad in ({"loss": "l2"}, {"terminal_fraction": 1.5}, {"terminal_fraction": float("nan")}):
        name = next(iter(bad))
        with pytest.raises(ValueError, match=name):
            train([pairs], tmp_path / "bad",
                  TrainConfig(base=8, steps=1, **bad),  # type: ignore[arg-type]
                  progress=False)
    # A checkpoint written before the loss was recorded resumes as v_mse.
    cfg2 = TrainConfig(base=8, mults=(1, 2), steps=2, batch=1, crop=64, warmup=1, threads=1,
                       save_every=1, log_every=100)
    train([pairs], tmp_path / "old", TrainConfig(**{**cfg2.__dict__, "steps": 1}),
          progress=False)
    ck = torch.load(tmp_path / "old" / "checkpoint.pt", map_location="cpu", weights_only=False)
    del ck["config"]["loss"]
    ck["config"]["steps"] = 2
    torch.save(ck, tmp_path / "old" / "checkpoint.pt")
    train([pairs], tmp_path / "old", cfg2, progress=False)  # resumes: no configuration error


@pytest.mark.parametrize(("flag", "value"), [("--terminal-fraction", "1.5"),
                                             ("--terminal-fraction", "nan")])
def test_train_cli_refuses_a_bad_terminal_fraction(tmp_path: Path, flag: str, value: str,
                                                   capsys):
    pytest.importorskip("torch")  # without it the command stops earlier, on the import
    assert main(["train", "tacdiff", "--data", str(tmp_path / "none"), flag, value,
                 "--out", str(tmp_path / "x"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--terminal-fraction" in err[0]


def test_train_cli_refuses_an_unknown_loss(tmp_path: Path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["train", "tacdiff", "--data", str(tmp_path / "none"), "--loss", "l2",
              "--out", str(tmp_path / "x"), "-q"])
    assert exc.value.code == 2
    assert "--loss" in capsys.readouterr().err
