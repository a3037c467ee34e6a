"""``--ray ADDRESS``: a batch command's files as Ray tasks, on a local Ray instance or a cluster.

The driver (the ``tacswitch`` process) reads every input file and sends its bytes to a task; the
task runs **the single-machine code** (:mod:`tacswitch.cli.remove_markers`' own per-file
functions, one thread) on a private temporary folder and returns the bytes it wrote; the driver
writes them under ``--out``. So the workers need no shared file system, the driver stays the
only writer (atomic writes, the resume record ``OUT/.tacswitch-COMMAND.json``), an interrupted
run resumes file by file, and every output is byte for byte the single-machine run's.

``ADDRESS``: ``local`` starts a Ray instance on this machine (``--workers`` CPUs, default all
cores) and stops it at the end; ``auto`` joins the cluster this machine belongs to (``ray
start`` was run here); ``ray://HOST:10001`` connects a Ray Client to a remote cluster's head.
Every node needs the same tacswitch installed (``pip install "tacswitch[cluster]"``).
Needs the ``cluster`` extra (Ray).
"""

from __future__ import annotations

import argparse
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tacswitch.cli.options import UsageError

#: Object-store memory (bytes) of a ``local`` instance: the inputs and outputs in flight only.
LOCAL_OBJECT_STORE_BYTES = 256 * 1024**2
#: Tasks in flight per CPU of the cluster (keeps the workers busy while the driver writes,
#: and bounds the driver's memory on folders of thousands of files).
IN_FLIGHT_PER_CPU = 2


def add_ray_option(p: argparse.ArgumentParser) -> None:
    """The ``--ray ADDRESS`` option of a batch command."""
    p.add_argument("--ray", default=None, metavar="ADDRESS",
                   help="run the files as Ray tasks: 'local' (a Ray instance on this machine, "
                        "--workers CPUs), 'auto' (the cluster this machine joined with `ray "
                        "start`) or ray://HOST:10001 (a remote cluster's head); outputs are "
                        "identical to a run without --ray and an interrupted run resumes per "
                        "file (needs: pip install 'tacswitch[cluster]')")


@contextmanager
def connected(address: str, workers: int | None) -> Iterator[Any]:
    """The ``ray`` module, connected to ``address`` (module doc) for the ``with`` block; a
    ``local`` instance is shut down on leaving it. One-line :class:`UsageError` naming
    ``--ray`` when Ray is missing or the address does not answer."""
    try:
        import ray
    except ImportError:
        raise UsageError("--ray: needs Ray; install it with: pip install 'tacswitch[cluster]'"
                         ) from None
    if not isinstance(address, str) or not address.strip():
        raise UsageError(f"--ray: an address ('local', 'auto' or ray://HOST:PORT); got "
                         f"{address!r}")
    started = False
    if not ray.is_initialized():
        opts: dict[str, Any] = {"log_to_driver": False, "configure_logging": False}
        try:
            if address == "local":
                ray.init(num_cpus=workers or os.cpu_count() or 1, include_dashboard=False,
                         object_store_memory=LOCAL_OBJECT_STORE_BYTES, **opts)
            else:
                ray.init(address=address, **opts)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise UsageError(f"--ray: cannot connect to {address!r}: {first}") from None
        started = True
    try:
        yield ray
    finally:
        if started:
            ray.shutdown()


@dataclass(frozen=True)
class FileResult:
    """What a task made of one input: ``outputs`` (path relative to the task's output folder
    -> bytes), the unreadable frames it skipped, or the reason the input was unreadable."""

    outputs: dict[str, bytes]
    bad_frames: int = 0
    unreadable: str | None = None


def written_files(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` but the resume records, by relative POSIX path."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not p.name.startswith(".tacswitch-")}


def run_in_scratch(name: str, data: bytes, work: Callable[[Path, Path], FileResult]
                   ) -> FileResult:
    """``work(input_path, output_folder)`` on a private temporary folder holding ``data`` as
    ``name``; the files it wrote are returned (the task side of :func:`map_files`)."""
    with tempfile.TemporaryDirectory(prefix="tacswitch-ray-") as tmp:
        src = Path(tmp) / "in" / name
        src.parent.mkdir()
        src.write_bytes(data)
        out = Path(tmp) / "out"
        out.mkdir()
        result = work(src, out)
        if result.unreadable is not None:
            return result
        return FileResult(written_files(out), result.bad_frames)


def write_outputs(out: Path, outputs: dict[str, bytes]) -> None:
    """Writes a task's files under ``out``, each atomically."""
    from tacswitch._io import atomic_open

    for rel, data in outputs.items():
        target = out / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_open(target, "wb") as fh:
            fh.write(data)


def map_files(ray: Any, task: Callable[..., FileResult], jobs: list[tuple[Path, Any]],
              on_result: Callable[[Path, FileResult], None],
              on_unreadable: Callable[[Path, str], None]) -> None:
    """Runs ``task(name, data, extra)`` as a Ray task for every ``(path, extra)`` of ``jobs``
    (``data``: the file's bytes, read here), at most :data:`IN_FLIGHT_PER_CPU` per cluster
    CPU at a time, and hands each result to ``on_result`` as it arrives (completion order);
    a file that cannot be read here goes to ``on_unreadable``."""
    remote = ray.remote(num_cpus=1, max_retries=2)(task)
    limit = max(1, IN_FLIGHT_PER_CPU * int(ray.cluster_resources().get("CPU", 1)))
    pending: dict[Any, Path] = {}

    def drain(until: int) -> None:
        while len(pending) > until:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                on_result(pending.pop(ref), ray.get(ref))

    for path, extra in jobs:
        try:
            data = path.read_bytes()
        except OSError as exc:
            on_unreadable(path, f"inputs: cannot read {str(path)!r} ({exc.strerror or exc})")
            continue
        pending[remote.remote(path.name, data, extra)] = path
        drain(limit - 1)
    drain(0)
