"""Execution providers: ``device="auto" | "cpu" | "cuda"`` on the model entry points and
``--device`` on the CLI. No GPU here: onnxruntime's provider list is monkeypatched, and the
sessions' requested providers are recorded."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import onnxruntime as ort
import pytest

import tacswitch as ts
from tacswitch import _ort
from tacswitch.cli import main

CPU_ONLY = ["AzureExecutionProvider", "CPUExecutionProvider"]
WITH_CUDA = ["CUDAExecutionProvider", "CPUExecutionProvider"]


@pytest.fixture
def recorded(monkeypatch: pytest.MonkeyPatch) -> list[list[str]]:
    """The providers every new session asks for; the session itself runs on the CPU (a
    CUDA provider cannot be created without a GPU)."""
    calls: list[list[str]] = []
    real = ort.InferenceSession

    def session(path: str, options: Any = None, providers: Any = None, **kw: Any) -> Any:
        calls.append(list(providers))
        return real(path, options, providers=["CPUExecutionProvider"], **kw)

    monkeypatch.setattr(ort, "InferenceSession", session)
    monkeypatch.setattr(_ort, "_CACHE", {})
    return calls


def FRAME() -> np.ndarray:
    """A GelSight Mini frame with markers, of a simulated grasp (cached)."""
    if not _FRAME:
        _FRAME.append(ts.sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=2).frames[4])
    return _FRAME[0]


_FRAME: list[np.ndarray] = []


def cuda_visible(monkeypatch: pytest.MonkeyPatch, visible: bool) -> None:
    monkeypatch.setattr(ort, "get_available_providers",
                        lambda: WITH_CUDA if visible else CPU_ONLY)


def test_auto_takes_cuda_when_onnxruntime_offers_it(monkeypatch: pytest.MonkeyPatch) -> None:
    cuda_visible(monkeypatch, True)
    assert _ort.providers("auto") == ["CUDAExecutionProvider", "CPUExecutionProvider"]
    assert _ort.providers("cuda") == ["CUDAExecutionProvider", "CPUExecutionProvider"]
    assert _ort.providers("cpu") == ["CPUExecutionProvider"]


def test_auto_is_the_cpu_without_cuda_and_cuda_is_one_line(
        monkeypatch: pytest.MonkeyPatch) -> None:
    cuda_visible(monkeypatch, False)
    assert _ort.providers("auto") == ["CPUExecutionProvider"]
    with pytest.raises(ValueError, match=r"^device: 'cuda' needs .*onnxruntime-gpu") as info:
        _ort.providers("cuda")
    assert "\n" not in str(info.value)
    for bad in ("gpu", "CUDA", None, 0):
        with pytest.raises(ValueError, match=r"^device: must be 'auto', 'cpu' or 'cuda'"):
            _ort.providers(bad)  # type: ignore[arg-type]


def test_the_sessions_get_the_chosen_providers(monkeypatch: pytest.MonkeyPatch,
                                               recorded: list[list[str]]) -> None:
    from tacswitch.motion.infer import load_model as motion_model
    from tacswitch.tacdiff.infer import load_model as tacdiff_model

    cuda_visible(monkeypatch, True)
    tacdiff_model("fast")
    motion_model(None, "cpu")
    assert recorded == [WITH_CUDA, ["CPUExecutionProvider"]]
    # One session per file and device: asking again makes none, another device one more.
    tacdiff_model("fast")
    tacdiff_model("fast", "cpu")
    assert recorded == [WITH_CUDA, ["CPUExecutionProvider"], ["CPUExecutionProvider"]]
    cuda_visible(monkeypatch, False)
    recorded.clear()
    motion_model("single", "auto")
    assert recorded == [["CPUExecutionProvider"]]


def test_the_slip_scorer_stays_on_the_cpu(monkeypatch: pytest.MonkeyPatch,
                                          recorded: list[list[str]]) -> None:
    from tacswitch.grasp.detector import load_scorer

    cuda_visible(monkeypatch, True)
    load_scorer()
    assert recorded == [["CPUExecutionProvider"]]


def test_entry_points_pass_the_device_down(monkeypatch: pytest.MonkeyPatch,
                                           recorded: list[list[str]]) -> None:
    frame = FRAME()
    cuda_visible(monkeypatch, True)
    ts.remove_markers(frame, method="tacdiff", model="fast", orientations=1, device="cpu")
    ts.predict_motion(frame, method="model", device="cuda")
    assert recorded == [["CPUExecutionProvider"], WITH_CUDA]
    cuda_visible(monkeypatch, False)
    with pytest.raises(ValueError, match=r"^device: 'cuda'"):
        ts.remove_markers(frame, method="hybrid", model="fast", device="cuda")
    with pytest.raises(ValueError, match=r"^device: 'cuda'"):
        ts.predict_motion(frame, device="cuda")
    with pytest.raises(ValueError, match=r"^device: must be"):
        ts.remove_markers(frame, method="telea", device="gpu")


def test_cpu_results_are_identical_whatever_the_device_argument() -> None:
    """On a machine without CUDA, ``auto`` is the same CPU session as before ``device``
    existed (``CPUExecutionProvider`` alone), so the outputs are bit-identical."""
    from tacswitch.tacdiff.infer import load_model

    if "CUDAExecutionProvider" in ort.get_available_providers():
        pytest.skip("onnxruntime offers CUDA here: auto runs on the GPU")
    assert load_model("fast", "auto").session.get_providers() == ["CPUExecutionProvider"]
    frame = FRAME()
    outs = [ts.remove_markers(frame, method="tacdiff", model="fast", orientations=1, **kw)
            for kw in ({}, {"device": "auto"}, {"device": "cpu"})]
    assert np.array_equal(outs[0], outs[1]) and np.array_equal(outs[0], outs[2])
    motions = [ts.predict_motion(frame, method="model", **kw)
               for kw in ({}, {"device": "cpu"})]
    assert np.array_equal(motions[0], motions[1])


@pytest.mark.parametrize("argv", [
    ["remove-markers", "IMG", "-o", "OUT", "--method", "tacdiff", "--device", "cuda"],
    ["motion", "IMG", "-o", "OUT", "--device", "cuda"],
    ["slip", "IMG", "--markerless", "--device", "cuda"],
])
def test_cli_device_cuda_without_cuda_is_a_usage_error(
        argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    cuda_visible(monkeypatch, False)
    img = tmp_path / "f.png"
    cv2.imwrite(str(img), FRAME())
    argv = [str(img) if a == "IMG" else str(tmp_path / "o") if a == "OUT" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--device: 'cuda' needs" in err, err


def test_cli_device_ignored_by_the_method_is_said(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    img = tmp_path / "f.png"
    cv2.imwrite(str(img), FRAME())
    assert main(["remove-markers", str(img), "-o", str(tmp_path / "o"), "--device", "cpu",
                 "-q"]) == 0
    assert "--device is ignored by --method telea" in capsys.readouterr().err
    assert main(["slip", str(img), "--device", "cpu"]) == 2
    assert "--device: applies to --markerless only" in capsys.readouterr().err
