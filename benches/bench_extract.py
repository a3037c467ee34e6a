"""Marker extraction vs the OpenCV chain users write today, at 640x480 (and other sensors).

Peer chains (OpenCV, one thread): grey -> blur -> blur - grey (saturating) -> fixed threshold ->
connectedComponentsWithStats -> area filter. Two blurs: the paper's Gaussian 15x15 sigma 5 and a
31x31 box (the fastest OpenCV variant found). Also: centre accuracy on synthetic discs (clean and
noise sigma 3), and the real GelSight Mini frames in ../shared/data when present.

    python benches/bench_extract.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
from harness import interleaved, machine, single_thread, table
from scipy.spatial import cKDTree

import tacswitch as ts
from tacswitch import sim

SHARED = Path(__file__).resolve().parents[2] / "shared"
REAL = SHARED / "data" / "real" / "fots_gelsight_mini_markers"


def opencv_chain(img: np.ndarray, blur: str, threshold: int = 25, min_area: int = 10) -> np.ndarray:
    """The peer: centroids of blobs darker than a blurred copy."""
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if blur == "gauss":
        bg = cv2.GaussianBlur(grey, (15, 15), 5)
    else:
        bg = cv2.blur(grey, (31, 31))
    diff = cv2.subtract(bg, grey)  # saturating: no uint8 wraparound
    _, binary = cv2.threshold(diff, threshold, 255, cv2.THRESH_BINARY)
    _, _, stats, cents = cv2.connectedComponentsWithStats(binary, connectivity=8)
    return cents[1:][stats[1:, cv2.CC_STAT_AREA] >= min_area]


def frame(preset: str, noise: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    p = sim.get_preset(preset)
    rest = sim.marker_grid(p.height, p.width, p.rows, p.cols, p.pitch, jitter=0.4, seed=seed)
    bg = sim.gel_background(p.height, p.width, seed=seed)
    img = sim.render_markers(bg, rest, p.diameter, darkness=p.darkness, edge_px=p.edge_px,
                             noise_sigma=noise, seed=seed + 1)
    return img, rest


def max_err(found: np.ndarray, truth: np.ndarray) -> float:
    if len(found) == 0:
        return float("inf")
    return float(cKDTree(found).query(truth)[0].max())


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer rounds (smoke test)")
    args = ap.parse_args()
    single_thread()
    rounds = 3 if args.quick else 15
    print(f"Machine: {machine()}\n")

    rows = []
    for preset in ("gelsight", "gelsight_mini", "dense"):
        img, rest = frame(preset, noise=sim.get_preset(preset).noise_sigma)
        t = interleaved({
            "ours": lambda img=img: ts.extract_markers(img),
            "auto": lambda img=img: ts.extract_markers(img, dilate="auto"),
            "cv_gauss": lambda img=img: opencv_chain(img, "gauss"),
            "cv_box": lambda img=img: opencv_chain(img, "box"),
        }, rounds=rounds, repeat=20)
        ours = ts.extract_markers(img).centres
        fastest = min(t["cv_gauss"].median, t["cv_box"].median)
        peer = opencv_chain(img, "box" if t["cv_box"].median < t["cv_gauss"].median else "gauss")
        same = len(peer) == len(ours) and max_err(ours, peer) < 1.0
        rows.append([
            f"{preset} {img.shape[1]}x{img.shape[0]}, {len(rest)} markers",
            t["ours"].fmt(), t["auto"].fmt(), t["cv_gauss"].fmt(), t["cv_box"].fmt(),
            f"**{fastest / t['ours'].median:.1f}x**",
            f"{len(ours)} / {len(peer)}{' (same)' if same else ''}",
        ])
    print("### Speed (median [IQR] per frame, one thread)\n")
    print(table(["frame", "tacswitch", "tacswitch, adaptive mask (dilate='auto')",
                 "OpenCV Gauss chain", "OpenCV box chain",
                 "speed-up vs fastest OpenCV", "markers ours / OpenCV"], rows))

    acc = []
    for noise in (0.0, 3.0):
        errs_ours, errs_cv = [], []
        for seed in range(5):
            img, rest = frame("gelsight", noise=noise, seed=seed)
            errs_ours.append(max_err(ts.extract_markers(img).centres, rest))
            errs_cv.append(max_err(opencv_chain(img, "gauss"), rest))
        acc.append([f"GelSight discs, noise sigma {noise:g}", f"{max(errs_ours):.3f}",
                    f"{max(errs_cv):.3f}"])
    print("\n### Centre accuracy (max error over 5 frames x 48 markers, px)\n")
    print(table(["frame", "tacswitch", "OpenCV Gauss chain"], acc))

    if REAL.is_dir():
        real = []
        for k in (0, 1):
            img = cv2.imread(str(REAL / f"{k}.png"))
            data = np.loadtxt(REAL / f"{k}.csv", delimiter=",", skiprows=1)
            truth = data[:, :2] + data[:, 2:4]
            m = ts.extract_markers(img)
            d, _ = cKDTree(m.centres).query(truth)
            back, _ = cKDTree(truth).query(m.centres)
            real.append([f"FOTS GelSight Mini {k}.png", f"{len(truth)}", f"{len(m)}",
                         f"{int((d > 7).sum())}", f"{int((back > 7).sum())}",
                         f"{np.median(d):.2f}"])
        print("\n### Real GelSight Mini frames (hand-tracked integer labels)\n")
        print(table(["frame", "labelled", "found", "missed", "false", "median |found - label| px"],
                    real))
    return 0


if __name__ == "__main__":
    sys.exit(main())
