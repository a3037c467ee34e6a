"""Biharmonic inpainting (Rust core) against scikit-image and exact expectations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import tacswitch as ts
from conftest import disc_mask
from tacswitch import tradeoff
from tacswitch.metrics import masked_mae


def test_matches_scikit_image_on_interior_holes():
    restoration = pytest.importorskip("skimage.restoration")
    rng = np.random.default_rng(0)
    h, w = 90, 120
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.stack([100 + 40 * np.sin(xx / 9) * np.cos(yy / 13), 80 + 0.3 * xx,
                    rng.normal(120, 10, (h, w))], axis=-1).astype(np.float32)
    mask = disc_mask((h, w), [(25, 25), (70, 30), (95, 65), (40, 66)], 7.5)
    ours = ts.inpaint_biharmonic(img, mask)
    ref = restoration.inpaint_biharmonic(img.astype(np.float64), mask, channel_axis=-1,
                                         split_into_regions=True)
    assert np.abs(ours - ref)[mask].max() < 1e-3
    np.testing.assert_array_equal(ours[~mask], img[~mask])


@pytest.mark.parametrize(("dtype", "value", "channels"), [
    (np.uint8, 100, 1), (np.uint8, 100, 3), (np.uint8, 7, 4), (np.uint16, 40000, 3),
    (np.float32, 0.1234567, 1), (np.float32, -3.5e4, 3)])
def test_flat_image_stays_flat_including_border_holes(dtype: type, value: float, channels: int):
    shape = (60, 80)
    mask = disc_mask(shape, [(0, 0), (79, 59), (40, 30), (0, 30), (44, 0)], 6)
    img: np.ndarray = np.full((*shape, channels), value, dtype=dtype)
    img[mask] = 0  # what lies under the mask must not leak
    out = ts.inpaint_biharmonic(img if channels > 1 else img[:, :, 0], mask)
    want = np.full_like(out, value)
    if np.dtype(dtype).kind == "f":
        np.testing.assert_allclose(out, want, rtol=1e-6)
    else:
        np.testing.assert_array_equal(out, want)


def test_reproduces_smooth_surfaces_that_telea_flattens():
    h, w = 64, 64
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    img = (100 + 0.02 * (xx - 32) ** 2 - 0.02 * (yy - 32) ** 2 + 0.5 * xx).astype(np.float32)
    mask = disc_mask((h, w), [(32, 32)], 10)
    out = ts.inpaint_biharmonic(img, mask)
    telea = ts.inpaint_telea(img, mask, 3)
    err = np.abs(out - img)[mask].max()
    assert err < 1e-3
    assert np.abs(telea - img)[mask].max() > 100 * err


def test_better_than_telea_on_contact_shading():
    frames = tradeoff.simulated_frames(3, "gelsight_mini", seed=1000)
    ours, telea = [], []
    for f in frames:
        c = f.mask & f.contact
        if c.any():
            ours.append(masked_mae(ts.inpaint_biharmonic(f.with_markers, f.mask), f.truth, c))
            telea.append(masked_mae(ts.inpaint_telea(f.with_markers, f.mask, 3), f.truth, c))
    assert telea and np.mean(ours) < 0.95 * np.mean(telea)


def test_remove_markers_biharmonic_keeps_unmasked_pixels():
    f = tradeoff.simulated_frames(1, "gelsight_mini", seed=3)[0]
    out = ts.remove_markers(f.with_markers, method="biharmonic")
    mask = ts.extract_markers(f.with_markers, dilate="auto").mask
    np.testing.assert_array_equal(out[~mask], f.with_markers[~mask])
    assert not np.array_equal(out, f.with_markers)


def test_errors_name_the_argument():
    img = np.zeros((20, 30, 3), np.uint8)
    with pytest.raises(ValueError, match="mask"):
        ts.inpaint_biharmonic(img, np.ones((20, 30), bool))
    with pytest.raises(ValueError, match="mask"):
        ts.inpaint_biharmonic(img, np.zeros((20, 31), bool))
    with pytest.raises(TypeError, match="img"):
        ts.inpaint_biharmonic(img.astype(np.float64), np.zeros((20, 30), bool))
    bad = np.zeros((20, 30), np.float32)
    bad[0, 0] = np.nan
    hole = np.zeros((20, 30), bool)
    hole[10, 10] = True
    with pytest.raises(ValueError, match="img"):
        ts.inpaint_biharmonic(bad, hole)
    bad[0, 0] = 0
    bad[10, 10] = np.nan  # NaN under the mask is fine
    assert np.isfinite(ts.inpaint_biharmonic(bad, hole)).all()
    big = np.zeros((400, 400), bool)
    big[20:380, 20:380] = True
    with pytest.raises(ValueError, match="mask: a hole of"):
        ts.inpaint_biharmonic(np.zeros((400, 400), np.uint8), big)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mask=arrays(np.bool_, (24, 32), elements=st.booleans()),
       seed=st.integers(0, 2**16), dtype=st.sampled_from([np.uint8, np.uint16, np.float32]))
def test_random_masks_never_fail_and_keep_known_pixels(mask, seed, dtype):
    if mask.all():
        mask[0, 0] = False
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 255, (24, 32, 3)).astype(dtype)
    out = ts.inpaint_biharmonic(img, mask)
    assert out.dtype == img.dtype and out.shape == img.shape
    np.testing.assert_array_equal(out[~mask], img[~mask])
    assert np.isfinite(out.astype(np.float64)).all()
