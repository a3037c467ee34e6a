"""TELEA inpainting (Rust core) against exact expectations and cv2.inpaint(INPAINT_TELEA)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import tacswitch
from conftest import disc_mask
from tacswitch import sim
from tacswitch.inpaint import inpaint_telea
from tacswitch.removal import remove_markers


def textured(h: int, w: int, seed: int = 0) -> np.ndarray:
    """Smooth GelSight-like shading plus a fine blurred texture, uint8 BGR."""
    rng = np.random.default_rng(seed)
    bg = sim.gel_background(h, w, seed=seed)
    tex = cv2.GaussianBlur(rng.normal(0, 10, (h, w, 3)).astype(np.float32), (0, 0), 1.5)
    return np.clip(np.rint(bg + tex), 0, 255).astype(np.uint8)


GRID = [(40.0 + 80 * i, 40.0 + 80 * j) for i in range(8) for j in range(6)]
BORDER = [(0.0, 0.0), (639.0, 479.0), (0.0, 200.0), (300.0, 0.0)]


@pytest.mark.parametrize(
    ("dtype", "value", "channels"),
    [
        (np.uint8, 100, 1),
        (np.uint8, 100, 3),
        (np.uint8, 100, 4),
        (np.uint16, 40000, 1),
        (np.uint16, 40000, 3),
        (np.float32, 0.1234567, 1),
        (np.float32, 0.1234567, 3),
        (np.float32, -3.5e4, 4),
    ],
)
@pytest.mark.parametrize("radius", [1, 3, 5, 12])
def test_flat_image_stays_exactly_flat(
    dtype: type, value: float, channels: int, radius: int
) -> None:
    shape = (120, 160)
    mask = disc_mask(shape, [(20, 20), (80, 60), *[(x / 4, y / 4) for x, y in BORDER]], 9)
    img: np.ndarray = np.full((*shape, channels), value, dtype=dtype)
    img[mask] = 0  # garbage under the mask must not leak
    if channels == 1:
        img = img[:, :, 0]
    out = inpaint_telea(img, mask, radius)
    assert out.dtype == img.dtype and out.shape == img.shape
    assert np.all(out == np.asarray(value, dtype=dtype))


def test_opencv_is_not_flat_on_a_flat_image() -> None:
    """The defect this implementation removes (documents why we differ from OpenCV)."""
    img = np.full((120, 160, 3), 100, np.uint8)
    mask = disc_mask((120, 160), [(0, 0), (80, 60), (159, 119)], 9)
    img[mask] = 0
    ref = cv2.inpaint(img, mask.astype(np.uint8), 3, cv2.INPAINT_TELEA)
    assert np.any(ref != 100)
    assert np.all(inpaint_telea(img, mask, 3) == 100)


def test_float_input_is_not_biased() -> None:
    img = np.full((64, 64), 10.0, np.float32)
    mask = disc_mask((64, 64), [(32, 32)], 6)
    assert np.all(inpaint_telea(img, mask, 3) == 10.0)


@pytest.mark.parametrize("radius", [3, 5])
def test_linear_ramp_error_is_bounded(radius: int) -> None:
    h, w = 120, 160
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    ramp = 20.0 + 0.5 * xx + 0.25 * yy
    mask = disc_mask((h, w), [(60, 60), (0, 119), (159, 0)], 8)
    out = inpaint_telea(ramp, mask, radius)
    slope = float(np.hypot(0.5, 0.25))
    # A zero-order fill errs by at most the slope times the hole radius.
    assert np.abs(out - ramp).max() <= slope * 8
    assert np.array_equal(out[~mask], ramp[~mask])
    # Rounded integer version: same bound plus rounding.
    out8 = inpaint_telea(np.rint(ramp).astype(np.uint8), mask, radius).astype(np.float32)
    assert np.abs(out8 - ramp).max() <= slope * 8 + 1


@pytest.mark.parametrize("radius", [3, 5])
def test_agrees_with_opencv_on_textured_images(radius: int) -> None:
    truth = textured(480, 640)
    mask = disc_mask((480, 640), GRID, 12)
    img = truth.copy()
    img[mask] = (30, 30, 30)
    ours = inpaint_telea(img, mask, radius).astype(np.float64)
    ref = cv2.inpaint(img, mask.astype(np.uint8), radius, cv2.INPAINT_TELEA).astype(np.float64)
    diff = np.abs(ours - ref)[mask]
    assert diff.mean() <= 1.5
    assert np.percentile(diff, 99) <= 5
    mae_ours = np.abs(ours - truth)[mask].mean()
    mae_cv = np.abs(ref - truth)[mask].mean()
    assert mae_ours <= mae_cv + 0.05


def test_border_holes_are_filled() -> None:
    truth = textured(100, 120, seed=2)
    mask = np.zeros((100, 120), bool)
    mask[0, :] = True
    mask[:, 0] = True
    mask[-3:, -3:] = True
    img = truth.copy()
    img[mask] = 0
    out = inpaint_telea(img, mask, 3)
    # Every filled pixel lies within the range of its neighbourhood, far from the painted 0.
    assert out[mask].min() > 100
    assert np.abs(out.astype(int) - truth)[mask].mean() < 8


def test_independent_holes_solve_alone_as_together() -> None:
    """Per-hole windows: filling holes one at a time equals filling them all at once."""
    truth = textured(240, 320, seed=4)
    centres = [(30.0, 30.0), (200.0, 50.0), (100.0, 180.0), (319.0, 239.0), (0.0, 120.0)]
    img = truth.copy()
    full = disc_mask((240, 320), centres, 10)
    img[full] = 0
    together = inpaint_telea(img, full, 5)
    one_by_one = img.copy()
    for c in centres:
        m = disc_mask((240, 320), [c], 10)
        one_by_one[m] = inpaint_telea(img, m, 5)[m]
    assert np.array_equal(together, one_by_one)


def test_empty_mask_returns_a_copy() -> None:
    img = textured(30, 40)
    out = inpaint_telea(img, np.zeros((30, 40), bool), 3)
    assert np.array_equal(out, img) and out is not img


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    mask=arrays(np.bool_, st.tuples(st.integers(1, 24), st.integers(1, 24))),
    dtype=st.sampled_from([np.uint8, np.uint16, np.float32]),
    channels=st.sampled_from([1, 3, 4]),
    radius=st.integers(1, 8),
    seed=st.integers(0, 2**16),
)
def test_random_masks(mask: np.ndarray, dtype: type, channels: int, radius: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    h, w = mask.shape
    img: np.ndarray = rng.integers(0, 255, (h, w, channels)).astype(dtype)
    if mask.all():
        with pytest.raises(ValueError, match="mask"):
            inpaint_telea(img, mask, radius)
        return
    out = inpaint_telea(img, mask, radius)
    assert out.shape == img.shape and out.dtype == img.dtype
    assert np.array_equal(out[~mask], img[~mask])
    assert np.isfinite(out.astype(np.float64)).all()
    # A weighted mean never leaves the range of the known values.
    known = img[~mask]
    assert out.min() >= known.min() and out.max() <= known.max()


def test_bad_inputs_name_the_argument() -> None:
    img = np.zeros((10, 12, 3), np.uint8)
    mask = np.zeros((10, 12), bool)
    mask[3, 3] = True
    with pytest.raises(TypeError, match="img"):
        inpaint_telea(img.astype(np.int32), mask)
    with pytest.raises(TypeError, match="img"):
        inpaint_telea([[1, 2]], mask)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="img"):
        inpaint_telea(np.zeros((10, 12, 5), np.uint8), mask)
    with pytest.raises(TypeError, match="mask"):
        inpaint_telea(img, mask.astype(np.float32))
    with pytest.raises(ValueError, match="mask"):
        inpaint_telea(img, mask[:9])
    with pytest.raises(ValueError, match="mask"):
        inpaint_telea(img, np.ones((10, 12), bool))
    for r in (0, 101, float("nan")):
        with pytest.raises(ValueError, match="radius"):
            inpaint_telea(img, mask, r)
    # Without a mask the markers are extracted, which needs uint8: the advice says so (the
    # generic check's float32 would be refused next).
    import tacswitch as ts

    for dtype in (np.float64, np.float32):
        with pytest.raises(TypeError, match=r"^img: without a mask .* needs dtype uint8"):
            ts.remove_markers(img.astype(dtype))
    assert ts.remove_markers(img.astype(np.float32), mask).dtype == np.float32
    with pytest.raises(TypeError, match="radius"):
        inpaint_telea(img, mask, "3")  # type: ignore[arg-type]
    f = img.astype(np.float32)
    f[5, 5, 1] = np.nan
    with pytest.raises(ValueError, match="img"):
        inpaint_telea(f, mask)
    f[3, 3] = np.inf  # under the mask: fine, it gets replaced
    f[5, 5, 1] = 0
    assert np.isfinite(inpaint_telea(f, mask)).all()


def test_remove_markers_extracts_and_keeps_unmasked_pixels(gelsight_grid: np.ndarray) -> None:
    bg = sim.gel_background(480, 640, seed=1)
    img = sim.render_markers(bg, gelsight_grid, 23.0)
    clean = np.clip(np.rint(bg), 0, 255).astype(np.uint8)
    mask = tacswitch.extract_markers(img, dilate=2, exclude_border=False).mask
    for method in ("telea", "ns"):
        out = remove_markers(img, method=method)  # type: ignore[arg-type]
        assert out.dtype == np.uint8 and out.shape == img.shape
        assert np.array_equal(out[~mask], img[~mask])
        assert np.abs(out.astype(int) - clean)[mask].mean() < 3
    given_mask = remove_markers(img, mask=mask, radius=5)
    assert np.array_equal(given_mask, inpaint_telea(img, mask, 5))


def test_unknown_method_is_refused() -> None:
    img = np.zeros((8, 8, 3), np.uint8)
    with pytest.raises(ValueError, match="method"):
        remove_markers(img, np.zeros((8, 8), bool), method="nope")  # type: ignore[arg-type]


def test_remove_markers_also_removes_markers_cut_by_the_border() -> None:
    pts = np.array([[-2.0, 60.0], [100.0, 60.0], [159.0, 100.0]], np.float32)
    bg = sim.gel_background(120, 160, seed=0)
    with_markers = sim.render_markers(bg, pts, 12.0, darkness=0.8)
    truth = sim.render_markers(bg, pts[:0], 12.0)
    clean = remove_markers(with_markers)
    # Every marker, the two cut by the left and right borders included, is gone.
    err = np.abs(clean.astype(int) - truth.astype(int))
    assert err.max() < 25, err.max()
    assert np.abs(with_markers.astype(int) - truth.astype(int)).max() > 80


@pytest.mark.parametrize("preset", ["gelsight", "gelsight_mini"])
def test_default_mask_covers_the_soft_marker_edges(preset: str) -> None:
    # remove_markers' own mask (extracted, dilated DEFAULT_DILATE times) must leave no dark rim:
    # its error under the true marker footprint stays near that of the true mask, for TELEA and
    # for the biharmonic fill (which extrapolates a rim and fails far worse with one dilation).
    from tacswitch.metrics import masked_mae
    from tacswitch.sim.scene import render_sample

    s = render_sample(preset, 5)
    true = tacswitch.dilate_mask(s.marker_mask)
    for method in ("telea", "biharmonic"):
        ideal = masked_mae(remove_markers(s.image_markers, true, method=method), s.image, true)
        ours = masked_mae(remove_markers(s.image_markers, method=method), s.image, true)
        tight = masked_mae(remove_markers(s.image_markers, method=method, dilate=1), s.image,
                           true)
        assert ours < 1.3 * ideal, (method, ours, ideal)
        # TELEA: one dilation is within 1 % of the default on the GelSight render since the
        # simulator's press law was calibrated on real presses (markers move and stretch more);
        # the biharmonic fill still fails far worse with it.
        assert tight > (0.97 * ours if method == "telea" else ours), (method, tight, ours)
