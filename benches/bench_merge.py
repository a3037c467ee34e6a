"""Patch merging (and tiling) vs the numpy equivalent, one thread, 256x256x3 float32 patches.

Layouts: the paper's 640x480 image in 6 patches (overlap 30) and a 704x704 image in 9 patches
(overlap 32). numpy peers: accumulate ``weight * patch`` and ``weight`` per patch with slicing,
then divide (weight 1 for the plain average, the same raised-cosine weights for feathering);
tiling as a stack of slices.

    python benches/bench_merge.py [--quick] [--update-md]
"""

from __future__ import annotations

import argparse

import numpy as np
from harness import interleaved, machine, publish, single_thread

from tacswitch.inpaint import merge_patches, tile

PATCH = 256
LAYOUTS = [((480, 640, 3), 30), ((704, 704, 3), 32)]
COMMAND = "python benches/bench_merge.py --update-md"


def feather(patch: int, ramp: int) -> np.ndarray:
    """Raised-cosine weights of one side, as the Rust core computes them."""
    t = np.arange(patch, dtype=np.float64)
    rise = np.where(t < ramp, 0.5 - 0.5 * np.cos(np.pi * (t + 0.5) / ramp), 1.0)
    return np.minimum(rise, rise[::-1]).astype(np.float32)


def numpy_merge(
    patches: np.ndarray, origins: np.ndarray, shape: tuple[int, ...], w2d: np.ndarray | None
) -> np.ndarray:
    acc = np.zeros(shape, np.float32)
    wsum = np.zeros((*shape[:2], 1), np.float32)
    for p, (x, y) in zip(patches, origins, strict=True):
        if w2d is None:
            acc[y : y + PATCH, x : x + PATCH] += p
            wsum[y : y + PATCH, x : x + PATCH] += 1.0
        else:
            acc[y : y + PATCH, x : x + PATCH] += p * w2d
            wsum[y : y + PATCH, x : x + PATCH] += w2d
    return acc / wsum


def numpy_tile(img: np.ndarray, origins: np.ndarray) -> np.ndarray:
    return np.stack([img[y : y + PATCH, x : x + PATCH] for x, y in origins])


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--update-md", action="store_true", help="write the table into BENCHMARKS.md")
    args = ap.parse_args()
    single_thread()
    rounds, repeat = (3, 10) if args.quick else (10, 20)
    rows = []
    for shape, overlap in LAYOUTS:
        img = np.random.default_rng(0).random(shape, dtype=np.float32) * 255
        patches, origins = tile(img, PATCH, overlap)
        # Per-patch offsets, as model outputs have: the merge has real work to do.
        patches = patches + np.arange(len(patches), dtype=np.float32)[:, None, None, None]
        # Per axis, the ramp is the smallest overlap between neighbouring patches.
        wx, wy = (
            feather(PATCH, PATCH - int(np.diff(np.unique(origins[:, k])).max())) for k in (0, 1)
        )
        w2d = (wy[:, None] * wx[None, :])[:, :, None]
        for mode, w in (("average", None), ("feather", w2d)):
            ours = merge_patches(patches, origins, shape, mode=mode)  # type: ignore[arg-type]
            ref = numpy_merge(patches, origins, shape, w)
            err = float(np.abs(ours - ref).max())
            t = interleaved(
                {
                    "numpy": lambda p=patches, o=origins, s=shape, w=w: numpy_merge(p, o, s, w),
                    "ours": lambda p=patches, o=origins, s=shape, m=mode: merge_patches(
                        p, o, s, mode=m
                    ),
                },
                rounds=rounds,
                repeat=repeat,
            )
            rows.append(
                [
                    f"merge {mode}",
                    f"{len(patches)} ({shape[1]}x{shape[0]})",
                    t["numpy"].fmt(),
                    t["ours"].fmt(),
                    f"**{t['numpy'].median / t['ours'].median:.1f}x**",
                    f"{err:.1e}",
                ]
            )
        t = interleaved(
            {
                "numpy": lambda img=img, o=origins: numpy_tile(img, o),
                "ours": lambda img=img, ov=overlap: tile(img, PATCH, ov),
            },
            rounds=rounds,
            repeat=repeat,
        )
        rows.append(
            [
                "tile",
                f"{len(patches)} ({shape[1]}x{shape[0]})",
                t["numpy"].fmt(),
                t["ours"].fmt(),
                f"**{t['numpy'].median / t['ours'].median:.1f}x**",
                "0",
            ]
        )
    header = ["operation", "patches", "numpy", "tacswitch", "speed-up", "max |ours - numpy|"]
    publish("## Patch merging", [
        f"Machine: {machine()}. One thread (`RAYON_NUM_THREADS=1`).",
        "256x256x3 float32 patches, each offset by its index so overlaps disagree;",
        "median [IQR] per call, both in alternating rounds of one run.",
        "numpy: slice-accumulate `w * patch` and `w`, then divide (float32).",
    ], header, rows, COMMAND, args.update_md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
