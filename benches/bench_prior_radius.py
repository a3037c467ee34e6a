"""Zero-shot TacDiff and hybrid with the prior's TELEA radius changed at inference.

The shipped models were trained with the prior's TELEA at r = 3; a larger radius is an input
shift. For each radius, copies of the shipped models recording it
(``tacswitch.prior_radius``, :func:`tacswitch.tacdiff.metadata.set_metadata`; same weights) are
scored on:

1. the real-frame proxy (:mod:`tacswitch.realproxy`: taxim's real GelSight / Mini presses,
   painted markers, crisp / soft lossless / MJPEG / H.264; own adaptive mask; masked MAE over
   the true footprint, grey levels);
2. the real FOTS GelSight Mini frames with markers (held-out shifted-mask pixels, MAE): dense
   (every shifted hole at once, twice the real hole density, the stress case) and sparse (a
   quarter of them at a time, pooled over the 4 sets: ``realproxy.sparse_heldout_scores``);
3. held-out simulated frames (4 per preset, true mask dilated once; masked MAE and MAE in
   contact).

    python benches/bench_prior_radius.py [--frames 3] [--radii 3,8,12] [--parts proxy,fots,sim]
        [--models LABEL=PATH,...] [--seed 0[,1,...]] [--separation S[,S...]]
        [--orientations N[,N...]]
        [--update [--section TITLE --intro TEXT]]

``--models`` scores these TacDiff ONNX files instead of the radius copies, each at the radius
it records (e.g. models trained at r = 12 against the zero-shot copies); our TELEA default
(``remove_markers``, r = 12) is scored alongside. ``--seed`` picks other real presses (a comma
list: one proxy table per set). ``--section`` writes another BENCHMARKS.md section than the
radius one (a model comparison), ``--intro`` its opening paragraph. ``--separation`` scores
TacDiff and hybrid at each hole separation given (``inpaint_tacdiff(separation=...)``: holes
closer than this are filled in separate passes; 0 = one pass), one row each; default: the
library's default only. ``--orientations`` likewise scores each orientation count
(``remove_markers(orientations=...)``: the network's estimate averaged over flips of the
frame), crossed with the separations when both are given.

Needs ``onnx`` (the ``train`` extra) for the model copies; FOTS frames from /work/shared.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from harness import machine, table, update_markdown

SECTION = "## TacDiff prior radius: models trained at r = 12 vs r = 3 (real frames first)"

REAL = Path("/work/shared/data/real/fots_gelsight_mini_markers")
CASES = {"crisp": [("crisp", "lossless")],
         "soft lossless": [("pasted", "lossless"), ("painted", "lossless")],
         "MJPEG": [("pasted", "mjpeg"), ("painted", "mjpeg")],
         "H.264": [("pasted", "h264"), ("painted", "h264")]}
METHODS = ("tacdiff", "hybrid")


def model_copies(radii: list[int], tmp: Path) -> dict[str, str]:
    """``{"default r=R": path}``: copies of the shipped models recording each radius."""
    from tacswitch.tacdiff.infer import model_path
    from tacswitch.tacdiff.metadata import set_metadata

    out = {}
    for name in ("default", "fast"):
        for r in radii:
            path = tmp / f"{name}_r{r}.onnx"
            shutil.copy(model_path(name), path)
            set_metadata(path, {"tacswitch.prior_radius": str(r)})
            out[f"{name} r={r}"] = str(path)
    return out


#: ``(row label, method, model path, remove_markers options)``.
Combo = tuple[str, str, str | None, dict[str, int]]
#: The option axes: ``{"separation": [...], "orientations": [...]}`` (absent or empty: the
#: library's default).
Axes = dict[str, list[int]]


def _combos(models: dict[str, str], axes: Axes | None = None) -> list[Combo]:
    """``(row label, method, model path, options)``: TELEA default first, then each model x
    method x every combination of the option values given (none: the library's defaults)."""
    import itertools

    from tacswitch.tacdiff.infer import load_model

    axes = {k: v for k, v in (axes or {}).items() if v}
    rows: list[Combo] = [("TELEA default (r=12)", "telea", None, {})]
    for method in METHODS:
        for label, path in models.items():
            r = load_model(path).prior_radius
            for values in itertools.product(*axes.values()):
                kw = dict(zip(axes, values, strict=True))
                tag = "".join(f", {k} {v}" for k, v in kw.items())
                rows.append((f"{method} {label} (prior r={r:g}{tag})", method, path, kw))
    return rows


def _fill(method: str, path: str | None, kw: dict[str, int]):  # type: ignore[no-untyped-def]
    import tacswitch as ts
    from tacswitch import realproxy as R

    def fill(img, extra):  # type: ignore[no-untyped-def]
        m = R._with(R.default_mask(img), extra)
        if path is None:
            return ts.remove_markers(img, m)
        return ts.remove_markers(img, m, method=method, model=path, **kw)

    return fill


def _case(name: str) -> str:
    return "/".join(name.split("/")[2:])


def proxy_rows(n: int, models: dict[str, str], seed: int = 0,
               axes: Axes | None = None) -> list[list[str]]:
    from tacswitch import realproxy as R

    want = {f"{s}/{c}" for v in CASES.values() for s, c in v}
    rows = []
    for sensor in R.SENSORS:
        frames = [f for f in R.proxy_frames(sensor, n, seed=seed) if _case(f.name) in want]
        for label, method, path, kw in _combos(models, axes):
            res = R.run(frames, _fill(method, path, kw))
            per = {c: R.pool([x for x in res if _case(x.name) in {f"{s}/{k}" for s, k in v}])
                   for c, v in CASES.items()}
            rows.append([sensor, label, *(f"{per[c].mae:.3f}" for c in CASES),
                         f"{R.pool(res).mae:.3f}"])
            print(rows[-1], flush=True)
    return rows


def fots_rows(models: dict[str, str], axes: Axes | None = None) -> list[list[str]]:
    import cv2

    from tacswitch import realproxy as R
    from tacswitch.markers import dilate_mask

    files = sorted(REAL.glob("*.png"))
    prep = []
    for p in files:
        img = cv2.imread(str(p))
        holdout, hidden = R.shifted_holdout(img)
        prep.append((img, holdout, hidden, dilate_mask(R.threshold_mask(img), 3)))
    rows = []
    for label, method, path, kw in _combos(models, axes):
        fill = _fill(method, path, kw)
        sc = [R.heldout_scores(img, fill, ho, hid, holes) for img, ho, hid, holes in prep]
        sp = [R.sparse_heldout_scores(img, fill, ho, hid) for img, ho, hid, _ in prep]
        rows.append([label, f"{np.mean([s[0] for s in sc]):.3f}",
                     f"{np.mean([s[1] for s in sc]):+.3f}",
                     f"{np.mean([s[0] for s in sp]):.3f}", f"{np.mean([s[1] for s in sp]):+.3f}",
                     f"{np.mean([np.mean(s[2]) for s in sc]):+.3f}"])
        print(rows[-1], flush=True)
    return rows


def sim_rows(models: dict[str, str], n: int = 4, axes: Axes | None = None) -> list[list[str]]:
    import tacswitch as ts
    from tacswitch import tradeoff
    from tacswitch.metrics import masked_mae
    from tacswitch.tacdiff.evaluate import HELD_OUT_SEED

    rows = []
    for preset in ("gelsight", "gelsight_mini"):
        frames = tradeoff.simulated_frames(n, preset, seed=HELD_OUT_SEED, mask="true")
        for label, method, path, kw in _combos(models, axes):
            mae, contact = [], []
            for f in frames:
                m = f.mask.astype(bool)
                if path is None:
                    out = ts.remove_markers(f.with_markers, m)
                else:
                    ref = {"ref": f.reference} if method == "hybrid" else {}
                    out = ts.remove_markers(f.with_markers, m, method=method, model=path,
                                            **ref, **kw)
                mae.append(masked_mae(out, f.truth, f.scored))
                sc = f.scored & f.contact
                if sc.any():
                    contact.append(masked_mae(out, f.truth, sc))
            rows.append([preset, label, f"{np.mean(mae):.3f}", f"{np.mean(contact):.3f}"])
            print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=3, help="real presses per sensor")
    ap.add_argument("--seed", default="0",
                    help="which real presses (realproxy seed; a comma list: one table each)")
    ap.add_argument("--radii", default="3,8,12")
    ap.add_argument("--models", default="",
                    help="LABEL=PATH,... TacDiff ONNX files to score instead of the copies")
    ap.add_argument("--parts", default="proxy,fots,sim")
    ap.add_argument("--separation", default="",
                    help="hole separations (px, comma list) to score TacDiff and hybrid at")
    ap.add_argument("--orientations", default="",
                    help="orientation counts (comma list of 1, 2, 4, 8) to score TacDiff and "
                         "hybrid at")
    ap.add_argument("--update", action="store_true", help="write the BENCHMARKS.md section")
    ap.add_argument("--section", default=SECTION,
                    help="BENCHMARKS.md section title (a '## ' heading) that --update writes")
    ap.add_argument("--intro", default="", help="opening paragraph of that section")
    args = ap.parse_args()
    if not args.section.startswith("## "):
        raise SystemExit(f"--section: must start with '## '; got {args.section!r}")
    try:
        seeds = [int(x) for x in args.seed.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"--seed: expected integers like 0,1,2; got {args.seed!r}") from None
    axes: Axes = {}
    for flag, key in (("--separation", "separation"), ("--orientations", "orientations")):
        text = getattr(args, key)
        try:
            axes[key] = [int(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise SystemExit(f"{flag}: expected integers like 1,4; got {text!r}") from None
    parts = args.parts.split(",")
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        if args.models:
            models = dict(item.split("=", 1) for item in args.models.split(","))
        else:
            models = model_copies([int(r) for r in args.radii.split(",")], Path(tmp))
        for seed in seeds if "proxy" in parts else []:
            out.append(f"Real-frame proxy ({args.frames} presses per sensor, seed {seed}, "
                       "x 7 cases), masked MAE:\n\n"
                       + table(["sensor", "method", *CASES, "all"],
                               proxy_rows(args.frames, models, seed, axes)))
        if "fots" in parts and any(REAL.glob("*.png")):
            out.append("Real FOTS GelSight Mini frames, held-out MAE and signed error (dense: "
                       "every shifted hole at once, twice the real hole density; sparse: a "
                       "quarter at a time, pooled over 4 sets), ghost:\n\n"
                       + table(["method", "dense MAE", "dense signed", "sparse MAE",
                                "sparse signed", "ghost"], fots_rows(models, axes)))
        if "sim" in parts:
            out.append("Held-out simulated frames (4 per preset, true mask dilated once):\n\n"
                       + table(["preset", "method", "masked MAE", "MAE in contact"],
                               sim_rows(models, axes=axes)))
    what = f"--models '{args.models}'" if args.models else f"--radii {args.radii}"
    body = "\n\n".join([*([args.intro] if args.intro else []), *out, f"Machine: {machine()}.",
                         f"Command: `python benches/bench_prior_radius.py --frames {args.frames} "
                         f"--seed {args.seed} {what} --parts {args.parts}"
                         + (f" --separation {args.separation}" if axes["separation"] else "")
                         + (f" --orientations {args.orientations}" if axes["orientations"]
                            else "")
                         + (f" --section '{args.section}'" if args.section != SECTION else "")
                         + "`"])
    print(body)
    if args.update:
        update_markdown(args.section, body)


if __name__ == "__main__":
    main()
