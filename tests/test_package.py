"""Packaging: the stub matches the extension, the code is lint-clean, the import stays light."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import tacswitch

ROOT = Path(__file__).resolve().parents[1]


def test_stub_matches_native_module() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "tacswitch._native"],
        capture_output=True, text=True, cwd=ROOT / "tests",
    )
    assert out.returncode == 0, out.stdout + out.stderr


def test_stub_and_typed_marker_ship_with_the_package() -> None:
    pkg = Path(tacswitch.__file__).parent
    assert (pkg / "_native.pyi").is_file()
    assert (pkg / "py.typed").is_file()


def test_import_does_not_load_heavy_modules() -> None:
    code = (
        "import sys, tacswitch, tacswitch.sim;"
        "heavy = [m for m in ('cv2', 'onnxruntime', 'torch', 'scipy') if m in sys.modules];"
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


RUFF = shutil.which("ruff") or str(Path(sys.executable).parent / "ruff")


@pytest.mark.skipif(not Path(RUFF).exists(), reason="ruff not installed")
def test_ruff_clean() -> None:
    ruff = RUFF
    out = subprocess.run([ruff, "check", "python", "tests", "benches"], capture_output=True,
                         text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr


def test_version_is_exposed() -> None:
    assert tacswitch.__version__.count(".") == 2


def test_mypy_clean() -> None:
    pytest.importorskip("mypy")
    out = subprocess.run([sys.executable, "-m", "mypy", "python/tacswitch"], capture_output=True,
                         text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
