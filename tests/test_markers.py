"""Marker extraction: accuracy, robustness across sensors, agreement with OpenCV."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial import cKDTree

import tacswitch as ts
from conftest import disc_image
from tacswitch import sim


def nearest_errors(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    d, _ = cKDTree(found).query(truth)
    return d


def test_clean_discs_centre_error_below_0_1px(gelsight_grid: np.ndarray) -> None:
    img = disc_image(gelsight_grid, edge_px=1.0)
    m = ts.extract_markers(img)
    assert len(m) == 48
    assert nearest_errors(m.centres, gelsight_grid).max() <= 0.1


def test_noisy_discs_centre_error_below_0_3px(gelsight_grid: np.ndarray) -> None:
    img = disc_image(gelsight_grid, noise=3.0, seed=5)
    m = ts.extract_markers(img)
    assert len(m) == 48
    assert nearest_errors(m.centres, gelsight_grid).max() <= 0.3


@pytest.mark.parametrize("name", sorted(sim.PRESETS))
def test_every_preset_gives_every_marker_and_no_false_one(name: str) -> None:
    p = sim.get_preset(name)
    rest = sim.marker_grid(p.height, p.width, p.rows, p.cols, p.pitch, jitter=0.5, seed=1)
    img = sim.markers.render_preset(p, rest, seed=2)
    m = ts.extract_markers(img)
    inside = (rest[:, 0] > 2) & (rest[:, 0] < p.width - 3) & (rest[:, 1] > 2) & (
        rest[:, 1] < p.height - 3)
    d = nearest_errors(m.centres, rest[inside])
    assert d.max() < 0.5, f"{name}: a marker was missed or misplaced ({d.max():.2f} px)"
    back, _ = cKDTree(rest).query(m.centres)
    assert back.max() < 0.5, f"{name}: a false marker at {m.centres[back.argmax()]}"


def test_mini_markers_with_low_contrast_soft_edges() -> None:
    # GelSight Mini: dots keep 25-30 % of the background and have 2-3 px edges.
    p = sim.get_preset("gelsight_mini")
    rest = sim.marker_grid(p.height, p.width, p.rows, p.cols, p.pitch)
    bg = sim.gel_background(p.height, p.width, seed=4)
    for darkness in (0.7, 0.75):
        img = sim.render_markers(bg, rest, 10.0, darkness=darkness, edge_px=3.0, noise_sigma=2.0,
                                 seed=9)
        m = ts.extract_markers(img)
        assert len(m) == len(rest)
        assert nearest_errors(m.centres, rest).max() < 0.3
        assert np.all((m.contrast > 0.55) & (m.contrast < 0.85))


def test_lighting_changes_do_not_change_the_markers(gelsight_grid: np.ndarray) -> None:
    img = disc_image(gelsight_grid, noise=1.5).astype(np.float32)
    _h, w = img.shape[:2]
    ramp = np.linspace(0.45, 1.05, w, dtype=np.float32)[None, :, None]
    for variant in (img * 0.5, img * ramp, img * 0.8 + 30):
        m = ts.extract_markers(np.clip(variant, 0, 255).astype(np.uint8))
        assert len(m) == 48
        assert nearest_errors(m.centres, gelsight_grid).max() < 0.3


def test_bright_markers_need_bright_polarity() -> None:
    pts = sim.marker_grid(240, 320, 5, 7, 40.0)
    dark = sim.gel_background(240, 320, seed=0) * 0.3
    img = sim.render_markers(dark, pts, 10.0, darkness=-2.0, edge_px=1.5)
    assert len(ts.extract_markers(img)) == 0
    m = ts.extract_markers(img, polarity="bright")
    assert len(m) == len(pts)
    assert nearest_errors(m.centres, pts).max() < 0.2


def test_markerless_images_give_no_markers() -> None:
    rng = np.random.default_rng(0)
    bg = sim.gel_background(480, 640, seed=1)
    for img in (
        np.zeros((480, 640, 3), np.uint8),
        np.full((480, 640, 3), 255, np.uint8),
        np.clip(bg + rng.normal(0, 2, bg.shape), 0, 255).astype(np.uint8),
    ):
        m = ts.extract_markers(img)
        assert len(m) == 0
        assert not m.mask.any()


def test_threshold_override_and_outputs() -> None:
    pts = np.array([[100.3, 80.7], [200.0, 150.0]], np.float32)
    img = disc_image(pts, shape=(240, 320), diameter=14)
    m = ts.extract_markers(img, threshold=40)
    assert m.threshold == 40
    assert m.centres.dtype == np.float32 and m.centres.shape == (2, 2)
    assert m.bboxes.shape == (2, 4) and m.areas.shape == (2,)
    assert m.mask.dtype == np.bool_ and m.mask.shape == (240, 320)
    # Boxes contain the centres; the mask holds exactly the areas.
    for (x, y), (bx, by, bw, bh) in zip(m.centres, m.bboxes, strict=True):
        assert bx <= x <= bx + bw - 1 and by <= y <= by + bh - 1
    assert m.mask.sum() == m.areas.sum()


def test_mask_dilation_matches_opencv_3x3_ellipse(gelsight_grid: np.ndarray) -> None:
    img = disc_image(gelsight_grid)
    base = ts.extract_markers(img)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    for k in (1, 2):
        ours = ts.extract_markers(img, dilate=k).mask
        ref = cv2.dilate(base.mask.astype(np.uint8), kernel, iterations=k).astype(bool)
        np.testing.assert_array_equal(ours, ref)


def test_components_match_opencv_labelling(gelsight_grid: np.ndarray) -> None:
    img = disc_image(gelsight_grid, noise=2.0)
    m = ts.extract_markers(img)
    n, _labels, stats, _ = cv2.connectedComponentsWithStats(m.mask.astype(np.uint8), connectivity=8)
    assert n - 1 == len(m)
    cv_boxes = sorted(tuple(int(v) for v in s[:4]) for s in stats[1:])
    ours = sorted(tuple(int(v) for v in b) for b in m.bboxes)
    assert cv_boxes == ours
    assert sorted(stats[1:, 4].tolist()) == sorted(m.areas.tolist())


def test_same_markers_as_the_opencv_chain(gelsight_grid: np.ndarray) -> None:
    """The benchmark's peer (grey -> blur difference -> threshold -> components) finds the same."""
    img = disc_image(gelsight_grid, noise=1.5)
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.int16)
    blur = cv2.GaussianBlur(grey.astype(np.float32), (0, 0), 15).astype(np.int16)
    binary = ((blur - grey) > 40).astype(np.uint8)
    _, _, stats, cents = cv2.connectedComponentsWithStats(binary, connectivity=8)
    cv_centres = cents[1:][stats[1:, 4] > 30]
    ours = ts.extract_markers(img).centres
    assert len(cv_centres) == len(ours) == 48
    assert nearest_errors(ours, cv_centres).max() < 1.0


