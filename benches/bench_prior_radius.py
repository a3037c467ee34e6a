"""Zero-shot TacDiff and hybrid with the prior's TELEA radius changed at inference.

The shipped models were trained with the prior's TELEA at r = 3; a larger radius is an input
shift. For each radius, copies of the shipped models recording it
(``tacswitch.prior_radius``, :func:`tacswitch.tacdiff.metadata.set_metadata`; same weights) are
scored on:

1. the real-frame proxy (:mod:`tacswitch.realproxy`: taxim's real GelSight / Mini presses,
   painted markers, crisp / soft lossless / MJPEG / H.264; own adaptive mask; masked MAE over
   the true footprint, grey levels);
2. the real FOTS GelSight Mini frames with markers (held-out shifted-mask pixels, MAE);
3. held-out simulated frames (4 per preset, true mask dilated once; masked MAE and MAE in
   contact).

    python benches/bench_prior_radius.py [--frames 3] [--radii 3,8,12] [--parts proxy,fots,sim]

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
from harness import machine, table

REAL = Path("/work/shared/data/real/fots_gelsight_mini_markers")
CASES = {"crisp": [("crisp", "lossless")],
         "soft lossless": [("pasted", "lossless"), ("painted", "lossless")],
         "MJPEG": [("pasted", "mjpeg"), ("painted", "mjpeg")],
         "H.264": [("pasted", "h264"), ("painted", "h264")]}
COMBOS = (("tacdiff", "default"), ("tacdiff", "fast"), ("hybrid", "default"), ("hybrid", "fast"))


def model_copies(radii: list[int], tmp: Path) -> dict[tuple[str, int], str]:
    from tacswitch.tacdiff.infer import model_path
    from tacswitch.tacdiff.metadata import set_metadata

    out = {}
    for name in ("default", "fast"):
        for r in radii:
            path = tmp / f"{name}_r{r}.onnx"
            shutil.copy(model_path(name), path)
            set_metadata(path, {"tacswitch.prior_radius": str(r)})
            out[name, r] = str(path)
    return out


def _case(name: str) -> str:
    return "/".join(name.split("/")[2:])


def proxy_rows(n: int, radii: list[int], models: dict) -> list[list[str]]:
    import tacswitch as ts
    from tacswitch import realproxy as R

    want = {f"{s}/{c}" for v in CASES.values() for s, c in v}
    rows = []
    for sensor in R.SENSORS:
        frames = [f for f in R.proxy_frames(sensor, n, seed=0) if _case(f.name) in want]
        for method, name in COMBOS:
            for r in radii:
                def fill(img, extra, method=method, path=models[name, r]):  # type: ignore[no-untyped-def]
                    m = R._with(R.default_mask(img), extra)
                    return ts.remove_markers(img, m, method=method, model=path)

                res = R.run(frames, fill)
                per = {c: R.pool([x for x in res if _case(x.name) in {f"{s}/{k}" for s, k in v}])
                       for c, v in CASES.items()}
                rows.append([sensor, f"{method} {name}", str(r),
                             *(f"{per[c].mae:.3f}" for c in CASES), f"{R.pool(res).mae:.3f}"])
                print(rows[-1], flush=True)
    return rows


def fots_rows(radii: list[int], models: dict) -> list[list[str]]:
    import cv2

    import tacswitch as ts
    from tacswitch import realproxy as R
    from tacswitch.markers import dilate_mask

    files = sorted(REAL.glob("*.png"))
    prep = []
    for p in files:
        img = cv2.imread(str(p))
        holdout, hidden = R.shifted_holdout(img)
        prep.append((img, holdout, hidden, dilate_mask(R.threshold_mask(img), 3)))
    rows = []
    for method, name in COMBOS:
        for r in radii:
            def fill(img, extra, method=method, path=models[name, r]):  # type: ignore[no-untyped-def]
                return ts.remove_markers(img, R._with(R.default_mask(img), extra), method=method,
                                         model=path)

            maes = [R.heldout_scores(img, fill, ho, hid, holes)[0] for img, ho, hid, holes in prep]
            rows.append([f"{method} {name}", str(r), f"{np.mean(maes):.3f}"])
            print(rows[-1], flush=True)
    return rows


def sim_rows(radii: list[int], models: dict) -> list[list[str]]:
    import tacswitch as ts
    from tacswitch import tradeoff
    from tacswitch.metrics import masked_mae
    from tacswitch.tacdiff.evaluate import HELD_OUT_SEED

    rows = []
    for preset in ("gelsight", "gelsight_mini"):
        frames = tradeoff.simulated_frames(4, preset, seed=HELD_OUT_SEED, mask="true")
        for method, name in COMBOS:
            for r in radii:
                mae, contact = [], []
                for f in frames:
                    kw = {"ref": f.reference} if method == "hybrid" else {}
                    out = ts.remove_markers(f.with_markers, f.mask.astype(bool), method=method,
                                            model=models[name, r], **kw)
                    mae.append(masked_mae(out, f.truth, f.scored))
                    sc = f.scored & f.contact
                    if sc.any():
                        contact.append(masked_mae(out, f.truth, sc))
                rows.append([preset, f"{method} {name}", str(r), f"{np.mean(mae):.3f}",
                             f"{np.mean(contact):.3f}"])
                print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=3, help="real presses per sensor")
    ap.add_argument("--radii", default="3,8,12")
    ap.add_argument("--parts", default="proxy,fots,sim")
    args = ap.parse_args()
    radii = [int(r) for r in args.radii.split(",")]
    parts = args.parts.split(",")
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        models = model_copies(radii, Path(tmp))
        if "proxy" in parts:
            out.append(f"Real-frame proxy ({args.frames} presses per sensor x 7 cases), masked "
                       "MAE:\n\n" + table(["sensor", "method", "prior TELEA r", *CASES, "all"],
                                          proxy_rows(args.frames, radii, models)))
        if "fots" in parts and any(REAL.glob("*.png")):
            out.append("Real FOTS GelSight Mini frames, held-out MAE:\n\n"
                       + table(["method", "prior TELEA r", "held-out MAE"],
                               fots_rows(radii, models)))
        if "sim" in parts:
            out.append("Held-out simulated frames (4 per preset, true mask dilated once):\n\n"
                       + table(["preset", "method", "prior TELEA r", "masked MAE",
                                "MAE in contact"], sim_rows(radii, models)))
    print("\n\n".join([*out, f"Machine: {machine()}.",
                       f"Command: `python benches/bench_prior_radius.py --frames {args.frames} "
                       f"--radii {args.radii} --parts {args.parts}`"]))


if __name__ == "__main__":
    main()
