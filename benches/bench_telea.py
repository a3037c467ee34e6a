"""TELEA inpainting vs cv2.inpaint(INPAINT_TELEA), one thread, 640x480 BGR.

Speed: median [IQR] per frame of 48 / 63 / 100 markers at radius 3 and 5 (the budget's radii)
and 12 (``remove_markers``' default), both timed in alternating rounds of the same run (warm-up,
GC off). Quality: mean absolute error over the
masked pixels against the true pixels, for ours and OpenCV's, on

- synthetic frames: a GelSight-like shaded gel plus a fine texture, dark soft discs painted on;
- real markerless GelSight frames (the 48 ball presses of Taxim's calibration pack, from the
  installed ``taxim`` package or a downloaded wheel), dark soft discs painted on, so the pixels
  under the markers are known.

The mask is every pixel the painted disc touches, dilated once by a 3x3 ellipse (the paper's
preprocessing).

    python benches/bench_telea.py [--quick] [--radii 3,5,12] [--taxim /tmp/taxim] [--update-md]
"""

from __future__ import annotations

import argparse
import glob
import io
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from harness import interleaved, machine, publish, single_thread

from tacswitch import sim
from tacswitch.inpaint import inpaint_telea

# (markers, rows, cols, pitch px, diameter px): the paper's GelSight grid and two denser ones.
LAYOUTS = [(48, 6, 8, 80.0, 23.0), (63, 7, 9, 66.0, 20.0), (100, 10, 10, 46.0, 16.0)]
RADII = (3, 5, 12)
DARKNESS = 0.85
ELLIPSE3 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
COMMAND = "python benches/bench_telea.py --update-md"


def synthetic_frames(n: int) -> list[np.ndarray]:
    """Shaded gel + blurred texture, uint8 BGR, no markers."""
    out = []
    for seed in range(n):
        rng = np.random.default_rng(seed)
        bg = sim.gel_background(480, 640, seed=seed)
        tex = cv2.GaussianBlur(rng.normal(0, 10, (480, 640, 3)).astype(np.float32), (0, 0), 1.5)
        out.append(np.clip(np.rint(bg + tex), 0, 255).astype(np.uint8))
    return out


