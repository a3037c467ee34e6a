"""Image-quality metrics for marker removal, in numpy (no extra dependency).

All metrics compare a prediction with the true image in grey levels of the input dtype's range
(``data_range`` 255 for uint8); colour images are compared over all channels. Masked variants
average over the pixels where ``mask`` is True (marker pixels: where inpainting happened).
SSIM and FID/KID for the paper's protocol live with the evaluation of the learned models.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def _pair(pred: Any, true: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    p, t = np.asarray(pred), np.asarray(true)
    if p.shape != t.shape:
        raise ValueError(f"pred: shape {p.shape} does not match true {t.shape}")
    return p.astype(np.float64), t.astype(np.float64)


def _mask(mask: Any, shape: tuple[int, ...]) -> NDArray[np.bool_]:
    m = np.asarray(mask).astype(bool)
    if m.shape != shape[:2]:
        raise ValueError(f"mask: expected shape {shape[:2]}; got {m.shape}")
    return m


def mse(pred: Any, true: Any) -> float:
    """Mean squared error over all pixels and channels (grey levels squared)."""
    p, t = _pair(pred, true)
    return float(np.mean((p - t) ** 2))


def psnr(pred: Any, true: Any, data_range: float = 255.0) -> float:
    """Peak signal-to-noise ratio in dB (``inf`` for identical images)."""
    e = mse(pred, true)
    return float("inf") if e == 0 else float(10 * np.log10(data_range**2 / e))


def masked_mae(pred: Any, true: Any, mask: Any) -> float:
    """Mean absolute error over the masked pixels (all channels), grey levels; NaN if none."""
    p, t = _pair(pred, true)
    m = _mask(mask, p.shape)
    if not m.any():
        return float("nan")
    return float(np.mean(np.abs(p[m] - t[m])))


def masked_psnr(pred: Any, true: Any, mask: Any, data_range: float = 255.0) -> float:
    """PSNR over the masked pixels only, dB; NaN if the mask is empty."""
    p, t = _pair(pred, true)
    m = _mask(mask, p.shape)
    if not m.any():
        return float("nan")
    e = float(np.mean((p[m] - t[m]) ** 2))
    return float("inf") if e == 0 else float(10 * np.log10(data_range**2 / e))


def paper_metrics(pred: Any, true: Any) -> dict[str, float]:
    """The paper's full-frame metrics: MSE, PSNR (dB) and SSIM with scikit-image on greyscale
    images (``cv2.COLOR_BGR2GRAY``), ``data_range=255``. Needs scikit-image
    (``pip install scikit-image``)."""
    import cv2

    try:
        from skimage.metrics import (
            mean_squared_error,
            peak_signal_noise_ratio,
            structural_similarity,
        )
    except ImportError:
        raise ValueError("paper metrics need scikit-image: pip install scikit-image") from None
    p, t = np.asarray(pred), np.asarray(true)
    if p.shape != t.shape:
        raise ValueError(f"pred: shape {p.shape} does not match true {t.shape}")
    if p.ndim == 3:
        p, t = cv2.cvtColor(p, cv2.COLOR_BGR2GRAY), cv2.cvtColor(t, cv2.COLOR_BGR2GRAY)
    e = float(mean_squared_error(t, p))
    return {"mse": e,
            "psnr": float("inf") if e == 0 else float(peak_signal_noise_ratio(t, p,
                                                                             data_range=255)),
            "ssim": float(structural_similarity(t, p, data_range=255))}
