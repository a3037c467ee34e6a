"""Shared fixtures: every test generates its own data (no files from outside the repository)."""

from __future__ import annotations

import ast
import functools
import inspect
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest

from tacswitch import sim

#: The bench suite's folder. It goes on the import path once, here, for every test: the
#: evaluation code the tests share with the benches lives there, not in the installed package
#: (``from proxies import motion_proxy``: the real-texture proxies, ``benches/proxies/``; the
#: runner's ``sections``).
BENCHES = Path(__file__).resolve().parents[1] / "benches"
if str(BENCHES) not in sys.path:
    sys.path.insert(0, str(BENCHES))

if TYPE_CHECKING:
    from proxies import motion_proxy as proxy


def disc_image(
    centres: np.ndarray,
    shape: tuple[int, int] = (480, 640),
    diameter: float = 23.0,
    *,
    darkness: float = 0.85,
    edge_px: float = 1.5,
    noise: float = 0.0,
    seed: int = 0,
) -> np.ndarray:
    """BGR frame with soft discs at ``centres`` on a GelSight-like background."""
    bg = sim.gel_background(shape[0], shape[1], seed=seed)
    return sim.render_markers(
        bg, centres, diameter, darkness=darkness, edge_px=edge_px, noise_sigma=noise, seed=seed + 1
    )


def disc_mask(shape: tuple[int, int], centres: list[tuple[float, float]], r: float) -> np.ndarray:
    """``H x W`` bool mask of discs of radius ``r`` px at ``centres`` ``(x, y)``."""
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    m = np.zeros(shape, bool)
    for cx, cy in centres:
        m |= (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
    return m


@pytest.fixture
def gelsight_grid() -> np.ndarray:
    """48 marker centres of the paper's GelSight at sub-pixel offsets."""
    p = sim.get_preset("gelsight")
    pts = sim.marker_grid(p.height, p.width, p.rows, p.cols, p.pitch)
    offsets = np.random.default_rng(3).uniform(-0.5, 0.5, pts.shape).astype(np.float32)
    return pts + offsets


@pytest.fixture(scope="session")
def marker_frames() -> list[np.ndarray]:
    """Two simulated GelSight Mini frames with markers (a sensor's raw frames for fine-tunes)."""
    from tacswitch.sim.scene import render_sample

    return [render_sample("gelsight_mini", 40 + i).image_markers for i in range(2)]


@pytest.fixture
def marker_frame_dir(tmp_path: Path, marker_frames: list[np.ndarray]) -> Path:
    """:func:`marker_frames` as PNG files in a folder (what ``tacswitch finetune`` reads)."""
    import cv2

    src = tmp_path / "frames"
    src.mkdir()
    for i, f in enumerate(marker_frames):
        cv2.imwrite(str(src / f"{i}.png"), f)
    return src


@pytest.fixture(scope="session")
def mini() -> proxy.RealPresses:
    """taxim's real markerless GelSight Mini presses at 320 x 240 (the taxim package)."""
    from proxies import motion_proxy as proxy

    return proxy.load_real_presses("gelsight_mini")


@pytest.fixture(scope="session")
def grid() -> np.ndarray:
    """The GelSight Mini marker grid (rest centres, x, y px) at 320 x 240."""
    from proxies import motion_proxy as proxy

    return proxy.marker_grid("gelsight_mini")[0]


# --- the train marker --------------------------------------------------------------------------
# The README's test command installs no torch: tests that need the train extra skip with the
# importorskip reason there, and `.ci/run` runs them afterwards with `python -m pytest -m train`.
# A test gets the marker when it, a fixture it uses, or its module's top level calls
# pytest.importorskip on one of the extra's modules; a test that needs them another way is marked
# @pytest.mark.train by hand.
TRAIN_MODULES = ("torch", "torchvision", "safetensors", "onnx", "onnxscript")
_TRAIN_SKIP = re.compile(r"importorskip\(\s*[\"'](" + "|".join(TRAIN_MODULES) + r")[\"'.]")


@functools.cache
def _module_needs_train(path: str) -> bool:
    """Whether the test module at ``path`` importorskips a train module at its top level."""
    tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    return any(_TRAIN_SKIP.search(ast.unparse(node)) for node in tree.body
               if isinstance(node, (ast.Expr, ast.Assign)))


@functools.cache
def _source_needs_train(fn: Any) -> bool:
    """Whether the source of the function ``fn`` importorskips a train module."""
    try:
        return bool(_TRAIN_SKIP.search(inspect.getsource(fn)))
    except (OSError, TypeError):
        return False


def pytest_collection_modifyitems(config: Any, items: list[pytest.Item]) -> None:
    for item in items:
        fn = getattr(item, "function", None)
        if fn is None or item.get_closest_marker("train"):
            continue
        info = getattr(item, "_fixtureinfo", None)
        fixtures = [d.func for defs in (info.name2fixturedefs.values() if info else ())
                    for d in defs]
        if (_module_needs_train(str(item.path))
                or any(_source_needs_train(f) for f in [fn, *fixtures])):
            item.add_marker(pytest.mark.train)
