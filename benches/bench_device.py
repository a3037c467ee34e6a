"""TacDiff and the motion models per onnxruntime execution provider: one row per device.

    python benches/bench_device.py [--device all|cpu|cuda] [--rounds 5] [--threads N]

``--device all`` (default) times every device onnxruntime offers here: the CPU, and CUDA when
``onnxruntime-gpu`` sees a GPU (``tacswitch._ort.providers``). Frames: a simulated GelSight
Mini press at 320x240 and a GelSight one at 640x480, with their own marker masks (the motion
models get the markerless image); TacDiff rows run ``inpaint_tacdiff`` (prior + network,
``patch="auto"``), motion rows ``MotionModel.__call__`` on the shipped models.
Median ms per frame over ``--rounds`` after one warm-up call (session creation, CUDA kernels'
first launch). The GPU rows include the host <-> device copies of every call, as a user's run
does.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, table


def _median_ms(fn: Callable[[], object], rounds: int) -> float:
    fn()  # warm-up
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def _frames() -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``(label, BGR frame with markers, dilated marker mask)`` per frame size."""
    from tacswitch.markers import dilate_mask
    from tacswitch.sim.scene import render_sample

    out = []
    for preset, seed in (("gelsight_mini", 11), ("gelsight", 11)):
        s = render_sample(preset, seed)
        h, w = s.image_markers.shape[:2]
        out.append((f"{w}x{h}", s.image_markers, dilate_mask(s.marker_mask)))
    return out


def _clean() -> list[np.ndarray]:
    """The markerless images of :func:`_frames`' scenes."""
    from tacswitch.sim.scene import render_sample

    return [render_sample(p, 11).image for p in ("gelsight_mini", "gelsight")]


def main() -> None:
    import onnxruntime as ort

    from tacswitch._ort import providers
    from tacswitch.motion.infer import MotionModel
    from tacswitch.tacdiff.infer import TacDiffModel, inpaint_tacdiff

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", choices=("all", "cpu", "cuda"), default="all")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None, help="CPU intra-op threads")
    args = ap.parse_args()
    has_cuda = "CUDAExecutionProvider" in ort.get_available_providers()
    devices = (["cpu", "cuda"] if has_cuda else ["cpu"]) if args.device == "all" else [args.device]
    for d in devices:
        providers(d)  # "cuda" without CUDA: the library's one-line error
    rows = []
    frames = _frames()
    clean = _clean()
    for device in devices:
        for name in ("default", "fast"):
            net = TacDiffModel(name, threads=args.threads, device=device)
            for label, img, mask in frames:
                ms = _median_ms(lambda img=img, mask=mask, net=net, d=device: inpaint_tacdiff(
                    img, mask, 1, model=net.path, device=d), args.rounds)
                rows.append([device, ", ".join(net.session.get_providers()),
                             f"TacDiff {name} K=1", label, f"{ms:.1f}"])
        for name in ("default", "single"):
            model = MotionModel(None if name == "default" else name, threads=args.threads,
                                device=device)
            for label, _, _ in frames:
                img = {f[0]: s for f, s in zip(frames, clean, strict=True)}[label]
                ref = None if model.design == "single" else img[:, ::-1].copy()
                ms = _median_ms(lambda img=img, ref=ref, m=model: m(img, ref), args.rounds)
                rows.append([device, ", ".join(model.session.get_providers()),
                             f"motion {name} ({model.arch})", label, f"{ms:.1f}"])
    print(table(["device", "session providers", "model", "frame", "ms per frame (median)"],
                rows))
    print(f"\nMachine: {machine()}; onnxruntime {ort.__version__} "
          f"({', '.join(ort.get_available_providers())}).")


if __name__ == "__main__":
    main()
