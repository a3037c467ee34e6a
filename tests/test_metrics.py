"""Metrics agree with scikit-image where both compute the same thing; masks are honoured."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.metrics import mean_squared_error, peak_signal_noise_ratio

from tacswitch import metrics


def test_agree_with_scikit_image() -> None:
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-9, 10, a.shape), 0, 255).astype(np.uint8)
    assert metrics.mse(a, b) == pytest.approx(mean_squared_error(a, b))
    assert metrics.psnr(a, b) == pytest.approx(peak_signal_noise_ratio(b, a, data_range=255))
    assert metrics.psnr(a, a) == float("inf")


def test_masked_metrics_only_look_under_the_mask() -> None:
    a = np.zeros((10, 10, 3), np.uint8)
    b = a.copy()
    b[:5] = 200  # outside the mask
    b[8, 8] = 10
    mask = np.zeros((10, 10), bool)
    mask[7:, 7:] = True
    assert metrics.masked_mae(b, a, mask) == pytest.approx(10 / 9)
    assert np.isnan(metrics.masked_mae(b, a, np.zeros((10, 10), bool)))
    with pytest.raises(ValueError, match="mask"):
        metrics.masked_mae(b, a, np.zeros((3, 3), bool))
    with pytest.raises(ValueError, match="pred"):
        metrics.mse(a, a[:5])
