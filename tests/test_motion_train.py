"""Training smoke test (skipped without torch): two tiny steps, export, resume."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")


def _tiny_data(n: int = 4) -> dict:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (n, 48, 64, 3), dtype=np.uint8)
    rest = rng.uniform(0, 60, (n, 5, 2)).astype(np.float32)
    disp = rng.normal(0, 2, (n, 5, 2)).astype(np.float32)
    disp[0, 0] = np.nan  # a marker the tracker lost: left out of the loss
    return {"image": img, "reference": img[::-1].copy(), "rest": rest, "displacement": disp,
            "present": np.ones((n, 5), bool)}


@pytest.mark.parametrize("use_ref", [False, True])
def test_two_steps_export_and_resume(tmp_path, use_ref):
    from tacswitch.motion.export import export_onnx
    from tacswitch.motion.infer import MotionModel
    from tacswitch.motion.train import TrainConfig, train

    data = _tiny_data()
    cfg = TrainConfig(arch="unet", use_ref=use_ref, epochs=1, batch=2, max_steps_per_epoch=2,
                      threads=1, val_fraction=0.25)
    net = train(data, tmp_path, cfg, progress=False)
    assert (tmp_path / "checkpoint.pt").is_file() and (tmp_path / "log.jsonl").is_file()
    # Resume: a finished run trains no further and gives the same weights.
    again = train(data, tmp_path, cfg, progress=False)
    for a, b in zip(net.state_dict().values(), again.state_dict().values(), strict=True):
        assert torch.equal(a, b)
    path = export_onnx(net, tmp_path / "m.onnx", metadata={"work_width": 64, "work_height": 48,
                                                           "default_centres": [[3.0, 4.0]]},
                       height=48, width=64)
    model = MotionModel(path, threads=1)
    img, ref = data["image"][1], data["reference"][1]
    got = model(img, ref=ref if use_ref else None, centres=data["rest"][1])
    with torch.no_grad():
        want = net(torch.from_numpy(img[None]), torch.from_numpy(data["rest"][1][None]),
                   torch.from_numpy(ref[None]) if use_ref else None)[0].numpy()
    np.testing.assert_allclose(got, want, atol=1e-4)


def test_reference_configuration_builds():
    from tacswitch.motion.model import MotionNet, count_params

    net = MotionNet("deeplabv3")
    assert 10.5e6 < count_params(net) < 11.5e6  # the paper's 11.0 M
    out = net.eval()(torch.zeros(1, 64, 64, 3, dtype=torch.uint8), torch.zeros(1, 3, 2))
    assert out.shape == (1, 3, 2)


def test_consistent_design_trains_exports_and_is_consistent(tmp_path):
    """The consistent design: two steps on crops, export, onnxruntime parity in both modes,
    exact zero for identical frames and a brightness change normalised away (untrained weights
    with random BatchNorm statistics: the properties hold by construction, not by training)."""
    from tacswitch.motion.export import export_onnx
    from tacswitch.motion.infer import MotionModel
    from tacswitch.motion.train import TrainConfig, train

    data = _tiny_data()
    data["disp_reference"] = 0.5 * data["displacement"]
    data["disp_image"] = 1.5 * data["displacement"]
    cfg = TrainConfig(design="consistent", loss="euclid", epochs=1, batch=2,
                      max_steps_per_epoch=2, threads=1, val_fraction=0.25, crop=(32, 32))
    net = train(data, tmp_path, cfg, progress=False)
    assert net.design == "consistent" and not net.use_ref
    gen = torch.Generator().manual_seed(0)
    for m in net.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-0.5, 0.5, generator=gen)
            m.running_var.uniform_(0.5, 2.0, generator=gen)
    path = export_onnx(net, tmp_path / "c.onnx", metadata={"work_width": 64, "work_height": 48},
                       height=48, width=64)
    model = MotionModel(path, threads=1)
    assert model.design == "consistent" and not model.use_ref
    assert model.metadata["tacswitch.kind"] == "motion"
    img, ref, cen = data["image"][1], data["reference"][1], data["rest"][1]
    t = torch.from_numpy
    with torch.no_grad():
        pair = net(t(img[None]), t(cen[None]), t(ref[None]))[0].numpy()
        single = net(t(img[None]), t(cen[None]))[0].numpy()
    np.testing.assert_allclose(model(img, ref, cen), pair, atol=1e-4)
    np.testing.assert_allclose(model(img, None, cen), single, atol=1e-4)
    assert np.abs(pair).max() > 1e-3 and np.abs(single - pair).max() > 1e-3  # not trivially 0
    dense = np.stack(np.meshgrid(np.arange(64.0), np.arange(48.0)), -1).reshape(-1, 2)
    assert np.abs(model(img, img, dense.astype(np.float32))).max() < 0.05
    brighter = np.clip(np.rint(img.astype(np.float32) * 1.1 + 6), 0, 255).astype(np.uint8)
    dim = np.clip(img.astype(np.float32) * 0.8, 0, 255).astype(np.uint8)
    # Mean/std normalisation removes a gain and an offset up to rounding and clipping.
    assert np.abs(model(brighter, dim, dense.astype(np.float32))).max() < 0.2
