"""Motion regression speed on this CPU with onnxruntime: shipped default vs the paper's reference.

    python benches/bench_motion.py [--onnx-dir DIR] [--threads N]

Times the shipped model end to end (``MotionModel.__call__``: validation, downsampling to the
working scale, session run) at 320x240 and 640x480, with a reference frame and single-frame (the
consistent design runs both terms of its graph, a batch of two, either way), and the raw session
of each architecture at full input size (the reference DeepLabV3-MobileNetV3 and LR-ASPP are
exported on the fly when torch is installed; speed does not depend on the weights). Threads:
``--threads`` (default ``os.cpu_count()``, the session default), no spinning.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, measure, table

from tacswitch.motion.infer import MotionModel, default_model_path, session_options

SIZES = ((240, 320), (480, 640))
BUDGET_HZ = {(240, 320): 100.0, (480, 640): 30.0}


def _export_arch(arch: str, out: Path) -> Path | None:
    try:
        import torch

        from tacswitch.motion.export import export_onnx
        from tacswitch.motion.model import MotionNet
    except ImportError:
        return None
    torch.manual_seed(0)
    return export_onnx(MotionNet(arch), out / f"{arch}.onnx",
                       metadata={"work_width": 100000, "work_height": 100000})


def _params(path: Path) -> int:
    import onnx

    m = onnx.load(str(path))
    return int(sum(np.prod(t.dims) for t in m.graph.initializer))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--onnx-dir", default=None, help="reuse exported <arch>.onnx files here")
    ap.add_argument("--threads", type=int, default=None, help="intra-op threads")
    ap.add_argument("--device", choices=("auto", "cpu", "cuda"), default="cpu",
                    help="onnxruntime device (default cpu, the budget's; benches/"
                         "bench_device.py has a row per device)")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    rows = []
    from tacswitch._ort import providers

    default = MotionModel(default_model_path(), threads=args.threads, device=args.device)
    for h, w in SIZES:
        img = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
        ref = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
        cen = default.centres_for(h, w)
        modes = [("with reference", ref)]
        if not default.use_ref:
            modes.append(("single frame", None))
        for mode, r in modes:
            t = measure(lambda img=img, r=r, cen=cen: default(img, r, cen), repeat=100,
                        warmup=10)
            hz = 1.0 / t.median
            rows.append([f"default ({default.arch}, {default.design}, {mode})", f"{w}x{h}",
                         f"{_params(default.path) / 1e6:.2f}", t.fmt("ms"), f"{hz:.0f}",
                         "yes" if hz >= BUDGET_HZ[(h, w)] else "NO"])
    import onnxruntime as ort

    tmp = Path(args.onnx_dir or tempfile.mkdtemp())
    archs = [("unet", default.path, "no downsampling")]
    for arch in ("lraspp", "deeplabv3"):
        p = tmp / f"{arch}.onnx"
        if not p.is_file():
            p = _export_arch(arch, tmp)  # type: ignore[assignment]
        if p is not None:
            archs.append((arch, p, "paper's reference" if arch == "deeplabv3" else "LR-ASPP"))
    for arch, path, note in archs:
        sess = ort.InferenceSession(str(path), session_options(args.threads),
                                    providers=providers(args.device))
        for h, w in SIZES:
            feed = {"image": rng.integers(0, 255, (1, h, w, 3), dtype=np.uint8),
                    "centres": (rng.random((99, 2)) * [w - 1, h - 1]).astype(np.float32)}
            names = {i.name for i in sess.get_inputs()}
            if "reference" in names:
                feed["reference"] = feed["image"][:, ::-1].copy()
            if "has_reference" in names:
                feed["has_reference"] = np.ones(1, np.float32)
            t = measure(lambda feed=feed, s=sess: s.run(None, feed), repeat=30, warmup=3)
            hz = 1.0 / t.median
            rows.append([f"{arch} at full size ({note})", f"{w}x{h}",
                         f"{_params(path) / 1e6:.2f}", t.fmt("ms"), f"{hz:.0f}",
                         "yes" if hz >= BUDGET_HZ[(h, w)] else "NO"])
    print(machine())
    print(table(["model", "frame", "M params", "time per frame (median [IQR])", "Hz",
                 "meets budget"], rows))


if __name__ == "__main__":
    main()
