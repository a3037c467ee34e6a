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


def test_licence_and_notices_ship_and_name_every_shipped_data_file() -> None:
    """Every model and calibration table in the package is made from others' data (Taxim's
    tables, the slip study's videos): THIRD_PARTY_NOTICES.md, which the wheel carries beside
    LICENSE, must name each one, so a new model cannot ship without its notice."""
    import fnmatch
    import re

    project = (ROOT / "pyproject.toml").read_text()
    assert re.search(r'^license = "MIT"$', project, re.M)
    assert re.search(r'^license-files = \["LICENSE", "THIRD_PARTY_NOTICES.md"\]$', project, re.M)
    assert "MIT License" in (ROOT / "LICENSE").read_text()
    notices = (ROOT / "THIRD_PARTY_NOTICES.md").read_text()
    named = {Path(tok).name for tok in re.findall(r"`([^`\s]+)`", notices)}
    pkg = ROOT / "python" / "tacswitch"
    shipped = [*pkg.glob("models/*.onnx"), *pkg.glob("models/*.safetensors"),
               *pkg.glob("sim/calib/*.npz")]
    assert len(shipped) >= 9
    missing = [p.name for p in shipped if not any(fnmatch.fnmatch(p.name, n) for n in named)]
    assert not missing, f"THIRD_PARTY_NOTICES.md does not name {missing}"