def real_frames(taxim: Path, n: int) -> list[np.ndarray]:
    """Markerless GelSight frames from Taxim's calibration pack: the installed ``taxim`` package
    (the ``test`` extra), else a wheel in ``taxim``; none when neither is there."""
    wheels = sorted(glob.glob(str(taxim / "taxim-*.whl")))
    if wheels:
        with zipfile.ZipFile(wheels[0]) as z:
            imgs = np.load(io.BytesIO(z.read("taxim/calib/gelsight/dataPack.npz")))["imgs"]
    else:
        try:
            import taxim as pkg
        except ImportError:
            return []
        imgs = np.load(Path(pkg.__file__).parent / "calib" / "gelsight" / "dataPack.npz")["imgs"]
    step = max(1, len(imgs) // n)
    return [np.ascontiguousarray(imgs[i]) for i in range(0, len(imgs), step)][:n]


def paint(frame: np.ndarray, rows: int, cols: int, pitch: float, diameter: float, seed: int):
    """Dark soft discs on ``frame``; returns (painted frame, dilated mask)."""
    centres = sim.marker_grid(480, 640, rows, cols, pitch, jitter=1.5, seed=seed)
    painted = sim.render_markers(frame.astype(np.float32), centres, diameter, darkness=DARKNESS)
    white = np.full((480, 640), 255.0, np.float32)
    touched = sim.render_markers(white, centres, diameter, darkness=DARKNESS) < 255
    mask = cv2.dilate(touched.astype(np.uint8), ELLIPSE3)
    return painted, mask


def mae(out: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    sel = mask.astype(bool)
    return float(np.abs(out.astype(np.float64) - truth)[sel].mean())


def run(name: str, frames: list[np.ndarray], rounds: int, repeat: int,
        radii: tuple[int, ...] = RADII) -> list[list[str]]:
    rows = []
    for n_markers, nr, nc, pitch, diam in LAYOUTS:
        painted = [paint(f, nr, nc, pitch, diam, seed=i) for i, f in enumerate(frames)]
        for radius in radii:
            img, mask = painted[0]
            t = interleaved(
                {
                    "cv2": lambda img=img, mask=mask, r=radius: cv2.inpaint(
                        img, mask, r, cv2.INPAINT_TELEA
                    ),
                    "ours": lambda img=img, mask=mask, r=radius: inpaint_telea(img, mask, r),
                },
                rounds=rounds,
                repeat=repeat,
            )
            e_cv = np.mean(
                [
                    mae(cv2.inpaint(p, m, radius, cv2.INPAINT_TELEA), f, m)
                    for (p, m), f in zip(painted, frames, strict=True)
                ]
            )
            e_us = np.mean(
                [
                    mae(inpaint_telea(p, m, radius), f, m)
                    for (p, m), f in zip(painted, frames, strict=True)
                ]
            )
            rows.append(
                [
                    name,
                    str(n_markers),
                    str(radius),
                    f"{int(mask.astype(bool).sum())}",
                    t["cv2"].fmt(),
                    t["ours"].fmt(),
                    f"**{t['cv2'].median / t['ours'].median:.1f}x**",
                    f"{e_cv:.3f}",
                    f"{e_us:.3f}",
                ]
            )
            print(" | ".join(rows[-1]), file=sys.stderr)
    return rows


def parse_args() -> argparse.Namespace:
    """The options of the inpainting benchmarks: --quick, --taxim, --update-md."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer frames and samples")
    ap.add_argument("--taxim", type=Path, default=Path("/tmp/taxim"),
                    help="folder with a taxim wheel (default: the installed taxim package)")
    ap.add_argument("--radii", default=",".join(map(str, RADII)),
                    help="TELEA radii, px (default: 3,5,12)")
    ap.add_argument("--update-md", action="store_true", help="write the table into BENCHMARKS.md")
    return ap.parse_args()


def synthetic_and_real(run_fn: Callable[[str, list[np.ndarray], int, int], list[list[str]]],
                       args: argparse.Namespace, quick: tuple[int, int, int],
                       full: tuple[int, int, int]) -> list[list[str]]:
    """``run_fn`` on the synthetic frames, then on the real Taxim frames when the wheel is
    there; ``quick``/``full`` are (rounds, repeat, frames). Pins everything to one thread."""
    single_thread()
    rounds, repeat, n_frames = quick if args.quick else full
    rows = run_fn("synthetic", synthetic_frames(n_frames), rounds, repeat)
    real = real_frames(args.taxim, 2 * n_frames)
    if real:
        rows += run_fn(f"real GelSight ({len(real)} frames)", real, rounds, repeat)
    else:
        print(f"(no Taxim wheel under {args.taxim}: real frames skipped)", file=sys.stderr)
    return rows


def main() -> int:
    args = parse_args()
    radii = tuple(int(r) for r in args.radii.split(","))
    rows = synthetic_and_real(lambda *a: run(*a, radii=radii), args, (3, 3, 2), (6, 5, 6))
    header = [
        "frames",
        "markers",
        "radius",
        "masked px",
        "cv2.inpaint TELEA",
        "tacswitch",
        "speed-up",
        "MAE cv2",
        "MAE ours",
    ]
    publish("## TELEA inpainting", [
        f"Machine: {machine()}. One thread (`RAYON_NUM_THREADS=1`, `cv2.setNumThreads(1)`).",
        "Times: median [IQR] per 640x480 BGR frame, both in alternating rounds of one run.",
        "MAE: mean |inpainted - true| over the masked pixels and channels (grey levels),",
        "averaged over the frames; markers are dark soft discs painted on known pixels,",
        "mask = painted pixels dilated once by a 3x3 ellipse.",
    ], header, rows, COMMAND + ("" if args.radii == "3,5,12" else f" --radii {args.radii}")
       + (" --quick" if args.quick else ""), args.update_md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