def test_dense_grid_265_markers() -> None:
    p = sim.get_preset("dense")
    img = sim.markers.render_preset(p, seed=3)
    m = ts.extract_markers(img)
    assert len(m) == p.rows * p.cols == 266


def test_markers_cut_by_the_border() -> None:
    pts = np.array([[-3.0, 60.0], [160.0, 60.0], [318.0, 120.0], [160.0, 238.5]], np.float32)
    img = disc_image(pts, shape=(240, 320), diameter=12)
    m = ts.extract_markers(img)
    # Centre outside (-3) dropped; inside but cut (318, 238.5) kept; interior kept.
    assert len(m) == 3
    assert nearest_errors(m.centres, pts[1:]).max() < 1.5
    assert len(ts.extract_markers(img, exclude_border=False)) == 4


def test_dilate_mask_matches_opencv() -> None:
    rng = np.random.default_rng(1)
    mask = rng.random((37, 53)) > 0.97
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    for k in (0, 1, 3):
        ref = cv2.dilate(mask.astype(np.uint8), kernel, iterations=k).astype(bool)
        np.testing.assert_array_equal(ts.dilate_mask(mask, k), ref)
    with pytest.raises(ValueError, match="mask"):
        ts.dilate_mask(np.zeros((2, 2, 2), bool))
