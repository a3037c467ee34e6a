"""Physically grounded simulator: pairing invariants, determinism, marker ground truth, optics."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

import tacswitch as ts
from tacswitch import sim
from tacswitch.sim import deform, optics


def _same(a: sim.Sample, b: sim.Sample) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in
               ("image", "image_markers", "reference", "marker_mask", "contact_mask",
                "displacement", "rest")) and a.params == b.params


def test_deterministic_by_seed() -> None:
    a = sim.render_sample("gelsight_mini", 11)
    b = sim.render_sample("gelsight_mini", 11)
    c = sim.render_sample("gelsight_mini", 12)
    assert _same(a, b)
    assert not np.array_equal(a.image, c.image)


@pytest.mark.parametrize(("preset", "label", "jpeg"), [
    ("gelsight_mini", "plain_weave", None), ("gelsight_mini", "star", 85),
    ("digit", "sphere", None), ("gelsight", "knurl", None)])
def test_pair_differs_only_under_marker_mask(preset: str, label: str, jpeg: int | None) -> None:
    s = sim.render_sample(preset, 3, label=label, jpeg_quality=jpeg)
    assert s.image.shape == s.image_markers.shape == (*s.marker_mask.shape, 3)
    assert np.array_equal(s.image[~s.marker_mask], s.image_markers[~s.marker_mask])
    # Markers darken: under the dot centres I_w is clearly darker than I_wo.
    pos = np.rint(s.rest + s.displacement).astype(int)[s.present]
    inside = (pos[:, 0] >= 0) & (pos[:, 0] < s.image.shape[1]) & (pos[:, 1] >= 0) & (
        pos[:, 1] < s.image.shape[0])
    x, y = pos[inside].T
    ratio = s.image_markers[y, x].mean(1) / np.maximum(s.image[y, x].mean(1), 1)
    assert 0.15 < np.median(ratio) < 0.4  # real dots keep ~0.25-0.30 of the background
    if label != "none":
        assert s.contact_mask.any()


@pytest.mark.parametrize(("preset", "seed", "label"), [
    ("gelsight", 1, "sphere"), ("gelsight", 2, "twill"), ("gelsight_mini", 3, "sphere"),
    ("gelsight_mini", 4, "corduroy"), ("gelsight_mini", 5, "hex"), ("digit", 6, "box")])
def test_extraction_finds_rendered_markers_within_0p3_px(preset: str, seed: int,
                                                         label: str) -> None:
    s = sim.render_sample(preset, seed, label=label)
    h, w = s.marker_mask.shape
    gt = s.rest + s.displacement
    d = s.params["marker_diameter"]
    keep = s.present & ~s.merged & (gt[:, 0] > d) & (gt[:, 0] < w - 1 - d) & (gt[:, 1] > d) & (
        gt[:, 1] < h - 1 - d)
    found = ts.extract_markers(s.image_markers)
    motion, valid = ts.match_markers(gt[keep], found.centres)
    assert valid.mean() >= 0.9
    err = np.hypot(*motion[valid].T)
    assert np.median(err) < 0.15
    assert np.percentile(err, 95) < 0.3


def test_shear_partial_slip_and_displacement_scale() -> None:
    scene = sim.Scene("gelsight_mini", 7, label="sphere")
    rest = scene.render(0, shear_px=(0.0, 0.0), load_ratio=0.0)
    low = scene.render(0, shear_px=(10.0, 0.0), load_ratio=0.2)
    high = scene.render(0, shear_px=(10.0, 0.0), load_ratio=0.9)
    # The stuck zone shrinks from the edge as the load approaches friction.
    assert 1.0 >= low.stick_fraction > high.stick_fraction > 0.0
    move = low.displacement - rest.displacement
    assert 8.0 < move[:, 0].max() < 14.0          # stuck markers follow the object
    assert abs(np.median(move[:, 1])) < 1.0
    # Far markers barely move (finite-thickness cutoff).
    far = np.hypot(*(scene.rest - np.asarray(scene.centre)).T) > 4 * scene.pitch
    if far.any():
        assert np.abs(move[far]).max() < 2.0


def test_press_dilates_outward() -> None:
    scene = sim.Scene("gelsight", 2, label="sphere")
    f = scene.render(0, depth=1.0)
    rel = scene.rest - np.asarray(scene.centre)
    r = np.hypot(*rel.T)
    near = (r > 0.3 * scene.pitch) & (r < 2 * scene.pitch)
    radial = (f.displacement[near] * rel[near]).sum(1) / r[near]
    assert (radial > 0).mean() > 0.8


def _ball(h: int, w: int, mmpx: float, cx: float, cy: float, a_px: float, radius_mm: float = 2.0
          ) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    a = a_px * mmpx
    depth = radius_mm - np.sqrt(radius_mm**2 - a * a)
    r2 = ((x - cx) ** 2 + (y - cy) ** 2) * mmpx**2
    cap = radius_mm - np.sqrt(np.maximum(radius_mm**2 - r2, 0))
    return np.where(r2 < radius_mm**2, depth - cap, -np.inf).astype(np.float32)


def test_shipped_calibration_contact_brightness() -> None:
    cal = optics.load_calibration("gelsight")
    gel, _ = deform.deform_gel(_ball(480, 640, cal.pixmm, 320, 240, 62), cal.pixmm)
    d = optics.shade_taxim(gel, cal.pixmm, cal)
    lo, hi = d.reshape(-1, 3).min(0), d.reshape(-1, 3).max(0)
    assert np.all(lo < -25) and np.all(lo > -90)
    assert np.all(hi > 25) and np.all(hi < 90)
    assert np.abs(optics.shade_taxim(np.zeros((48, 64), np.float32), 0.3, cal)).max() == 0


@pytest.mark.skipif(importlib.util.find_spec("taxim") is None, reason="taxim not installed")
def test_contact_brightness_matches_real_taxim_presses() -> None:
    from pathlib import Path

    import cv2
    import taxim  # only its data files are read

    data = np.load(Path(taxim.__file__).parent / "calib/gelsight/dataPack.npz")
    f0 = cv2.GaussianBlur(data["f0"].astype(np.float32), (0, 0), 2)
    cal = optics.load_calibration("gelsight")
    yy, xx = np.mgrid[0:480, 0:640]
    for i in (0, 10, 20, 30, 40):
        (cx, cy), a = data["touch_center"][i], float(data["touch_radius"][i])
        real = cv2.GaussianBlur(data["imgs"][i].astype(np.float32), (0, 0), 2) - f0
        gel, _ = deform.deform_gel(_ball(480, 640, cal.pixmm, cx, cy, a), cal.pixmm)
        simd = optics.shade_taxim(gel, cal.pixmm, cal)
        m = (xx - cx) ** 2 + (yy - cy) ** 2 < (1.5 * a) ** 2
        for c in range(3):  # BGR, same channel order as the real frames
            assert np.corrcoef(simd[..., c][m], real[..., c][m])[0, 1] > 0.85
            for ext in (np.min, np.max):
                ratio = ext(simd[..., c][m]) / ext(real[..., c][m])
                assert 0.5 < ratio < 1.4, (i, c, ext.__name__, ratio)


def test_phong_fallback_and_classes() -> None:
    for label in sim.CLASSES:
        s = sim.render_sample("gelsight_mini", 0, label=label, optics="phong")
        assert s.label == label
        assert s.params["optics"] == "phong"
        assert s.contact_mask.any() == (label != "none")
    with pytest.raises(ValueError, match="optics"):
        sim.Scene("digit", 0, optics="taxim")


def test_grasp_sequence_labels() -> None:
    slip = sim.render_grasp("gelsight_mini", "slip", n_frames=12, seed=1, label="sphere")
    hold = sim.render_grasp("gelsight_mini", "hold", n_frames=12, seed=1, label="sphere")
    assert len(slip) == len(hold) == 12
    assert not any(hold.slip) and any(slip.slip) and not any(slip.slip[: slip.grasp_start])
    base = slip.frames[slip.grasp_start]
    # The object slides on while the markers stay near saturation.
    off = np.asarray(slip.object_offset)
    assert np.hypot(*(off[-1] - off[slip.grasp_start])) > 2.0
    hold_move = max(np.abs(f.displacement - hold.frames[hold.grasp_start].displacement).max()
                    for f in hold.frames[hold.grasp_start:])
    assert hold_move < 0.05
    for f in slip.frames:
        assert np.array_equal(f.image[~f.marker_mask], f.image_markers[~f.marker_mask])
    assert base.image.shape == (240, 320, 3)


# --- gel-attached grain (issue 15): measured on real presses, carried by the gel's motion -------


def _hp(img: np.ndarray, sigma: float = 2.0) -> np.ndarray:
    import cv2

    g = img.astype(np.float32).mean(-1)
    return g - cv2.GaussianBlur(g, (0, 0), sigma)


@pytest.mark.parametrize("name", ["gelsight", "gelsight_mini"])
def test_grain_statistics_in_the_range_measured_on_real_presses(name: str) -> None:
    """No-contact frames of a scene at the real frames' scale (640 x 480, 0.0295 mm/px): the
    fixed pattern's strength and the shape of its radial spectrum match the real presses'."""
    import dataclasses

    from tacswitch.sim import grain

    p = dataclasses.replace(sim.get_preset(name), height=480, width=640, mm_per_px=0.0295)
    real = np.log(np.asarray(grain.REAL_RADIAL_PSD[name])[1:7])
    for seed in (0, 1):
        sc = sim.Scene(p, seed, label="none", appearance="random")
        frames = np.stack([sc.render(k).image for k in range(4)])
        s = grain.measure_grain(frames)
        # Real: fixed pattern 0.27 / 0.36 grey levels, correlation 0.19 / 0.41 between frames.
        assert 0.18 < s.fixed_std < 0.6, s
        assert 0.05 < s.corr < 0.5, s
        assert np.corrcoef(np.log(s.radial_psd[1:7]), real)[0, 1] > 0.97, s.radial_psd
    # Without the grain layer the fixed pattern is (nearly) gone: the statistic can fail.
    sc = sim.Scene(p, 0, label="none", appearance="random", grain=False)
    s = grain.measure_grain(np.stack([sc.render(k).image for k in range(4)]))
    assert s.fixed_std < 0.15, s


@pytest.mark.skipif(importlib.util.find_spec("taxim") is None, reason="taxim not installed")
def test_grain_constants_are_the_real_measurement() -> None:
    from tacswitch.sim import grain

    imgs, use = grain.taxim_presses("gelsight_mini")
    s = grain.measure_grain(imgs, use)
    assert 0.3 < s.fixed_std < 0.42 and 0.3 < s.corr < 0.5
    np.testing.assert_allclose(s.radial_psd, grain.REAL_RADIAL_PSD["gelsight_mini"], rtol=0.02,
                               atol=2e-4)


def test_grain_moves_with_the_displacement_field() -> None:
    """Away from the contact (no shading), frame t's grain is the rest grain carried by the
    field: warped by it, the rest frame's high-pass matches; unwarped, it does not."""
    import cv2

    from tacswitch.sim import grain

    sc = sim.Scene("gelsight_mini", 3, label="sphere")
    sc.noise_sigma[:] = 0.0
    rest = sc.render(0, depth=0.0)
    f = sc.render(0, shear_px=(8.0, 3.0), load_ratio=0.2)
    assert f.field is not None and rest.field is not None
    assert np.abs(rest.field).max() == 0
    a, b = _hp(rest.image), _hp(f.image)
    near = cv2.dilate(f.contact_mask.astype(np.uint8), np.ones((31, 31), np.uint8)) > 0
    m = ~near & (np.hypot(f.field[..., 0], f.field[..., 1]) > 1.0)
    m[:10], m[-10:], m[:, :10], m[:, -10:] = False, False, False, False
    assert m.sum() > 1000
    moved = grain.warp_layer(a, f.field)
    c_moved = np.corrcoef(moved[m], b[m])[0, 1]
    c_fixed = np.corrcoef(a[m], b[m])[0, 1]
    assert c_moved > 0.7 and c_moved > c_fixed + 0.2, (c_moved, c_fixed)
    # The markers and the field agree: the field at a marker's rest centre is its displacement.
    xy = np.round(sc.rest).astype(int)
    ok = (xy[:, 0] >= 0) & (xy[:, 0] < 320) & (xy[:, 1] >= 0) & (xy[:, 1] < 240)
    fd = f.field[xy[ok, 1], xy[ok, 0]]
    assert np.abs(fd - f.displacement[ok]).max() < 0.35


def test_random_appearance_differs_and_keeps_pairing() -> None:
    a = sim.render_sample("gelsight_mini", 5, label="sphere")
    b = sim.render_sample("gelsight_mini", 5, label="sphere", appearance="random")
    assert b.params["appearance"] == "random" and b.params["look"]
    assert np.abs(a.image.astype(float).mean((0, 1)) - b.image.astype(float).mean((0, 1))).max() > 1
    assert np.array_equal(b.image[~b.marker_mask], b.image_markers[~b.marker_mask])
    with pytest.raises(ValueError, match="appearance"):
        sim.Scene("gelsight_mini", 0, appearance="odd")  # type: ignore[arg-type]
