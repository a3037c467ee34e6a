"""The TELEA radius of ``remove_markers``' default pipeline, measured where it matters.

Our TELEA (Rust core) on the mask ``remove_markers`` builds (adaptive growth, border-cut markers
kept) at each radius, scored on

1. the real-frame proxy (:mod:`tacswitch.realproxy`): Taxim's real markerless GelSight
   (640x480) and GelSight Mini (320x240) presses with markers painted on and captured (crisp;
   soft black/grey dots lossless, MJPEG q75, H.264 CRF 26), masked MAE over the true footprint,
   split into the contact disc and the free gel, per-marker ghost; presses where a radius beats
   r=3; OpenCV's ``cv2.inpaint`` TELEA on a one-dilation threshold mask for comparison;
2. real GelSight Mini frames with markers (FOTS, /work/shared/data/real): held-out shifted-mask
   MAE and the ghost around the real markers (skipped when the folder is missing);
3. simulated contacts (:func:`tacswitch.sim.render_sample`, crisp rendered markers): with the
   known one-dilation mask (the ``tacswitch bench`` setting) and with the default pipeline's
   own mask, overall and in contact;
4. speed: ``inpaint_telea`` against ``cv2.inpaint`` at the same radius on the same adaptive
   mask, and the whole ``remove_markers`` call, interleaved, one thread.

Images are uint8 BGR; errors in grey levels over all channels.

Run: python benches/studies/bench_radius.py [--presses N] [--sim N] [--quick] [--json OUT] [--update]
     python benches/studies/bench_radius.py --load OUT [--speed] [--update]   # re-render a saved run,
                                                 # optionally re-timing only the speed part
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benches/: harness
sys.path.insert(0, str(Path(__file__).parent))
from harness import interleaved, machine, single_thread, table, update_markdown

SECTION = "## TELEA radius of the default pipeline (real frames first)"
REAL = Path("/work/shared/data/real/fots_gelsight_mini_markers")
RADII = (3, 5, 6, 8, 10, 12, 16, 20, 24)
OPENCV_RADII = (3, 8, 12, 16)
SPEED_RADII = (3, 5, 8, 10, 12, 16)
#: Proxy columns: (style, capture) cases pooled into each.
CASES = {
    "crisp": [("crisp", "lossless")],
    "soft lossless": [("pasted", "lossless"), ("painted", "lossless")],
    "MJPEG": [("pasted", "mjpeg"), ("painted", "mjpeg")],
    "H.264": [("pasted", "h264"), ("painted", "h264")],
}
COL_OF = {f"{s}/{c}": col for col, cases in CASES.items() for s, c in cases}


class Acc:
    """Error sums over a set of pixels: MAE, signed mean, count."""

    def __init__(self) -> None:
        self.abs = 0.0
        self.sgn = 0.0
        self.n = 0

    def add(self, out: np.ndarray, truth: np.ndarray, sel: np.ndarray) -> None:
        if sel.any():
            e = out[sel].astype(np.float64) - truth[sel]
            self.abs += float(np.abs(e).sum())
            self.sgn += float(e.sum())
            self.n += e.size

    @property
    def mae(self) -> float:
        return self.abs / self.n if self.n else float("nan")

    @property
    def signed(self) -> float:
        return self.sgn / self.n if self.n else float("nan")


def proxy(sensor: str, n: int, radii: tuple[int, ...], cv_radii: tuple[int, ...]) -> dict:
    """Per method (ours at each radius, OpenCV at each radius) and column: pooled MAE, signed,
    contact / free-gel MAE, ghosts, and per-press MAE (for win counts)."""
    import cv2

    from tacswitch import realproxy as R
    from tacswitch.inpaint import inpaint_telea

    frames = [f for f in R.proxy_frames(sensor, n, seed=0)
              if "/".join(f.name.split("/")[2:]) in COL_OF]
    acc: dict = defaultdict(Acc)
    ghosts: dict = defaultdict(list)
    press: dict = defaultdict(Acc)
    for f in frames:
        col = COL_OF["/".join(f.name.split("/")[2:])]
        idx = f.name.split("/")[1]
        own, thr = R.default_mask(f.img), R.threshold_mask(f.img).astype(np.uint8)
        fills = {f"ours r={r}": (lambda r=r, img=f.img, m=own: inpaint_telea(img, m, r))
                 for r in radii}
        fills |= {f"OpenCV r={r}": (lambda r=r, img=f.img, m=thr:
                                    cv2.inpaint(img, m, r, cv2.INPAINT_TELEA))
                  for r in cv_radii}
        for name, fn in fills.items():
            out = np.asarray(fn())
            for part, sel in (("all", f.footprint), ("contact", f.footprint & f.contact),
                              ("free", f.footprint & ~f.contact)):
                acc[(name, col, part)].add(out, f.clean, sel)
            press[(name, col, idx)].add(out, f.clean, f.footprint)
            ghosts[(name, col)].append(R.ghost_per_marker(out, f.footprint, f.clean))
        print(sensor, f.name, flush=True)
    names = [f"ours r={r}" for r in radii] + [f"OpenCV r={r}" for r in cv_radii]
    res: dict = {}
    for name in names:
        row = {}
        for col in CASES:
            g = np.concatenate(ghosts[(name, col)])
            row[col] = {"mae": acc[(name, col, "all")].mae,
                        "signed": acc[(name, col, "all")].signed,
                        "contact": acc[(name, col, "contact")].mae,
                        "free": acc[(name, col, "free")].mae,
                        "ghost": float(g.mean()), "abs_ghost": float(np.abs(g).mean()),
                        "press": {i: press[(name, col, i)].mae for i in
                                  sorted({k[2] for k in press if k[0] == name and k[1] == col})}}
        res[name] = row
    h, w = frames[0].img.shape[:2]
    return {"size": f"{w}x{h}", "presses": n, "methods": res}


def fots(radii: tuple[int, ...], cv_radii: tuple[int, ...]) -> dict | None:
    """Held-out shifted-mask MAE / signed error and the ghost around the real markers."""
    import cv2

    from tacswitch import realproxy as R
    from tacswitch.markers import dilate_mask

    files = sorted(REAL.glob("*.png"))
    if not files:
        return None
    prep = []
    for p in files:
        img = cv2.imread(str(p))
        holdout, hidden = R.shifted_holdout(img)
        prep.append((img, holdout, hidden, dilate_mask(R.threshold_mask(img), 3)))
    fills = {f"ours r={r}": R.own_mask_fill("telea", radius=r) for r in radii}
    fills |= {f"OpenCV r={r}": R.opencv_fill(r) for r in cv_radii}
    res = {}
    for name, fill in fills.items():
        scores = [R.heldout_scores(img, fill, ho, hid, holes) for img, ho, hid, holes in prep]
        g = np.concatenate([s[2] for s in scores])
        res[name] = {"mae": float(np.mean([s[0] for s in scores])),
                     "signed": float(np.mean([s[1] for s in scores])),
                     "ghost": float(g.mean()), "abs_ghost": float(np.abs(g).mean()),
                     "over1": float((np.abs(g) > 1).mean())}
        print("fots", name, res[name], flush=True)
    return {"frames": len(files), "methods": res}


def simulated(preset: str, n: int, radii: tuple[int, ...]) -> dict:
    """Simulated contacts: known one-dilation mask, and the default pipeline's own mask scored
    over its union with the true footprint (a missed rim counts)."""
    from tacswitch import realproxy as R
    from tacswitch.inpaint import inpaint_telea
    from tacswitch.markers import dilate_mask
    from tacswitch.sim.scene import render_sample

    acc: dict = defaultdict(Acc)
    for i in range(n):
        s = render_sample(preset, (0, i))
        masks = {"known": dilate_mask(s.marker_mask)}
        own = R.default_mask(s.image_markers)
        masks["own"] = own
        for kind, m in masks.items():
            score = m | s.marker_mask
            for r in radii:
                out = inpaint_telea(s.image_markers, m, r)
                acc[(kind, r, "all")].add(out, s.image, score)
                acc[(kind, r, "contact")].add(out, s.image, score & s.contact_mask)
    h, w = s.image.shape[:2]
    return {"size": f"{w}x{h}", "frames": n,
            "rows": {f"{kind} r={r}": {"mae": acc[(kind, r, "all")].mae,
                                       "contact": acc[(kind, r, "contact")].mae}
                     for kind in ("known", "own") for r in radii}}


def speed(sensor: str, radii: tuple[int, ...], rounds: int) -> dict:
    """Median ms per frame at each radius: ``inpaint_telea`` and ``cv2.inpaint`` TELEA on the
    same adaptive mask, and ``remove_markers(img, radius=r)`` (mask extraction included), on a
    painted H.264 proxy frame; interleaved, one thread."""
    import cv2

    import tacswitch as ts
    from tacswitch import realproxy as R

    f = R.proxy_frames(sensor, 1, styles=("painted",), captures=("h264",), seed=0)[0]
    m = R.default_mask(f.img)
    m8 = m.view(np.uint8)
    res = {}
    for r in radii:
        t = interleaved({
            "cv2": lambda r=r: cv2.inpaint(f.img, m8, r, cv2.INPAINT_TELEA),
            "ours": lambda r=r: ts.inpaint_telea(f.img, m, r),
            "pipeline": lambda r=r: ts.remove_markers(f.img, radius=r),
        }, rounds=rounds, repeat=3)
        res[r] = {k: v.median * 1e3 for k, v in t.items()}
        print("speed", sensor, r, res[r], flush=True)
    h, w = f.img.shape[:2]
    return {"size": f"{w}x{h}", "masked_px": int(m.sum()), "ms": res}


def render(data: dict, cmd: str) -> str:
    """The Markdown section."""
    parts = [
        "Which TELEA radius `remove_markers` should use by default. Our TELEA on the mask the "
        "default pipeline builds (adaptive growth); radius in px. Real data decides first: "
        "the real-frame proxy (Taxim's real markerless presses, markers painted and captured; "
        "truth = the clean real frame) and the real FOTS GelSight Mini frames with markers "
        "(held-out bare-gel pixels); simulated contacts second; speed breaks ties."]
    for sensor, d in data["proxy"].items():
        meth = d["methods"]
        base = meth["ours r=3"]
        rows = []
        for name, row in meth.items():
            cells = [name]
            for col in CASES:
                c = row[col]
                cells.append(f"{c['mae']:.2f} ({c['signed']:+.2f})")
            comp = [row[c] for c in ("MJPEG", "H.264")]
            cells.append(" / ".join(f"{row[c]['contact']:.2f}" for c in CASES))
            cells.append(" / ".join(f"{row[c]['free']:.2f}" for c in CASES))
            cells.append(f"{np.mean([c['ghost'] for c in comp]):+.2f}")
            cells.append(f"{row['crisp']['ghost']:+.2f}")
            wins = total = 0
            for col in CASES:
                for i, v in row[col]["press"].items():
                    total += 1
                    wins += v < base[col]["press"][i]
            cells.append("-" if name == "ours r=3" else f"{wins}/{total}")
            rows.append(cells)
        parts.append(
            f"**Proxy, {sensor}** ({d['size']}, {d['presses']} real presses x 7 style/capture "
            "cases; masked MAE over the true footprint (signed error); contact / free gel: MAE "
            "inside / outside the press's contact disc per column; ghost: hole minus gel ring, "
            "relative to the clean frame, luma; wins: (press, column) cells where the method's "
            "MAE is below ours r=3):\n\n" + table(
                ["method", *(f"MAE {c}" for c in CASES), "contact crisp/soft/MJPEG/H.264",
                 "free gel crisp/soft/MJPEG/H.264", "ghost (compr.)", "ghost crisp",
                 "beats r=3"], rows))
    if data.get("fots"):
        d = data["fots"]
        rows = [[n, f"{v['mae']:.2f}", f"{v['signed']:+.2f}", f"{v['ghost']:+.2f}",
                 f"{v['abs_ghost']:.2f}", f"{100 * v['over1']:.0f} %"]
                for n, v in d["methods"].items()]
        parts.append(f"**Real GelSight Mini frames with markers** ({d['frames']} FOTS frames, "
                     "320x240; held-out shifted-mask pixels, real markers copied onto them; "
                     "ghost around the real markers, no clean frame):\n\n" + table(
                         ["method", "held-out MAE", "held-out signed", "ghost", "abs ghost",
                          "markers with abs ghost > 1"], rows))
    for preset, d in data["sim"].items():
        rows = [[n, f"{v['mae']:.3f}", f"{v['contact']:.3f}"] for n, v in d["rows"].items()]
        parts.append(f"**Simulated, {preset}** ({d['frames']} contacts, {d['size']}, crisp "
                     "rendered markers; known = true markers dilated once, own = the default "
                     "pipeline's mask scored over its union with the footprint):\n\n"
                     + table(["mask, radius", "masked MAE", "MAE in contact"], rows))
    for sensor, d in data["speed"].items():
        rows = [[str(r), f"{v['ours']:.2f}", f"{v['cv2']:.2f}", f"{v['cv2'] / v['ours']:.1f}x",
                 f"{v['pipeline']:.2f}"] for r, v in d["ms"].items()]
        parts.append(f"**Speed, {sensor}** ({d['size']}, painted H.264 proxy frame, "
                     f"{d['masked_px']} masked px; median ms per frame, one thread, interleaved):"
                     "\n\n" + table(["radius", "inpaint_telea", "cv2.inpaint TELEA (same mask)",
                                     "speed-up", "remove_markers (mask + fill)"], rows))
    parts += [f"Machine: {data.get('machine', machine())}.", f"Command: `{cmd}`"]
    if "speed_machine" in data:
        parts.append(f"Speed tables re-timed on: {data['speed_machine']}.")
    return "\n\n".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--presses", type=int, default=8, help="real presses per sensor")
    ap.add_argument("--sim", type=int, default=8, help="simulated contacts per preset")
    ap.add_argument("--rounds", type=int, default=5, help="timing rounds")
    ap.add_argument("--quick", action="store_true", help="1 press, 2 sim frames, 3 radii")
    ap.add_argument("--json", type=Path, help="also write the raw numbers here")
    ap.add_argument("--load", type=Path, help="render the raw numbers of an earlier --json run")
    ap.add_argument("--speed", action="store_true", help="with --load: re-time the speed part")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    single_thread()
    from tacswitch.realproxy import SENSORS

    radii, cv_radii, sp_radii = RADII, OPENCV_RADII, SPEED_RADII
    n, n_sim, rounds = args.presses, args.sim, args.rounds
    if args.quick:
        radii, cv_radii, sp_radii, n, n_sim, rounds = (3, 8, 12), (3, 12), (3, 12), 1, 2, 2
    if args.load:
        data = json.loads(args.load.read_text())
        cmd = data["command"]
        if args.speed:
            data["speed"] = {s: speed(s, sp_radii, rounds) for s in SENSORS}
            data["speed_machine"] = machine()
            cmd += f"; speed re-timed: `--load RUN.json --speed --rounds {rounds}`"
    else:
        data = {"proxy": {s: proxy(s, n, radii, cv_radii) for s in SENSORS},
                "fots": fots(radii, cv_radii),
                "sim": {p: simulated(p, n_sim, radii) for p in SENSORS},
                "speed": {s: speed(s, sp_radii, rounds) for s in SENSORS},
                "machine": machine()}
        cmd = ("python benches/studies/bench_radius.py" + (" --quick" if args.quick else
               f" --presses {n} --sim {n_sim} --rounds {rounds}"))
        data["command"] = cmd
    if args.json:
        args.json.write_text(json.dumps(data, indent=1))
    body = render(data, cmd)
    print(body)
    if args.update:
        update_markdown(SECTION, body)


if __name__ == "__main__":
    main()
