"""Marker removal on real frames: the real-frame proxy and the ground-truth-free check.

1. Proxy (:mod:`tacswitch.realproxy`): Taxim's real markerless GelSight (640x480) and GelSight
   Mini (320x240) presses with markers painted on (crisp black dots; black pasted and grey
   painted dots with soft rims and halo fitted to real Mini frames) and captured (lossless,
   MJPEG q75, H.264 CRF 26), scored against the clean real frame over the true footprint:
   masked MAE, mean signed error, and the ghost (hole minus gel ring, per marker, relative to
   the clean frame).
2. Real frames with markers (FOTS GelSight Mini, /work/shared/data/real): hold out bare-gel
   pixels half a pitch from the markers (real markers copied there), score each fill there (all
   at once, and sparse: a quarter at a time, ``realproxy.sparse_heldout_scores``), and measure
   the ghost around the real markers.

Every method picks its own mask (that is what a user gets); times are medians per frame on one
thread (GelSight, 640x480). "TELEA default" is ``remove_markers``' default radius
(:data:`tacswitch.inpaint.DEFAULT_RADIUS`); r=3, the default before, is kept as its own row, and
hybrid's TELEA part runs at the default radius. The TacDiff and hybrid rows depend on the code
and models in ``python/tacswitch/tacdiff`` and ``python/tacswitch/models``: the section names the
commit and says whether those had uncommitted changes.

Run: python benches/bench_real_removal.py [--quick] [--frames N] [--no-models] [--update]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, single_thread, table, update_markdown

SECTION = "## Marker removal on real frames (real-frame proxy)"
REAL = Path("/work/shared/data/real/fots_gelsight_mini_markers")
#: (style, capture) cases of the proxy and their column titles.
CASES = {
    "crisp": [("crisp", "lossless")],
    "soft lossless": [("pasted", "lossless"), ("painted", "lossless")],
    "MJPEG": [("pasted", "mjpeg"), ("painted", "mjpeg")],
    "H.264": [("pasted", "h264"), ("painted", "h264")],
}
SOFT = ("soft lossless", "MJPEG", "H.264")
COMPRESSED = ("MJPEG", "H.264")


def proxy_tables(n: int, methods: dict, sensors: tuple[str, ...]) -> list[str]:
    from tacswitch import realproxy as R

    out = []
    for sensor in sensors:
        want = {f"{s}/{c}" for cases in CASES.values() for s, c in cases}
        frames = [f for f in R.proxy_frames(sensor, n, seed=0)
                  if "/".join(f.name.split("/")[2:]) in want]

        def pick(res: list, cols: tuple[str, ...]) -> list:
            keep = {f"{s}/{c}" for col in cols for s, c in CASES[col]}
            return [r for r in res if "/".join(r.name.split("/")[2:]) in keep]

        rows = []
        for name, fill in methods.items():
            res = R.run(frames, fill)
            per = {col: R.pool(pick(res, (col,))) for col in CASES}
            comp = R.pool(pick(res, COMPRESSED))
            rows.append((comp.mae, [name, *(f"{per[c].mae:.2f}" for c in CASES),
                                    f"{comp.signed:+.2f}", f"{comp.ghost:+.2f}",
                                    f"{comp.ghost_abs:.2f}", f"{per['crisp'].ghost:+.2f}",
                                    f"{R.pool(res).ms:.0f}"]))
            print(sensor, rows[-1][1], flush=True)
        rows.sort(key=lambda r: r[0])
        h, w = frames[0].img.shape[:2]
        out.append(f"**{sensor}** ({w}x{h}, {n} real presses x {len(frames) // n} "
                   "style/capture cases; masked MAE over the true footprint, grey levels; "
                   "signed error and ghost pooled over the MJPEG and H.264 cases; sorted by "
                   "their MAE):\n\n" + table(
                       ["method", *(f"MAE {c}" for c in CASES), "signed (compr.)",
                        "ghost (compr.)", "abs ghost (compr.)", "ghost crisp", "ms / frame"],
                       [r[1] for r in rows]))
    return out


def real_table(methods: dict) -> str | None:
    import cv2

    from tacswitch import realproxy as R
    from tacswitch.markers import dilate_mask

    files = sorted(REAL.glob("*.png"))
    if not files:
        return None
    imgs = [cv2.imread(str(p)) for p in files]
    prep = []
    for img in imgs:
        holdout, hidden = R.shifted_holdout(img)
        prep.append((img, holdout, hidden, dilate_mask(R.threshold_mask(img), 3)))
    rows = []
    for name, fill in methods.items():
        maes, signed, ghosts, sparse = [], [], [], []
        for img, holdout, hidden, holes in prep:
            a, s, g = R.heldout_scores(img, fill, holdout, hidden, holes)
            maes.append(a)
            signed.append(s)
            ghosts.append(g)
            sparse.append(R.sparse_heldout_scores(img, fill, holdout, hidden)[0])
        g = np.concatenate(ghosts)
        rows.append((float(np.mean(maes)), [name, f"{np.mean(maes):.2f}",
                                            f"{np.mean(signed):+.2f}",
                                            f"{np.mean(sparse):.2f}", f"{g.mean():+.2f}",
                                            f"{np.abs(g).mean():.2f}",
                                            f"{(np.abs(g) > 1).mean() * 100:.0f} %"]))
        print("real", rows[-1][1], flush=True)
    rows.sort(key=lambda r: r[0])
    n_hold = int(np.mean([p[1].sum() for p in prep]))
    return (f"**Real GelSight Mini frames with markers** ({len(imgs)} FOTS frames, 320x240; "
            f"{n_hold} held-out bare-gel px per frame, real markers copied onto them: all at "
            "once, twice the real hole density, and sparse, a quarter at a time pooled over 4 "
            "sets; ghost around the real markers, without a clean frame):\n\n" + table(
                ["method", "held-out MAE", "held-out signed", "held-out MAE sparse", "ghost",
                 "abs ghost",
                 "markers with abs ghost > 1"], [r[1] for r in rows]))


def profile_table() -> str | None:
    """Real FOTS dots against the painted style, lossless and through the proxy's codecs."""
    import cv2

    from tacswitch import realproxy as R
    from tacswitch.sim import capture
    from tacswitch.sim.markers import marker_grid, paint_markers

    files = sorted(REAL.glob("*.png"))
    if not files:
        return None
    ks = range(4, 12)
    real = np.mean([R.radial_profile(cv2.imread(str(p)), radii=12) for p in files], axis=0)
    rng = np.random.default_rng(0)
    gel = np.full((240, 320, 3), (190, 150, 178), np.uint8)  # the FOTS frames' mean gel colour
    centres = marker_grid(240, 320, 8, 10, 29.0) + rng.uniform(-0.5, 0.5, (80, 2))
    painted, _ = paint_markers(gel, centres, R.styles_for("gelsight_mini")["painted"], rng=1)
    rows = [["real FOTS Mini dots", *(f"{real[k]:.3f}" for k in ks)]]
    for name, prof in R.CAPTURES.items():
        p = R.radial_profile(capture.apply(painted, prof, 0), centres, radii=12)
        rows.append([f"painted style, {name}", *(f"{p[k]:.3f}" for k in ks)])
    return ("**Marker profile** (mean luma over the gel 10-14 px out, by distance from the dot "
            "centre; 320x240): the painted style against the real FOTS GelSight Mini dots.\n\n"
            + table(["dots", *(f"{k}-{k + 1} px" for k in ks)], rows))


