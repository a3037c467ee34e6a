"""``.ci/run`` runs the README's test command in a throw-away environment and removes it."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README_TEST = 'pip install ".[test,train]" && python -m pytest'


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    script = (ROOT / ".ci" / "run").read_text()
    assert README_TEST in (ROOT / "README.md").read_text()
    assert [line for line in script.splitlines() if line.strip() == README_TEST] == [README_TEST]
    assert "trap " in script


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
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", TMPDIR=str(tmp))
    run = subprocess.run(["bash", str(ROOT / ".ci" / "run")], env=env, capture_output=True,
                         text=True, timeout=60)
    assert (run.returncode == 0) == tests_pass, run.stderr
    calls = log.read_text().splitlines()
    assert 'pip install .[test,train]' in calls and "python -m pytest" in calls
    assert any(c.startswith("cargo clippy") for c in calls) == tests_pass
    assert list(tmp.iterdir()) == []  # the environment is gone
