"""Held-out evaluation of marker removal with the paper's metrics (``tacswitch evaluate tacdiff``).

Frames are simulated contacts the model never saw (their own seeds), with the true markerless
image. Per method: the paper's full-frame MSE / PSNR / SSIM (scikit-image, greyscale, per image,
averaged), and where the work happens: masked MAE over the filled pixels and over the filled
pixels in contact.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from tacswitch.metrics import masked_mae, paper_metrics
from tacswitch.tradeoff import Inpaint, PairedFrame

#: Seed offset of held-out frames (training pairs use SeedSequence([seed, preset, i])).
HELD_OUT_SEED = 1000


def evaluate(frames: Sequence[PairedFrame], methods: dict[tuple[str, str], Inpaint]
             ) -> list[dict[str, Any]]:
    """One row per method: method, setting, mse, psnr, ssim, masked_mae, contact_mae."""
    rows = []
    for (name, knob), fn in methods.items():
        per: dict[str, list[float]] = {"mse": [], "psnr": [], "ssim": [], "masked_mae": [],
                                       "contact_mae": []}
        for f in frames:
            out = fn(f.with_markers, f.mask.view(np.uint8), f)
            for k, v in paper_metrics(out, f.truth).items():
                per[k].append(v)
            per["masked_mae"].append(masked_mae(out, f.truth, f.mask))
            if (f.mask & f.contact).any():
                per["contact_mae"].append(masked_mae(out, f.truth, f.mask & f.contact))
        rows.append({"method": name, "setting": knob,
                     **{k: float(np.mean(v)) if v else float("nan") for k, v in per.items()}})
    return rows


def markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The rows as a Markdown table."""
    lines = ["| method | setting | MSE | PSNR dB | SSIM | masked MAE | MAE in contact |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['method']} | {r['setting']} | {r['mse']:.3f} | {r['psnr']:.2f} | "
                     f"{r['ssim']:.4f} | {r['masked_mae']:.3f} | {r['contact_mae']:.3f} |")
    return "\n".join(lines)
