"""Biharmonic inpainting vs scikit-image's inpaint_biharmonic (the same equation), one thread.

Speed: median [IQR] per 640x480 BGR frame with 48 / 63 / 100 painted markers, ours and
``skimage.restoration.inpaint_biharmonic(..., split_into_regions=True, channel_axis=-1)`` timed
in alternating rounds of one run (scikit-image is slow, so fewer samples). Quality: mean
absolute error over the masked pixels against the true pixels, for ours, scikit-image's and our
TELEA r=3, on the frames of ``bench_telea.py``: synthetic shaded gel with fine texture, and the
real markerless GelSight ball presses of Taxim's calibration pack (real contact shading) with
dark soft discs painted on.

    pip download --no-deps taxim==1.4.1 -d /tmp/taxim    # real frames (optional)
    python benches/bench_biharmonic.py [--quick] [--taxim /tmp/taxim] [--update-md]
"""

from __future__ import annotations

import sys

import numpy as np
from bench_telea import LAYOUTS, mae, paint, parse_args, synthetic_and_real
from harness import interleaved, machine, publish

from tacswitch.inpaint import inpaint_biharmonic, inpaint_telea

COMMAND = "python benches/bench_biharmonic.py --taxim /tmp/taxim --update-md"


def skimage_fill(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    from skimage.restoration import inpaint_biharmonic as sk

    out = sk(img.astype(np.float64), mask.astype(bool), channel_axis=-1,
             split_into_regions=True)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def run(name: str, frames: list[np.ndarray], rounds: int, repeat: int) -> list[list[str]]:
    rows = []
    for n_markers, nr, nc, pitch, diam in LAYOUTS:
        painted = [paint(f, nr, nc, pitch, diam, seed=i) for i, f in enumerate(frames)]
        img, mask = painted[0]
        t = interleaved({"skimage": lambda img=img, mask=mask: skimage_fill(img, mask),
                         "ours": lambda img=img, mask=mask: inpaint_biharmonic(img, mask)},
                        rounds=rounds, repeat=repeat)
        errs = {k: np.mean([mae(fn(p, m), f, m) for (p, m), f in
                            zip(painted, frames, strict=True)])
                for k, fn in (("skimage", skimage_fill), ("ours", inpaint_biharmonic),
                              ("telea", lambda p, m: inpaint_telea(p, m, 3)))}
        rows.append([name, str(n_markers), str(int(mask.astype(bool).sum())),
                     t["skimage"].fmt(), t["ours"].fmt(),
                     f"**{t['skimage'].median / t['ours'].median:.1f}x**",
                     f"{errs['skimage']:.3f}", f"{errs['ours']:.3f}", f"{errs['telea']:.3f}"])
        print(" | ".join(rows[-1]), file=sys.stderr)
    return rows


def main() -> int:
    args = parse_args()
    rows = synthetic_and_real(run, args, (2, 2, 2), (4, 3, 6))
    header = ["frames", "markers", "masked px", "scikit-image", "tacswitch", "speed-up",
              "MAE scikit-image", "MAE ours", "MAE TELEA r=3 (ours)"]
    publish("## Biharmonic inpainting", [
        f"Machine: {machine()}. One thread (`RAYON_NUM_THREADS=1`).",
        "Times: median [IQR] per 640x480 BGR frame, both in alternating rounds of one run.",
        "MAE: mean |inpainted - true| over the masked pixels and channels (grey levels),",
        "averaged over the frames; markers and mask as in the TELEA section.",
    ], header, rows, COMMAND, args.update_md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