def code_state() -> str:
    """The commit, and whether the TacDiff code or models differ from it (uncommitted)."""
    import subprocess

    root = Path(__file__).resolve().parents[1]

    def git(*a: str) -> str:
        # rstrip only: porcelain lines start with a status column that may be a space.
        return subprocess.run(["git", *a], capture_output=True, text=True,
                              cwd=root).stdout.rstrip()

    dirty = git("status", "--porcelain", "--", "python/tacswitch/tacdiff",
                "python/tacswitch/models", "python/tacswitch/inpaint.py")
    changed = ", ".join(line[3:] for line in dirty.splitlines())
    return (f"commit {git('rev-parse', '--short', 'HEAD')}"
            + (f", with uncommitted changes in {changed}" if changed else
               ", TacDiff code and models as committed"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="1 press per sensor, radii 3 and 12")
    ap.add_argument("--frames", type=int, default=4, help="real presses per sensor")
    ap.add_argument("--no-models", action="store_true", help="skip TacDiff and hybrid")
    ap.add_argument("--update", action="store_true", help="write the section of BENCHMARKS.md")
    args = ap.parse_args()
    single_thread()
    from tacswitch import realproxy as R

    n = 1 if args.quick else args.frames
    radii = (3, 12) if args.quick else (3, 5, 8, 12)
    methods = R.methods(radii, models=not args.no_models,
                        priors=("telea+biharmonic", "telea+biharmonic-grown"))
    methods["biharmonic grown (own mask)"] = R.grown_biharmonic_fill()
    profile = profile_table()
    parts = proxy_tables(n, methods, R.SENSORS)
    real = real_table(methods)
    cmd = "python benches/bench_real_removal.py" + (" --quick" if args.quick else
                                                    f" --frames {n}") + (
        " --no-models" if args.no_models else "")
    body = "\n\n".join([
        "Marker removal where the truth is known and the frames are real: Taxim's real "
        "markerless presses with markers painted on as real ones look "
        "(`tacswitch.sim.markers.paint_markers`, fitted to real GelSight Mini dots) and "
        "captured as a camera or recorder would (`tacswitch.sim.capture`); every method builds "
        "its own mask, as `remove_markers` does. `ghost`: mean over markers of (filled hole - "
        "gel ring 3-6 px out) minus the same on the clean frame, luma; it should stay within "
        "+-1. Numbers measured on real frames with painted markers (the proxy), not on real "
        "markers, except the last table.",
        *([profile] if profile else []), *parts, *([real] if real else []),
        f"Machine: {machine()}. TacDiff/hybrid rows measured at {code_state()}.",
        f"Command: `{cmd}`"])
    print(body)
    if args.update:
        update_markdown(SECTION, body)


if __name__ == "__main__":
    main()
