"""Two builds of the native module, timed in alternating rounds in one process: the tracker's
frame update (extraction + matching, ``_native.Tracker.update_image``) on rendered grasps at
640x480 and 320x240, and on 90 frames of a REAL GelSight Mini grasp video (320x240) when the
data folder is there (``--video``), one thread. For before/after records of a change to the
native core: build each commit (``maturin develop --release``), copy its
``python/tacswitch/_native.abi3.so`` aside, then

    python benches/bench_native_builds.py before=PATH after=PATH [--rounds 15]

Every build sees the same frames, in turn within each round, so a busy machine slows both
alike; the table gives medians over rounds (CPU time of this thread and wall-clock) and each
build's ratio to the first. Extraction outputs are compared too: a speed change should leave
them bit-identical, and the table says whether it did.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path
from types import ModuleType

import numpy as np
from harness import machine, single_thread, table

from tacswitch import extract_markers, sim
from tacswitch.grasp.dataset import read_video

DEFAULT_VIDEO = (Path(__file__).resolve().parents[2]
                 / "shared/data/real/gsmini_slip_train/avocado_real/exp_num_5/camera_0.avi")


def load_build(name: str, path: Path) -> ModuleType:
    """Imports the extension at ``path`` as ``NAME._native`` (its init symbol is the last part)."""
    spec = importlib.util.spec_from_file_location(f"{name}._native", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"builds: cannot load {path}")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def parse_builds(specs: list[str]) -> dict[str, Path]:
    builds: dict[str, Path] = {}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep or not name.isidentifier() or not Path(path).is_file():
            raise SystemExit(f"builds: expected NAME=PATH of an existing .so; got {spec!r}")
        builds[name] = Path(path)
    if len(builds) < 2:
        raise SystemExit("builds: give at least two NAME=PATH")
    return builds


def rates(mod: ModuleType, ref: np.ndarray, frames: list[np.ndarray],
          passes: int) -> tuple[float, float]:
    """Frames/s (thread CPU time, wall-clock) of ``passes`` passes of a fresh tracker."""
    tr = mod.Tracker(ref)
    for f in frames[:3]:
        tr.update_image(f)
    tr.reset()
    c0, w0 = time.thread_time(), time.perf_counter()
    for _ in range(passes):
        for f in frames:
            tr.update_image(f)
    n = passes * len(frames)
    return n / (time.thread_time() - c0), n / (time.perf_counter() - w0)


def outputs(mod: ModuleType, frames: list[np.ndarray]) -> list[bytes]:
    """Every field of the native extraction, with and without the adaptive mask, as bytes."""
    res = []
    for f in frames:
        for adaptive in (False, True):
            out = mod.extract_markers(f, adaptive=adaptive)
            res.append(b"".join(np.asarray(out[k]).tobytes() for k in sorted(out)))
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("builds", nargs="+", help="NAME=PATH of a built _native.abi3.so (two or more)")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--passes", type=int, default=3, help="passes over the frames per round")
    ap.add_argument("--video", type=Path, default=DEFAULT_VIDEO,
                    help="a real marker video for the real row (skipped when missing)")
    args = ap.parse_args()
    single_thread()
    mods = {k: load_build(k, p) for k, p in parse_builds(args.builds).items()}
    print(machine())
    rows = []
    sets: list[tuple[str, np.ndarray, list[np.ndarray]]] = []
    for preset in ("gelsight", "gelsight_mini"):
        seq = sim.grasp_sequence(preset, "slip", n_frames=60, seed=0)
        sets.append((f"rendered {preset}", seq.reference,
                     [np.ascontiguousarray(f) for f in seq.frames[30:60]]))
    if args.video.is_file():
        video = [f for _, f in zip(range(90), read_video(args.video), strict=False)]
        sets.append(("REAL GelSight Mini video", video[0], video))
    for name, ref_frame, frames in sets:
        ref = extract_markers(ref_frame).centres
        got: dict[str, list[tuple[float, float]]] = {k: [] for k in mods}
        for _ in range(args.rounds):
            for k, m in mods.items():
                got[k].append(rates(m, ref, frames, args.passes))
        first = next(iter(mods))
        base = float(np.median([c for c, _ in got[first]]))
        same = {k: outputs(m, frames) == outputs(mods[first], frames) for k, m in mods.items()}
        h, w = frames[0].shape[:2]
        for k, r in got.items():
            cpu = float(np.median([c for c, _ in r]))
            wall = float(np.median([wl for _, wl in r]))
            rows.append([f"{name} {w}x{h}", k, f"{cpu:.0f}", f"{wall:.0f}",
                         f"**{cpu / base:.2f}x**", "yes" if same[k] else "**no**"])
    print(table(["frames", "build", "frames/s (CPU)", "frames/s (wall)",
                 "vs first (CPU)", "outputs identical to first"], rows))
    print(f"\nCommand: `python benches/bench_native_builds.py {' '.join(sys.argv[1:])}`")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
