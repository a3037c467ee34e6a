"""Is a stuck shear visible in ONE markerless frame? A check on the real FOTS GelSight Mini pair.

The two FOTS frames show one ball contact, pressed (``0.png``) and then sheared while stuck
(``1.png``), with hand-tracked marker motion. A single-frame predictor (the paper's setting) can
only see the shear if the sheared contact *looks* different from a pressed one. Candidates:

1. **Imprint translation.** A stuck contact carries its imprint with the gel: measured here by
   phase correlation of the high-passed frames around the contact, against the markers' mean
   motion over the contact. Invisible in one frame (nothing says where the contact started).
2. **A shape change**, e.g. the bulge of a thin incompressible layer: material pushed ahead of
   the contact thickens the gel there and thins it behind, ``dz = (T / 2) div(u)`` (``u`` the
   lateral motion, ``T`` the gel thickness), which the LEDs would show as a dipole around the
   rim. Measured here: the frame-1 imprint moved back by the measured translation, minus
   frame 0 (``D``), regressed on the shading that bulge would make (``S``: the thin-layer height
   from the FOTS markers' own motion, rendered with the shipped GelSight Mini Taxim tables) and
   on the illumination gradient the shift-back moves (the LEDs do not move with the gel), over
   the ring around the contact. The fitted ``kappa`` is the share of the thin-layer bulge the
   real frame shows; its interval comes from leaving out one of 8 angular sectors at a time
   (jackknife: neighbouring pixels are not independent).

The simulator renders the gel surface from the vertical indentation only (no shear bulge),
so its single-frame model cannot learn a shear cue; this bench says whether a real frame has one
worth adding. One pair of frames, one sensor: a check, not a calibration.

    python benches/studies/bench_shear_cue.py [--data DIR] [--thickness MM] [--update]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from bench_motion_fots import DATA, load_pair
from harness import machine, publish

SECTION = "## A shear cue in one markerless frame? (real FOTS GelSight Mini pair)"
#: The FOTS frames' pixel size: the GelSight Mini preset's (320 x 240 working size).
MM_PER_PX = 0.059
#: High-pass scale (px) for the imprint's texture, and the ring scored (contact radii).
HP_SIGMA = 6.0
RING = (1.0, 2.5)
SECTORS = 8


def highpass(img: np.ndarray, sigma: float = HP_SIGMA) -> np.ndarray:
    import cv2

    g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)
    return g - cv2.GaussianBlur(g, (0, 0), sigma)


def contact_of(hp: np.ndarray) -> tuple[tuple[float, float], float]:
    """Centre ``(x, y)`` px and radius px of the imprint: the peak of the blurred high-pass
    energy, and the radius where its azimuthal mean falls below a quarter of the centre's."""
    import cv2

    e = cv2.GaussianBlur(hp * hp, (0, 0), 12.0)
    cy, cx = np.unravel_index(int(np.argmax(e)), e.shape)
    yy, xx = np.mgrid[0:e.shape[0], 0:e.shape[1]]
    r = np.hypot(xx - cx, yy - cy)
    prof = [float(e[(r >= k) & (r < k + 2)].mean()) for k in range(0, 120, 2)]
    edge = next((2 * i for i, v in enumerate(prof) if v < 0.25 * prof[0]), 120)
    return (float(cx), float(cy)), float(edge)


