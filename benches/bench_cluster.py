"""``tacswitch remove-markers`` on a folder: one machine against Ray tasks, and how Ray scales
with workers (needs the ``cluster`` extra).

Data: **simulated** GelSight frames with markers (``tacswitch.sim.grasp_sequence``, 640x480
PNG), written once into a scratch folder. Each configuration converts the whole folder into a
fresh output folder, as a user runs it (the CLI in this process, ``-q``); the outputs of every
Ray run are checked byte for byte against the single-machine run's. Ray runs join a local
instance of N CPUs started just before (``--ray auto``, as on a cluster); its start and stop,
paid once per run by ``--ray local``, are reported apart.

    python benches/bench_cluster.py [--frames 96] [--rounds 3] [--method telea]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2

from tacswitch import sim
from tacswitch.cli import main as cli


def digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()
            if not p.name.startswith(".")}


def timed(args: list[str]) -> float:
    t0 = time.perf_counter()
    if cli(args) != 0:
        raise SystemExit(f"failed: {' '.join(args)}")
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=96)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--method", default="telea")
    a = ap.parse_args()
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "in"
        src.mkdir()
        n = 0
        seed = 0
        while n < a.frames:
            g = sim.grasp_sequence("gelsight", "slip", n_frames=24, seed=seed)
            for f in g.frames:
                if n < a.frames:
                    cv2.imwrite(str(src / f"f{n:05d}.png"), f)
                    n += 1
            seed += 1
        configs = [("one machine, --workers 1", ["--workers", "1"]),
                   (f"one machine, --workers {cores}", ["--workers", str(cores)])]
        ray_workers = sorted({1, cores})
        configs += [(f"--ray, local instance of {w} CPU{'s' * (w > 1)}", ["--ray", "auto"])
                    for w in ray_workers]
        times: dict[str, list[float]] = {name: [] for name, _ in configs}
        startup: dict[str, list[float]] = {name: [] for name, _ in configs}
        reference = None
        for r in range(a.rounds):
            for k, (name, opts) in enumerate(configs):
                out = Path(tmp) / f"out-{r}-{k}"
                ray = None
                if "--ray" in opts:
                    import ray

                    t0 = time.perf_counter()
                    ray.init(num_cpus=ray_workers[k - 2], include_dashboard=False,
                             log_to_driver=False)
                    startup[name].append(time.perf_counter() - t0)
                times[name].append(timed(["remove-markers", str(src), "-o", str(out), "-q",
                                          "--method", a.method, *opts]))
                if ray is not None:
                    t0 = time.perf_counter()
                    ray.shutdown()
                    startup[name][-1] += time.perf_counter() - t0
                d = digests(out)
                if reference is None:
                    reference = d
                elif d != reference:
                    raise SystemExit(f"{name}: outputs differ from the single-machine run")
                print(f"round {r + 1}: {name}: {times[name][-1]:.2f} s", file=sys.stderr)
    base = statistics.median(times[configs[0][0]])
    print(f"{a.frames} simulated 640x480 GelSight frames, --method {a.method}, {cores} cores; "
          f"median of {a.rounds} rounds; outputs identical in every run\n")
    print("| run | conversion, s (median) | frames/s | vs one machine, 1 worker | Ray start + "
          "stop, s |")
    print("|---|---|---|---|---|")
    for name, _ in configs:
        t = statistics.median(times[name])
        up = f"{statistics.median(startup[name]):.1f}" if startup[name] else "-"
        print(f"| {name} | {t:.2f} | {a.frames / t:.1f} | {base / t:.2f}x | {up} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
