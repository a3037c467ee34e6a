"""Painted pairs from real markerless frames, parallel rendering, and GPU-ready training options
(device, batch prefetch, time budget, snapshots). Training parts skip without torch."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from tacswitch import realproxy
from tacswitch.cli import main
from tacswitch.tacdiff import data as tdata
from tacswitch.tacdiff import painted

PITCH, DIAMETER = 28.5, 11.5  # GelSight Mini at 320x240


@pytest.fixture(scope="module")
def mini_presses() -> list[tuple[int, np.ndarray, np.ndarray]]:
    pytest.importorskip("taxim")
    return realproxy.training_presses("gelsight_mini")[:3]


def test_training_presses_exclude_the_scored_ones() -> None:
    pytest.importorskip("taxim")
    for sensor in realproxy.SENSORS:
        held = realproxy.held_out_indices(sensor)
        train = [i for i, _, _ in realproxy.training_presses(sensor)]
        scored = {int(i) for i in np.linspace(0, len(train) + len(held) - 1,
                                                realproxy.HELD_OUT_PRESSES).round()}
        assert scored <= held and not held & set(train)
        assert len(train) + len(held) == len(realproxy.load_presses(sensor)[1])


def test_painted_pair_is_real_gel_with_realistic_markers(mini_presses) -> None:
    _, clean, contact = mini_presses[0]
    pair = painted.painted_pair(clean, pitch=PITCH, diameter=DIAMETER, seed=5, contact=contact)
    assert pair["cond"].shape == pair["target"].shape == clean.shape
    assert pair["cond"].dtype == pair["target"].dtype == np.uint8
    fp, mask = pair["footprint"], pair["mask"]
    # Markers cover the frame at about the pitch, the mask covers (nearly) all they changed,
    # and away from them the target is the real frame (blur and colour drift at most).
    assert 0.05 < fp.mean() < 0.4
    assert (fp & ~mask).sum() < 0.05 * fp.sum()  # the footprint counts 0.5-level halos
    assert np.array_equal(pair["loss_mask"], mask) and np.array_equal(pair["contact"], contact)
    gel = ~cv2.dilate(mask.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    diff = np.abs(pair["target"].astype(float) - clean.astype(float))[gel].mean()
    assert diff < 12
    # Markers are darker than the gel they cover.
    assert pair["cond"][fp].mean() < pair["target"][fp].mean() - 20
    # Deterministic by seed, different across seeds.
    again = painted.painted_pair(clean, pitch=PITCH, diameter=DIAMETER, seed=5, contact=contact)
    assert all(np.array_equal(pair[k], again[k]) for k in pair)
    other = painted.painted_pair(clean, pitch=PITCH, diameter=DIAMETER, seed=6)
    assert not np.array_equal(pair["cond"], other["cond"]) and not other["contact"].any()


def test_covering_grid_reaches_every_border() -> None:
    pts = painted.covering_grid(240, 320, PITCH, DIAMETER, np.random.default_rng(0))
    r = DIAMETER / 2
    assert (pts[:, 0] > -r).all() and (pts[:, 0] < 319 + r).all()
    # The lattice runs on past every border: the outermost dots lie within a pitch less a
    # radius of it (placement jitter 0.5 px), so dots cut by the border occur.
    reach = PITCH - r + 2
    assert pts[:, 0].min() < reach and pts[:, 0].max() > 319 - reach
    assert pts[:, 1].min() < reach and pts[:, 1].max() > 239 - reach
    cut = [painted.covering_grid(240, 320, PITCH, DIAMETER, np.random.default_rng(s))
           for s in range(10)]
    assert any((g[:, 0] < r).any() for g in cut)


def test_render_painted_pairs_is_the_same_with_workers_and_resumes(tmp_path: Path,
                                                                    mini_presses) -> None:
    frames = [f for _, f, _ in mini_presses]
    contacts = [c for _, _, c in mini_presses]
    one = painted.render_painted_pairs(tmp_path / "a", frames, 5, pitch=PITCH,
                                       diameter=DIAMETER, contacts=contacts, shard=2,
                                       progress=False, prior="telea", prior_radius=5)
    two = painted.render_painted_pairs(tmp_path / "b", frames, 5, pitch=PITCH,
                                       diameter=DIAMETER, contacts=contacts, shard=2,
                                       workers=2, progress=False, prior="telea",
                                       prior_radius=5)
    assert [p.name for p in one] == [p.name for p in two] == [
        "pairs_painted_000.npz", "pairs_painted_001.npz", "pairs_painted_002.npz"]
    for p, q in zip(one, two, strict=True):
        a, b = np.load(p), np.load(q)
        assert sorted(a) == sorted(b) and all(np.array_equal(a[k], b[k]) for k in a)
    shard = dict(np.load(one[0]))
    assert tdata.has_fills(shard, "telea", 5) and len(shard["cond"]) == 2
    mtime = one[0].stat().st_mtime_ns
    painted.render_painted_pairs(tmp_path / "a", frames, 5, pitch=PITCH, diameter=DIAMETER,
                                 shard=2, progress=False)
    assert one[0].stat().st_mtime_ns == mtime  # finished shards are kept


def test_render_painted_pairs_bad_input(tmp_path: Path, mini_presses) -> None:
    f = mini_presses[0][1]
    kw: dict[str, Any] = {"pitch": PITCH, "diameter": DIAMETER, "progress": False}
    with pytest.raises(ValueError, match="frames"):
        painted.render_painted_pairs(tmp_path, [], 1, **kw)
    with pytest.raises(ValueError, match=r"frames\[1\]"):
        painted.render_painted_pairs(tmp_path, [f, f[:100]], 1, **kw)
    with pytest.raises(TypeError, match=r"frames\[0\]"):
        painted.render_painted_pairs(tmp_path, [f.astype(np.float32)], 1, **kw)
    with pytest.raises(ValueError, match="contacts"):
        painted.render_painted_pairs(tmp_path, [f], 1, contacts=[None, None], **kw)
    with pytest.raises(ValueError, match="pitch, diameter"):
        painted.render_painted_pairs(tmp_path, [f], 1, pitch=10, diameter=12, progress=False)
    with pytest.raises(ValueError, match="workers"):
        painted.render_painted_pairs(tmp_path, [f], 1, workers=0, **kw)
    with pytest.raises(ValueError, match="name"):
        painted.render_painted_pairs(tmp_path, [f], 1, name="../x", **kw)
    with pytest.raises(ValueError, match="prior"):
        painted.render_painted_pairs(tmp_path, [f], 1, prior="magic", **kw)


def test_render_pairs_is_the_same_with_workers(tmp_path: Path) -> None:
    mix = (("gelsight_mini", 1.0),)
    one = tdata.render_pairs(tmp_path / "a", 3, mix=mix, shard=2, progress=False)
    two = tdata.render_pairs(tmp_path / "b", 3, mix=mix, shard=2, progress=False, workers=2,
                             prior="telea", prior_radius=5)
    for p, q in zip(one, two, strict=True):
        a, b = np.load(p), np.load(q)
        assert all(np.array_equal(a[k], b[k]) for k in a)
        assert tdata.has_fills(dict(b), "telea", 5) and not tdata.has_fills(dict(a), "telea", 5)
    with pytest.raises(ValueError, match="workers"):
        tdata.render_pairs(tmp_path / "c", 1, workers=0)


def _paint_dir(root: Path, presses, spec: dict | None) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    for i, f, c in presses:
        cv2.imwrite(str(root / f"press_{i:02d}.png"), f)
        cv2.imwrite(str(root / f"press_{i:02d}.contact.png"), c.astype(np.uint8) * 255)
    if spec is not None:
        (root / "markers.json").write_text(json.dumps(spec))
    return root


def test_train_cli_paints_real_frames_and_renders_only(tmp_path: Path, mini_presses) -> None:
    pytest.importorskip("torch")
    folder = _paint_dir(tmp_path / "mini", mini_presses[:2],
                        {"pitch": PITCH, "diameter": DIAMETER})
    data = tmp_path / "d"
    assert main(["train", "tacdiff", "--data", str(data), "--paint", str(folder),
                 "--paint-pairs", "3", "--render-only", "-q"]) == 0
    shards = sorted(p.name for p in data.iterdir())
    assert len(shards) == 1 and shards[0].startswith("pairs_painted_mini_")
    shard = dict(np.load(data / shards[0]))
    assert len(shard["cond"]) == 3 and shard["contact"].any()  # contact masks were read
    assert tdata.has_fills(shard, "telea+biharmonic-grown", 12)  # the default prior, cached
    # The same folder again: nothing new. Another spec (or other frames) under the same folder
    # name: new shards, not the stale ones.
    again = ["train", "tacdiff", "--data", str(data), "--paint", str(folder), "--paint-pairs",
             "3", "--render-only", "-q"]
    assert main(again) == 0 and sorted(p.name for p in data.iterdir()) == shards
    (folder / "markers.json").write_text(json.dumps({"pitch": 40, "diameter": 12}))
    assert main(again) == 0 and len(list(data.iterdir())) == 2


@pytest.mark.parametrize(("extra", "message"), [
    (["--paint", "NOPE"], "--paint: no folder"),
    (["--paint", "EMPTY"], "--paint: no PNG/JPEG"),
    (["--paint", "NOSPEC"], "--pitch and --diameter"),
    (["--paint", "NOSPEC", "--pitch", "10", "--diameter", "12"], "--pitch, --diameter"),
    (["--paint", "MIXED", "--pitch", "28", "--diameter", "11"], "one size per folder"),
    (["--time-budget", "-1"], "--time-budget"),
    (["--paint", "LIST"], "must hold an object"),
    (["--paint", "BADMASK", "--pitch", "28", "--diameter", "11"], "contact mask"),
    (["--paint", "NOSPEC", "--pitch", "28", "--diameter", "11", "--device", "tpu"],
     "--device"),
    (["--workers", "0"], "--workers"),
    ([], "--out"),
])
def test_train_cli_paint_and_gpu_options_are_checked(tmp_path: Path, mini_presses, capsys,
                                                     extra: list[str], message: str) -> None:
    pytest.importorskip("torch")
    (tmp_path / "EMPTY").mkdir()
    _paint_dir(tmp_path / "NOSPEC", mini_presses[:1], None)
    mixed = _paint_dir(tmp_path / "MIXED", mini_presses[:1], None)
    cv2.imwrite(str(mixed / "small.png"), np.zeros((10, 10, 3), np.uint8))
    _paint_dir(tmp_path / "LIST", mini_presses[:1], None)
    (tmp_path / "LIST" / "markers.json").write_text("[28, 11]")
    bad = _paint_dir(tmp_path / "BADMASK", mini_presses[:1], None)
    next(bad.glob("*.contact.png")).write_bytes(b"not an image")
    names = ("NOPE", "EMPTY", "NOSPEC", "MIXED", "LIST", "BADMASK")
    args = [str(tmp_path / a) if a in names else a for a in extra]
    out = [] if not extra else ["--out", str(tmp_path / "run")]
    assert main(["train", "tacdiff", "--data", str(tmp_path / "d"), *out, *args, "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not (tmp_path / "d").exists()  # refused before rendering anything


def test_paint_folder_contact_masks_of_any_format_are_not_frames(tmp_path: Path,
                                                                 mini_presses) -> None:
    from tacswitch.cli.tacdiff_cmds import paint_source

    folder = tmp_path / "f"
    folder.mkdir()
    _, frame, contact = mini_presses[0]
    cv2.imwrite(str(folder / "a.jpg"), frame)
    cv2.imwrite(str(folder / "a.contact.jpg"), contact.astype(np.uint8) * 255)
    name, frames, contacts, pitch, diameter = paint_source(str(folder), 28.5, 11.5)
    assert name == "f" and len(frames) == 1 and contacts[0] is not None
    assert (pitch, diameter) == (28.5, 11.5)


def test_step_batches_prefetch_draws_what_a_plain_run_draws(mini_presses) -> None:
    from tacswitch.tacdiff.train import TrainConfig, step_batches

    pair = painted.painted_pair(mini_presses[0][1], pitch=PITCH, diameter=DIAMETER, seed=1)
    sampler = tdata.CropSampler([{k: v[None] for k, v in pair.items()}], 32, prior="telea",
                                prior_radius=5)
    cfg = TrainConfig(batch=2, steps=5, seed=3)
    plain = list(step_batches(sampler, cfg, 1, workers=0))
    ahead = list(step_batches(sampler, cfg, 1, workers=3))
    assert len(plain) == len(ahead) == 4
    for (b1, t1, r1), (b2, t2, r2) in zip(plain, ahead, strict=True):
        assert all(np.array_equal(b1[k], b2[k]) for k in b1) and np.array_equal(t1, t2)
        assert r1.random() == r2.random()  # the generators continue alike
    assert "eps" in plain[0][0] and plain[0][0]["eps"].shape == plain[0][0]["target"].shape


def test_pick_device_names_the_argument() -> None:
    torch = pytest.importorskip("torch")
    from tacswitch.tacdiff.train import pick_device

    assert pick_device("cpu") == "cpu"
    assert pick_device("auto") == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(ValueError, match="device"):
        pick_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match=r"device.*no CUDA"):
            pick_device("cuda")


def test_denoiser_creates_no_tensor_off_its_device() -> None:
    """On the meta device any tensor made on the CPU inside forward fails (as on a GPU)."""
    torch = pytest.importorskip("torch")
    from tacswitch.tacdiff.model import DenoiserUNet, UNetConfig, network_input

    net = DenoiserUNet(UNetConfig(base=8, mults=(1, 2))).to("meta")  # the default prior
    planes = [torch.empty((2, c, 32, 32), device="meta") for c in (3, 1, 3, 3, 3, 3)]
    x = network_input(*planes)
    out = net(x, torch.empty(2, device="meta"))
    assert out.device.type == "meta" and out.shape[-2:] == (32, 32)


def test_time_budget_ends_training_and_snapshots_are_written(tmp_path: Path,
                                                              mini_presses) -> None:
    pytest.importorskip("torch")
    from tacswitch.tacdiff.train import TrainConfig, train

    pair = painted.painted_pair(mini_presses[0][1], pitch=PITCH, diameter=DIAMETER, seed=1)
    shard = {k: v[None] for k, v in pair.items()}
    seen: list[int] = []
    cfg = TrainConfig(base=8, mults=(1, 2), steps=10_000, batch=1, crop=32, warmup=1,
                      threads=1, prior="telea", prior_radius=5, time_budget=1e-9, log_every=1)
    train([shard], tmp_path / "run", cfg, progress=False,
          callback=lambda step, ema: seen.append(step), callback_every=1000)
    log = [json.loads(line) for line in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    # Out of time after the first step: it is logged, checkpointed and the callback sees it.
    assert [e["step"] for e in log] == [1] and seen == [1]
    assert (tmp_path / "run" / "model.safetensors").is_file()
    # Run again: the budget is spent, so it is finished; nothing trains, nothing changes.
    before = {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()}
    train([shard], tmp_path / "run", cfg, progress=False)
    after = {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()}
    assert after["log.jsonl"] == before["log.jsonl"]
    assert after["checkpoint.pt"] == before["checkpoint.pt"]
    assert after["model.safetensors"] == before["model.safetensors"]
    with pytest.raises(ValueError, match="time_budget"):
        train([shard], tmp_path / "bad", TrainConfig(base=8, steps=1, time_budget=-1.0),
              progress=False)
