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
