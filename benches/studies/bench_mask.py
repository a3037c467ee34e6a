"""Marker masks on real-frame proxies: does the mask cover what a marker darkens?

Proxy frames (real with painted markers): taxim's real markerless GelSight (640x480) and
GelSight Mini (downscaled to 320x240, the resolution of the real Mini frames with markers)
presses, with markers painted the way real ones look (``tacswitch.sim.markers.paint_markers``:
GelSight pasted black dots, Mini grey painted dots; grids at a random phase so markers are cut
by every border) and captured as a camera and recorder would (``tacswitch.sim.capture``: optical
blur, sensor noise, MJPEG or H.264; no colour drift, so the clean frame stays the target).
Scored against the clean real frame over the true footprint (every pixel painting changed by
more than half a grey level):

- masked MAE / mean signed error of the fill (grey levels, all BGR channels);
- coverage: the fraction of the footprint inside the mask;
- rim: mean darkening (clean - captured luma) of the one-pixel ring just outside the mask, i.e.
  what the fill is built from beyond the truth (0 is ideal);
- mask size relative to the footprint.

Masks: ``remove_markers``'s extraction with ``dilate`` 1, 2, 5 and ``"auto"`` (adaptive, the
default), our TELEA r=3; OpenCV TELEA r=3..12 on the one-dilation mask (the usual recipe).
Also the real GelSight Mini frames with markers (FOTS): markers found vs labelled, and marker
pixels (luma below half the gel's median) left outside each mask; and the split in contact /
off contact on ``tacswitch.realproxy`` frames (Taxim's contact disc): mask size per marker, how
often growth ran to its cap, and the masked MAE of TELEA r=12 on the adaptive mask vs OpenCV's on
the one-dilation mask (contact shading is not planar around a marker, which the growth rule has
to tell from a marker's rim).

    python benches/studies/bench_mask.py [--quick] [--contact-presses N] [--update]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved, machine, publish, single_thread, table

import tacswitch as ts
from tacswitch.sim import capture
from tacswitch.sim.markers import paint_markers, sample_style

SHARED = Path(__file__).resolve().parents[3] / "shared"
REAL = SHARED / "data" / "real" / "fots_gelsight_mini_markers"
SECTION = "## Marker masks on real-frame proxies (adaptive growth)"

#: Sensor: (taxim calibration, downscale, marker kind, diameter px, pitch px).
SENSORS = {
    "GelSight": ("gelsight", 1, "pasted", 23.0, 80.0),
    "GelSight Mini": ("gelsight_mini", 2, "painted", 11.5, 28.5),
}
#: Captures: name -> profile (no gain/offset drift: the clean frame stays the target).
CAPTURES = {
    "crisp dots (edge 0.3 px, no halo), lossless": capture.CaptureProfile(),
    "real-look dots, lossless, no blur/noise": capture.CaptureProfile(),
    "soft (blur 1.0, noise 1.5)": capture.CaptureProfile(blur_sigma=1.0, read_noise=1.5),
    "MJPEG q80": capture.CaptureProfile(blur_sigma=0.7, read_noise=1.5, codec="mjpeg",
                                        quality=80),
    "H.264 CRF 23": capture.CaptureProfile(blur_sigma=0.7, read_noise=1.5, codec="h264",
                                           quality=23),
    "H.264 CRF 28": capture.CaptureProfile(blur_sigma=0.7, read_noise=1.5, codec="h264",
                                           quality=28),
}
OURS = ("1", "2", "5", "auto")
CV_RADII = (3, 5, 8, 12)


def clean_frames(calib: str, scale: int, n: int) -> list[np.ndarray]:
    import taxim

    pack = np.load(Path(taxim.__file__).parent / "calib" / calib / "dataPack.npz")
    imgs = pack["imgs"]
    idx = np.linspace(0, len(imgs) - 1, n).round().astype(int)
    out = []
    for i in idx:
        f = imgs[i]
        if scale > 1:
            f = cv2.resize(f, (f.shape[1] // scale, f.shape[0] // scale),
                           interpolation=cv2.INTER_AREA)
        out.append(np.ascontiguousarray(f))
    return out


def grid(h: int, w: int, pitch: float, diameter: float, rng: np.random.Generator) -> np.ndarray:
    """A jittered square grid at a random phase, including markers cut by the borders."""
    ox, oy = rng.uniform(0, pitch, 2)
    xs = np.arange(ox - pitch, w + pitch, pitch)
    ys = np.arange(oy - pitch, h + pitch, pitch)
    pts = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    pts = pts + rng.normal(0, 0.5, pts.shape)
    r = diameter / 2
    keep = (pts[:, 0] > -0.8 * r) & (pts[:, 0] < w - 1 + 0.8 * r) & (pts[:, 1] > -0.8 * r) & (
        pts[:, 1] < h - 1 + 0.8 * r)
    return pts[keep]


def luma(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32) if img.ndim == 3 else \
        img.astype(np.float32)


def scores(filled: np.ndarray, clean: np.ndarray, foot: np.ndarray) -> tuple[float, float]:
    d = filled.astype(np.float32)[foot] - clean.astype(np.float32)[foot]
    return float(np.abs(d).mean()), float(d.mean())


def rim(mask: np.ndarray, clean: np.ndarray, captured: np.ndarray) -> float:
    ring = ts.dilate_mask(mask, 1) & ~mask
    return float((luma(clean) - luma(captured))[ring].mean()) if ring.any() else 0.0


def run_case(clean: np.ndarray, img: np.ndarray, foot: np.ndarray, acc: dict) -> None:
    masks = {}
    for d in OURS:
        ex = ts.extract_markers(img, dilate=d if d == "auto" else int(d), exclude_border=False)
        masks[d] = ex.mask
        if d == "auto":
            acc.setdefault(("rings",), []).extend(ex.grow_rings.tolist())
    for d, m in masks.items():
        out = ts.inpaint_telea(img, m, 3)
        mae, bias = scores(out, clean, foot)
        acc.setdefault(("ours", d), []).append(
            (mae, bias, float(m[foot].mean()), rim(m, clean, img), m.sum() / max(foot.sum(), 1)))
    m1 = masks["1"].astype(np.uint8)
    for r in CV_RADII:
        out = cv2.inpaint(img, m1, r, cv2.INPAINT_TELEA)
        mae, bias = scores(out, clean, foot)
        acc.setdefault(("cv", r), []).append((mae, bias))


def proxy(n_frames: int, seed: int) -> tuple[list[list[str]], dict[str, np.ndarray]]:
    rows, samples = [], {}
    for sensor, (calib, scale, kind, diam, pitch) in SENSORS.items():
        frames = clean_frames(calib, scale, n_frames)
        for cap_name, prof in CAPTURES.items():
            acc: dict = {}
            rng = np.random.default_rng(seed)
            for clean in frames:
                h, w = clean.shape[:2]
                style = sample_style(rng, kind=kind, diameter=diam)  # type: ignore[arg-type]
                if cap_name.startswith("crisp"):
                    # Antialiased sharp discs: the case where a wider mask only costs.
                    style = replace(style, edge_px=0.3, halo=0.0, texture=0.0)
                pts = grid(h, w, pitch, style.diameter, rng)
                painted, foot = paint_markers(clean, pts, style, rng=rng)
                img = capture.apply(painted, prof, rng)
                run_case(clean, img, foot, acc)
                if cap_name.startswith("H.264 CRF 23"):
                    samples[sensor] = img
            cells = [sensor, cap_name]
            for d in OURS:
                a = np.array(acc[("ours", d)])
                cells.append(f"{a[:, 0].mean():.2f} ({a[:, 1].mean():+.2f}) "
                             f"{100 * a[:, 2].mean():.1f}% rim {a[:, 3].mean():+.1f}")
            best_cv = min(CV_RADII, key=lambda r: np.mean([v[0] for v in acc[("cv", r)]]))
            cv = np.array(acc[("cv", best_cv)])
            cells.append(f"{cv[:, 0].mean():.2f} ({cv[:, 1].mean():+.2f}) r={best_cv}")
            cells.append(" / ".join(f"{np.mean([v[0] for v in acc[('cv', r)]]):.2f}"
                                    for r in CV_RADII))
            rings = np.array(acc[("rings",)])
            a = np.array(acc[("ours", "auto")])
            cells.append(f"{np.median(rings):.0f} [{np.percentile(rings, 10):.0f}, "
                         f"{np.percentile(rings, 90):.0f}], {a[:, 4].mean():.2f}x")
            rows.append(cells)
            print(" | ".join(cells), flush=True)
    return rows, samples


def timing(samples: dict[str, np.ndarray], rounds: int) -> list[list[str]]:
    """Extraction with each mask, interleaved rounds (the machine is shared)."""
    rows = []
    for sensor, img in samples.items():
        t = interleaved({
            "plain": lambda img=img: ts.extract_markers(img),
            "2": lambda img=img: ts.extract_markers(img, dilate=2),
            "auto": lambda img=img: ts.extract_markers(img, dilate="auto"),
            "telea": lambda img=img: ts.remove_markers(img, dilate=2),
        }, rounds=rounds, repeat=10)
        n = len(ts.extract_markers(img, exclude_border=False))
        grow = t["auto"].median - t["plain"].median
        rows.append([f"{sensor} {img.shape[1]}x{img.shape[0]}, {n} markers", t["plain"].fmt(),
                     t["2"].fmt(), t["auto"].fmt(), f"{1e3 * grow:.2f} ms",
                     t["telea"].fmt()])
    return rows


def _cap_rings(ex: ts.Markers) -> np.ndarray:
    """The growth cap of each marker as ``mask_grow`` sets it (approximately: the radius is the
    thresholded blob's equivalent disc, so border-cut markers' caps are underestimated)."""
    from scipy.spatial import cKDTree

    r = np.sqrt(ex.areas / np.pi)
    by_size = np.maximum(np.ceil(1.5 * r), 1)
    if len(ex) < 2:
        return np.minimum(by_size, 48)
    d, _ = cKDTree(ex.centres).query(ex.centres, k=2)
    gap = np.maximum(d[:, 1] - 2 * r, 0)
    return np.minimum(np.minimum(by_size, np.maximum(np.floor(0.5 * gap), 1)), 48)


def contact_split(n_presses: int, seed: int = 0) -> list[list[str]]:
    """Per marker, in contact (painted centre inside Taxim's contact disc) vs off contact, on
    the real-frame proxy (``tacswitch.realproxy``: all styles x captures): adaptive mask pixels
    per marker and rings, the share of markers whose growth ran to its cap, and the masked MAE
    of TELEA r=12 on the default (adaptive) mask and of OpenCV TELEA r=12 on the one-dilation
    mask, over the footprint pixels of those markers (pixels go to the nearest painted
    centre)."""
    from scipy.spatial import cKDTree

    from tacswitch import realproxy as rp

    rows = []
    for sensor in rp.SENSORS:
        frames = rp.proxy_frames(sensor, n_presses, seed=seed)
        groups: dict[tuple[str, str], dict[str, list]] = {}
        for f in frames:
            cap = f.name.split("/")[3]
            h, w = f.clean.shape[:2]
            yy, xx = np.mgrid[0:h, 0:w]
            tree = cKDTree(f.centres)
            _, owner = tree.query(np.stack([xx.ravel(), yy.ravel()], 1))
            owner = owner.reshape(h, w)
            cx = np.clip(np.rint(f.centres[:, 0]).astype(int), 0, w - 1)
            cy = np.clip(np.rint(f.centres[:, 1]).astype(int), 0, h - 1)
            touch = f.contact[cy, cx]
            ex = ts.extract_markers(f.img, dilate="auto", exclude_border=False)
            m1 = ts.extract_markers(f.img, dilate=1, exclude_border=False).mask
            ours = ts.remove_markers(f.img, ex.mask, radius=12)
            cv = cv2.inpaint(f.img, m1.astype(np.uint8), 12, cv2.INPAINT_TELEA)
            err_o = np.abs(ours.astype(np.float64) - f.clean).mean(axis=2)
            err_c = np.abs(cv.astype(np.float64) - f.clean).mean(axis=2)
            _, which = tree.query(ex.centres) if len(ex) else (None, np.zeros(0, int))
            caps = _cap_rings(ex) if len(ex) else np.zeros(0)
            size_a = np.bincount(owner[ex.mask], minlength=len(f.centres))
            size_1 = np.bincount(owner[m1], minlength=len(f.centres))
            for key, sel in (("contact", touch), ("off", ~touch)):
                g = groups.setdefault((cap, key), {k: [] for k in
                                                   ("eo", "ec", "sa", "s1", "rings", "capped")})
                pix = f.footprint & sel[owner]
                g["eo"].append(err_o[pix])
                g["ec"].append(err_c[pix])
                found = np.unique(which[sel[which]])
                g["sa"].extend(size_a[found].tolist())
                g["s1"].extend(size_1[found].tolist())
                mine = sel[which]
                g["rings"].extend(ex.grow_rings[mine].tolist())
                g["capped"].extend((ex.grow_rings[mine] >= caps[mine]).tolist())
        for (cap, key), g in sorted(groups.items()):
            if not g["rings"]:
                continue
            eo, ec = np.concatenate(g["eo"]), np.concatenate(g["ec"])
            cells = [sensor, cap, key, f"{len(g['rings'])}",
                     f"{eo.mean():.2f}", f"{ec.mean():.2f}",
                     f"{np.mean(g['sa']):.0f} / {np.mean(g['s1']):.0f}",
                     f"{np.median(g['rings']):.0f} [{np.percentile(g['rings'], 90):.0f}]",
                     f"{100 * np.mean(g['capped']):.0f}%"]
            rows.append(cells)
            print(" | ".join(cells), flush=True)
    return rows


def real_frames() -> list[list[str]]:
    from scipy.spatial import cKDTree

    rows = []
    for k in (0, 1):
        img = cv2.imread(str(REAL / f"{k}.png"))
        data = np.loadtxt(REAL / f"{k}.csv", delimiter=",", skiprows=1)
        truth = data[:, :2] + data[:, 2:4]
        g = luma(img)
        dark = g < 0.5 * np.median(g)
        cells = [f"FOTS GelSight Mini {k}.png", f"{len(truth)}"]
        m = ts.extract_markers(img)
        d, _ = cKDTree(m.centres).query(truth)
        back, _ = cKDTree(truth).query(m.centres)
        cells += [f"{len(m)}", f"{int((d > 7).sum())}", f"{int((back > 7).sum())}"]
        for dil in (1, 2, "auto"):
            mk = ts.extract_markers(img, dilate=dil).mask
            left = int((dark & ~mk).sum())
            ex = ts.extract_markers(img, dilate=dil)
            cells.append(f"{left} px, {mk.sum() / max(ex.areas.sum(), 1):.1f}x")
        rings = ts.extract_markers(img, dilate="auto").grow_rings
        cells.append(f"{np.median(rings):.0f} [{rings.min()}, {rings.max()}]")
        rows.append(cells)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="2 frames per sensor (smoke test)")
    ap.add_argument("--frames", type=int, default=6, help="clean frames per sensor")
    ap.add_argument("--contact-presses", type=int, default=3,
                    help="presses per sensor of the in-contact / off-contact split (0: skip)")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    single_thread()
    n = 2 if args.quick else args.frames
    rows, samples = proxy(n, seed=0)
    cost = timing(samples, 3 if args.quick else 10)
    notes = [
        f"Machine: {machine()}. Real taxim frames with painted markers ({n} presses per sensor,"
        " markers painted by `sim.markers.paint_markers`, captured by `sim.capture`);"
        " scored against the clean real frame over the true footprint.",
        "Cells: masked MAE (mean signed error) coverage of the footprint, rim = mean darkening"
        " of the 1-px ring just outside the mask (grey levels). TELEA r=3 (ours) on the mask"
        " of `extract_markers(dilate=...)`; OpenCV `cv2.inpaint` TELEA on the one-dilation"
        " mask at its best radius, and at r=3/5/8/12. Adaptive rings: median [10th, 90th"
        " percentile] per marker, mask size / true footprint.",
    ]
    header = ["sensor", "capture", "dilate 1", "dilate 2", "dilate 5", "auto (default)",
              "OpenCV best", "OpenCV r=3/5/8/12", "auto rings, size"]
    body_rows = rows
    if REAL.is_dir():
        real = real_frames()
        notes_real = table(["frame", "labelled", "found", "missed", "false",
                            "dark px outside mask, mask/area: dilate 1", "dilate 2", "auto",
                            "auto rings median [min, max]"], real)
        print(notes_real)
    else:
        notes_real = "(FOTS frames not present)"
    split = contact_split(args.contact_presses) if args.contact_presses > 0 else []
    split_tab = table(["sensor", "capture", "markers", "n", "TELEA r=12, adaptive mask",
                       "OpenCV TELEA r=12, dilate 1", "mask px / marker: adaptive / dilate 1",
                       "rings median [90th]", "ran to the cap"], split)
    cost_tab = table(["frame (H.264 CRF 23 proxy)", "extract_markers", "dilate=2",
                      "dilate='auto'", "adaptive growth alone",
                      "remove_markers (TELEA r=3, dilate=2, for scale)"], cost)
    notes_tail = ["", "Real GelSight Mini frames with markers (FOTS, 320x240): markers found"
                  " (default options) and near-black pixels (luma < half the median) left"
                  " outside the mask:", "", notes_real, "",
                  f"In contact vs off contact (`tacswitch.realproxy`, {args.contact_presses}"
                  " presses per sensor x painted/pasted/crisp dots; a marker is in contact when"
                  " its painted centre lies in Taxim's contact disc; masked MAE over those"
                  " markers' true footprints, grey levels; cap: growth stopped at 1.5 radii or"
                  " half the gap, as estimated from the thresholded area):", "", split_tab, "",
                  "Cost of the adaptive mask (median [IQR] per frame, one thread, interleaved"
                  " rounds on a busy shared machine):", "", cost_tab]
    publish(SECTION, notes, header, body_rows,
            "python benches/studies/bench_mask.py" + (" --quick" if args.quick else ""), args.update)
    print("\n".join(notes_tail))
    if args.update:
        from harness import update_markdown

        text = (Path(__file__).resolve().parents[2] / "BENCHMARKS.md").read_text()
        start = text.find(SECTION + "\n")
        nxt = text.find("\n## ", start + len(SECTION))
        body = text[start + len(SECTION):nxt if nxt >= 0 else len(text)].strip()
        update_markdown(SECTION, body + "\n" + "\n".join(notes_tail))
    return 0


if __name__ == "__main__":
    sys.exit(main())
