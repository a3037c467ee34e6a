"""Derives the shipped calibration arrays from the ``taxim==1.4.1`` wheel (MIT licence).

Run once by a maintainer (``python -m tacswitch.sim.calib.make_calib``, taxim installed or its
wheel unpacked: ``--taxim DIR``); the package itself never runs it and never downloads anything.

What is kept, per sensor (``gelsight``, ``gelsight_mini``), in ``<sensor>.npz``:

- ``poly``: ``3 x M x D x 6`` float16, channel order **BGR**, bins of gradient magnitude
  ``atan(|grad z|)`` over ``[0, pi/2]`` (M) and direction ``atan2(dz/dy, dz/dx)`` over
  ``[-pi, pi]`` (D). Each bin holds the six coefficients of a colour offset (grey levels) that is
  a quadratic in the *normalised* pixel position ``u = x / W``, ``v = y / H`` of the 640x480
  calibration frame: ``[u^2, v^2, u v, u, v, 1]``. Taxim stores them for raw pixel coordinates in
  float64; normalising makes all six of similar size, so float16 keeps the colour within
  ~0.1 grey level (checked below) at a quarter of the size.
- ``background``: the real no-contact frame ``f0`` (BGR uint8; the Mini's at 320x240).
- ``pixmm``: mm per pixel of the 640x480 calibration frame.

Taxim's ``polycalib.npz`` names its tables ``grad_r/g/b`` but stores them in B, G, R order of
the frames (its own renderers swap them back); this is checked against a real press in
tests/test_sim_optics.py.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

CALIB_W, CALIB_H = 640, 480


def derive(taxim_calib: Path, sensor: str, out: Path) -> None:
    src = taxim_calib / sensor
    data = np.load(src / "polycalib.npz")
    # grad_r holds the frames' first (B) channel; see the module docstring.
    poly = np.stack([data["grad_r"], data["grad_g"], data["grad_b"]]).astype(np.float64)
    scale = np.array([CALIB_W**2, CALIB_H**2, CALIB_W * CALIB_H, CALIB_W, CALIB_H, 1.0])
    norm = poly * scale
    poly16 = norm.astype(np.float16)
    # Worst colour error of the float16 table over the frame corners and centre.
    pts = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [0.5, 0.5]])
    feats = np.stack([pts[:, 0] ** 2, pts[:, 1] ** 2, pts[:, 0] * pts[:, 1], pts[:, 0],
                      pts[:, 1], np.ones(len(pts))], axis=1)
    err = np.abs((norm - poly16.astype(np.float64)) @ feats.T).max()
    print(f"{sensor}: float16 table error <= {err:.3f} grey levels")
    f0 = np.load(src / "dataPack.npz", allow_pickle=True)["f0"]
    if sensor == "gelsight_mini":
        import cv2

        f0 = cv2.resize(f0, (320, 240), interpolation=cv2.INTER_AREA)
    params = json.loads((src / "params.json").read_text())
    np.savez_compressed(out / f"{sensor}.npz", poly=poly16, background=f0,
                        pixmm=np.float64(params["sensor"]["pixmm"]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--taxim", type=Path, default=None,
                    help="taxim package folder (default: the installed taxim)")
    args = ap.parse_args()
    if args.taxim is None:
        import taxim

        args.taxim = Path(taxim.__file__).parent
    out = Path(__file__).parent
    for sensor in ("gelsight", "gelsight_mini"):
        derive(args.taxim / "calib", sensor, out)


if __name__ == "__main__":
    main()