def dense_motion(pts: np.ndarray, u: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A smooth ``H x W x 2`` field through the markers' motion (thin-plate spline)."""
    from scipy.interpolate import RBFInterpolator

    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    rbf = RBFInterpolator(pts, u, kernel="thin_plate_spline", smoothing=5.0)
    return rbf(np.stack([xx.ravel(), yy.ravel()], 1)).reshape(h, w, 2).astype(np.float32)


def main() -> int:
    import cv2

    import tacswitch as ts
    from tacswitch.sim.optics import load_calibration, shade_taxim

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DATA, help="folder of FOTS PNG + CSV pairs")
    ap.add_argument("--thickness", type=float, default=2.0,
                    help="gel thickness T, mm, of the thin-layer bulge (the presets' default)")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    pair = load_pair(args.data)
    if pair is None:
        return 1
    im0, im1, rest, d0, d1 = pair
    u0, u1 = ts.remove_markers(im0), ts.remove_markers(im1)
    c0, c1 = u0.astype(np.float32), u1.astype(np.float32)
    h, w = c0.shape[:2]
    hp0, hp1 = highpass(u0), highpass(u1)
    (cx, cy), a = contact_of(hp0)

    # 1. The imprint's translation against the gel's (markers over the contact).
    half = round(1.3 * a)
    y0, y1 = max(0, int(cy) - half), min(h, int(cy) + half)
    x0, x1 = max(0, int(cx) - half), min(w, int(cx) + half)
    win = cv2.createHanningWindow((x1 - x0, y1 - y0), cv2.CV_32F)
    (tx, ty), resp = cv2.phaseCorrelate(hp0[y0:y1, x0:x1], hp1[y0:y1, x0:x1], win)
    at0 = rest + d0
    inside = np.hypot(at0[:, 0] - cx, at0[:, 1] - cy) < a
    gel_t = (d1 - d0)[inside].mean(0) if inside.any() else np.full(2, np.nan)

    # 2. What is left once the imprint is moved back: regress on a thin-layer bulge's shading.
    back = np.float32([[1, 0, -tx], [0, 1, -ty]])
    d = cv2.warpAffine(c1, back, (w, h), flags=cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REFLECT) - c0
    u = dense_motion(at0, d1 - d0, (h, w))
    div = np.gradient(u[..., 0], axis=1) + np.gradient(u[..., 1], axis=0)
    # Heights toward the camera: the gel thickens (surface away from the camera) where it
    # converges, div < 0.
    dz = (0.5 * args.thickness * div).astype(np.float32)
    s = shade_taxim(dz, MM_PER_PX, load_calibration("gelsight_mini"))
    light = cv2.GaussianBlur(c0, (0, 0), 20.0)
    gy, gx = np.gradient(light, axis=(0, 1))
    # What moving the LEDs' pattern back with the imprint adds: L(x + t) - L(x).
    g = tx * gx + ty * gy
    yy, xx = np.mgrid[0:h, 0:w]
    r = np.hypot(xx - cx, yy - cy)
    ring = (r >= RING[0] * a) & (r < RING[1] * a)
    sector = ((np.arctan2(yy - cy, xx - cx) + np.pi) / (2 * np.pi) * SECTORS).astype(int)
    sector = np.minimum(sector, SECTORS - 1)

    def fit(sel: np.ndarray) -> np.ndarray:
        """Least squares of D on [S, G, per-channel constants] over ``sel`` (all channels)."""
        n = int(sel.sum())
        cols = [s[sel].ravel(), g[sel].ravel()]
        for ch in range(3):
            one = np.zeros((n, 3), np.float32)
            one[:, ch] = 1
            cols.append(one.ravel())
        coef, *_ = np.linalg.lstsq(np.stack(cols, 1), d[sel].ravel(), rcond=None)
        return coef

    coef = fit(ring)
    jack = np.array([fit(ring & (sector != k))[0] for k in range(SECTORS)])
    se = float(np.sqrt((SECTORS - 1) / SECTORS * ((jack - jack.mean()) ** 2).sum()))
    # Leading and trailing halves of the ring, along the shear.
    e = np.array([tx, ty]) / max(float(np.hypot(tx, ty)), 1e-9)
    along = (xx - cx) * e[0] + (yy - cy) * e[1]
    lead, trail = ring & (along > 0.3 * a), ring & (along < -0.3 * a)

    def dipole(img: np.ndarray) -> float:
        m = img.mean(2)
        return float(m[lead].mean() - m[trail].mean())

    raw = c1 - c0
    rows = [
        ["contact (frame 0): centre, radius", f"({cx:.0f}, {cy:.0f}) px, {a:.0f} px", ""],
        ["imprint translation, frame 0 -> 1 (phase correlation)",
         f"({tx:.1f}, {ty:.1f}) px", f"peak response {resp:.2f}"],
        ["markers' mean motion over the contact, frame 0 -> 1 (FOTS truth)",
         f"({gel_t[0]:.1f}, {gel_t[1]:.1f}) px", f"{int(inside.sum())} markers"],
        ["ring dipole (leading - trailing half, grey), frame 1 - frame 0", f"{dipole(raw):+.2f}",
         "imprint moved and LEDs fixed"],
        ["the same, imprint moved back (D)", f"{dipole(d):+.2f}", ""],
        [f"the thin-layer bulge's shading S (T = {args.thickness:g} mm, Mini tables)",
         f"{dipole(s):+.2f}",
         f"mean absolute S {float(np.abs(s[ring]).mean()):.2f} grey on the ring"],
        ["kappa: share of the thin-layer bulge in D", f"{coef[0]:+.3f} +- {se:.3f}",
         f"jackknife over {SECTORS} sectors"],
        ["illumination term (LEDs' gradient moved back)", f"{coef[1]:+.3f}", "1 = all of it"],
    ]
    notes = [
        f"{machine()}.",
        "",
        "One FOTS GelSight Mini contact (real markers, removed by `remove_markers`' default), "
        "pressed then sheared while stuck. Ring = "
        f"{RING[0]:g}-{RING[1]:g} contact radii; leading / trailing = the ring's halves along "
        "the imprint's translation. See the script's docstring for the method.",
    ]
    publish(SECTION, notes, ["quantity", "value", "note"], rows,
            "python benches/studies/bench_shear_cue.py",
            args.update)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
