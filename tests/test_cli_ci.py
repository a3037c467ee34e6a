"""``.ci/run`` runs the README's test command (no torch) in a throw-away environment, then the
training tests with the train extra, then the strict documentation build, then the Rust checks,
and removes the environment."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README_TEST = 'pip install ".[test]" && python -m pytest'


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    script = (ROOT / ".ci" / "run").read_text()
    assert README_TEST in (ROOT / "README.md").read_text()
    assert [line for line in script.splitlines() if line.strip() == README_TEST] == [README_TEST]
    assert "trap " in script


def test_readme_test_command_installs_no_torch() -> None:
    # The train extra (torch: GBs of CUDA wheels) stays out of the README's test command.
    readme = (ROOT / "README.md").read_text()
    commands = [line for line in readme.splitlines() if "&& python -m pytest" in line]
    assert commands and not any("train" in c for c in commands), commands


def test_demo_output_is_ignored_by_git() -> None:
    lines = (ROOT / ".gitignore").read_text().splitlines()
    assert "tacswitch-demo/" in lines


def _stub(path: Path, body: str) -> None:
    path.write_text("#!/usr/bin/env bash\n" + body)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)


@pytest.mark.parametrize("tests_pass", [True, False])
def test_ci_removes_its_environment(tmp_path: Path, tests_pass: bool) -> None:
    """The real script with stand-ins for python3, pip and cargo: the environment it makes
    under TMPDIR is gone afterwards, whether the tests pass or fail."""
    if shutil.which("bash") is None:
        pytest.skip("needs bash")
    bin_dir, tmp, log = tmp_path / "bin", tmp_path / "tmp", tmp_path / "log"
    bin_dir.mkdir()
    tmp.mkdir()
    # python3 -m venv DIR: an "environment" whose activate puts the stand-ins first.
    _stub(bin_dir / "python3", f"""
if [ "$1 $2" = "-m venv" ]; then
  mkdir -p "$3/bin" && echo 'export PATH="{bin_dir}:$PATH"' > "$3/bin/activate"
  head -c 100000 /dev/zero > "$3/bin/payload"
fi
""")
    _stub(bin_dir / "python", f'echo "python $*" >> "{log}"\n'
          f'[ "$*" = "-m pytest" ] && exit {0 if tests_pass else 1}\nexit 0\n')
    _stub(bin_dir / "pip", f'echo "pip $*" >> "{log}"\n')
    _stub(bin_dir / "cargo", f'echo "cargo $*" >> "{log}"\n')
    _stub(bin_dir / "mkdocs", f'echo "mkdocs $*" >> "{log}"\n')
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", TMPDIR=str(tmp))
    run = subprocess.run(["bash", str(ROOT / ".ci" / "run")], env=env, capture_output=True,
                         text=True, timeout=60)
    assert (run.returncode == 0) == tests_pass, run.stderr
    calls = [c for c in log.read_text().splitlines() if "--upgrade pip" not in c]
    # The train, cluster and docs extras: their package lists read from pyproject.toml
    # (python -c), installed without building the extension again.
    steps = ["pip install .[test]", "python -m pytest", "python -c", "pip install -r",
             "python -m pytest -m train", "python -c", "pip install -r",
             "python -m pytest -m cluster", "python -c", "pip install -r",
             "mkdocs build --strict", "cargo test", "cargo fmt", "cargo clippy"]
    done = [next((s for s in steps if c.startswith(s) and (s != "python -m pytest"
                                                            or c == s)), c) for c in calls]
    assert done == (steps if tests_pass else steps[:2]), calls
    assert list(tmp.iterdir()) == []  # the environment is gone
