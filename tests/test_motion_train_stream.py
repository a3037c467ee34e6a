"""Streaming training of the consistent motion regressor (torch; CPU here, the GPU when there is
one): a tiny end-to-end run, the batch augmentation, argument checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from tacswitch.motion import train_stream as ts_  # noqa: E402


def _batch(n: int = 6, h: int = 24, w: int = 32) -> dict:
    g = torch.Generator().manual_seed(0)
    img = torch.randint(0, 256, (n, h, w, 3), generator=g, dtype=torch.uint8)
    rest = torch.rand(n, 5, 2, generator=g) * torch.tensor([w - 1.0, h - 1.0])
    motion = {k: torch.randn(n, 5, 2, generator=g)
              for k in ("displacement", "disp_image", "disp_reference")}
    return {"image": img, "reference": img.flip(1).contiguous(), "rest": rest, **motion}


def test_augment_flips_move_centres_and_motions_together() -> None:
    b = _batch()
    h, w = b["image"].shape[1:3]
    out = ts_.augment(b, torch.Generator().manual_seed(3), colour=False)
    seen = set()
    for i in range(len(b["image"])):
        fx = bool(torch.equal(out["image"][i], b["image"][i].flip(1)) or
                  torch.equal(out["image"][i], b["image"][i].flip(0).flip(1)))
        fy = bool(torch.equal(out["image"][i], b["image"][i].flip(0)) or
                  torch.equal(out["image"][i], b["image"][i].flip(0).flip(1)))
        if torch.equal(out["image"][i], b["image"][i]):
            fx = fy = False
        seen.add((fx, fy))
        sx, sy = (-1.0 if fx else 1.0), (-1.0 if fy else 1.0)
        want_x = (w - 1) - b["rest"][i, :, 0] if fx else b["rest"][i, :, 0]
        want_y = (h - 1) - b["rest"][i, :, 1] if fy else b["rest"][i, :, 1]
        assert torch.allclose(out["rest"][i, :, 0], want_x)
        assert torch.allclose(out["rest"][i, :, 1], want_y)
        for k in ("displacement", "disp_image", "disp_reference"):
            assert torch.allclose(out[k][i], b[k][i] * torch.tensor([sx, sy]))
    assert len(seen) > 1  # the seed flips some samples and not others


def test_augment_colour_keeps_both_frames_alike() -> None:
    b = _batch()
    b["reference"] = b["image"].clone()
    out = ts_.augment(b, torch.Generator().manual_seed(1), colour=True)
    assert torch.equal(out["image"], out["reference"])
    assert out["image"].dtype == torch.uint8
    assert not torch.equal(out["image"], b["image"])


def test_a_tiny_run_writes_models_that_are_consistent(tmp_path) -> None:
    from tacswitch.motion.infer import MotionModel

    cfg = ts_.StreamConfig(workers=1, capacity=8, warm=2, batch=2, n_val=2, max_steps=2,
                           eval_every=1, seconds=600.0, device="cpu",
                           variants={"a": {"widths": [8, 8, 8, 8]}})
    scores = ts_.train_stream(tmp_path, cfg, progress=False)
    assert set(scores) == {"a"} and np.isfinite(scores["a"]["pair_e_rmse"])
    log = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    assert log[-1]["step"] == 2
    m = MotionModel(tmp_path / "a.onnx")
    assert m.design == "consistent"
    img = np.random.default_rng(0).integers(0, 256, (240, 320, 3), dtype=np.uint8)
    assert not np.any(m(img, img.copy()))
    meta = json.loads(m.metadata["tacswitch.trained_on"])
    assert meta["steps"] == 2 and meta["stream"]["preset"] == "mixed"


def test_arguments_are_checked(tmp_path) -> None:
    with pytest.raises(ValueError, match=r"^workers: "):
        ts_.train_stream(tmp_path, ts_.StreamConfig(workers=0))
    with pytest.raises(ValueError, match=r"^capacity: "):
        ts_.train_stream(tmp_path, ts_.StreamConfig(capacity=4, warm=8))
    with pytest.raises(ValueError, match=r"^preset: "):
        ts_.train_stream(tmp_path, ts_.StreamConfig(preset="nope"))
    with pytest.raises(ValueError, match=r"^device: "):
        ts_.resolve_device("not-a-device")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match=r"^device: "):
            ts_.resolve_device("cuda")
