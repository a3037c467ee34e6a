"""tacswitch.realproxy: real markerless frames with painted markers, scores, held-out check."""

from __future__ import annotations

import numpy as np
import pytest

from tacswitch import realproxy as R
from tacswitch.sim.markers import MarkerStyle, marker_grid, paint_markers

pytest.importorskip("taxim")


@pytest.fixture(scope="module")
def mini_frames() -> list[R.ProxyFrame]:
    return R.proxy_frames("gelsight_mini", 1, styles=("painted", "crisp"),
                          captures=("lossless", "mjpeg"), seed=1)


def test_proxy_frames_are_real_presses_with_painted_markers(
        mini_frames: list[R.ProxyFrame]) -> None:
    _, presses = R.load_presses("gelsight_mini", 1)
    assert len(mini_frames) == 4
    names = [f.name for f in mini_frames]
    assert names[0] == "gelsight_mini/0/painted/lossless" and names[-1].endswith("crisp/mjpeg")
    for f in mini_frames:
        assert f.img.shape == f.clean.shape == (240, 320, 3)
        np.testing.assert_array_equal(f.clean, presses[0][0])
        assert f.contact.any() and f.footprint.sum() > 50 * 60
        # Markers darken their footprint; the rest is the clean frame up to the codec.
        assert f.img[f.footprint].mean() < f.clean[f.footprint].mean() - 15
        off = ~f.footprint
        assert np.abs(f.img[off].astype(int) - f.clean[off]).mean() < 3.0
    lossless = mini_frames[0]
    np.testing.assert_array_equal(lossless.img[~lossless.footprint],
                                  lossless.clean[~lossless.footprint])
    again = R.proxy_frames("gelsight_mini", 1, styles=("painted",), captures=("mjpeg",), seed=1)
    np.testing.assert_array_equal(again[0].img, mini_frames[1].img)


def test_perfect_fill_scores_zero_and_identity_scores_the_markers(
        mini_frames: list[R.ProxyFrame]) -> None:
    f = mini_frames[0]
    mae, signed, ghosts = R.score(f.clean, f)
    assert mae == 0 and signed == 0 and np.abs(ghosts).max() < 1e-4
    s = R.evaluate(mini_frames[:1], lambda img, extra: img)
    assert s.mae > 15 and s.signed < -15 and s.ghost < -15
    assert s.mae == pytest.approx(R.score(f.img, f)[0])


def test_ghost_sees_a_dark_hole_and_subtracts_real_shading() -> None:
    y, x = np.mgrid[0:100, 0:100]
    clean = np.dstack([120 + 0.5 * x] * 3).astype(np.uint8)
    holes = np.zeros((100, 100), bool)
    for cx, cy in ((30, 30), (70, 30), (30, 70), (70, 70)):
        holes |= (x - cx) ** 2 + (y - cy) ** 2 <= 25
    out = clean.copy()
    out[holes] -= 3
    g = R.ghost_per_marker(out, holes, clean)
    assert g.shape == (4,) and np.allclose(g, -3, atol=0.05)
    # A linear gradient cancels in the hole - ring difference even without the clean frame.
    assert np.abs(R.ghost_per_marker(clean, holes)).max() < 0.3
    with pytest.raises(ValueError, match="holes"):
        R.ghost_per_marker(out, holes[:50])


def test_shifted_holdout_lies_on_bare_gel_and_hides_it() -> None:
    clean = np.full((160, 200, 3), 170, np.uint8)
    centres = marker_grid(160, 200, 4, 5, 36.0)
    img, fp = paint_markers(clean, centres, MarkerStyle(texture=0, level_jitter=0))
    holdout, hidden = R.shifted_holdout(img)
    assert holdout.sum() > 10 * 50
    assert not (holdout & fp).any()
    np.testing.assert_array_equal(hidden[~holdout], img[~holdout])
    assert hidden[holdout].mean() < img[holdout].mean() - 40  # a marker is shown there
    mae, signed, ghosts = R.heldout_scores(img, R.own_mask_fill("telea"), holdout, hidden,
                                           R.threshold_mask(img))
    assert mae < 3 and abs(signed) < 3 and ghosts.size >= 12


def test_methods_fill_with_their_own_masks(mini_frames: list[R.ProxyFrame]) -> None:
    from tacswitch.inpaint import DEFAULT_RADIUS

    ms = R.methods((3, 8), models=False, priors=("telea",))
    assert f"TELEA default r={DEFAULT_RADIUS} (own mask)" in ms
    assert "TELEA r=3, previous default (own mask)" in ms
    assert "OpenCV TELEA r=8 (1-dilation threshold mask)" in ms
    f = mini_frames[0]
    for name, fill in ms.items():
        out = fill(f.img, None)
        assert out.shape == f.img.shape and out.dtype == np.uint8, name
        assert R.score(out, f)[0] < 0.2 * R.score(f.img, f)[0], name


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="sensor"):
        R.load_presses("digit")
    with pytest.raises(ValueError, match="styles"):
        R.proxy_frames("gelsight_mini", 1, styles=("glossy",))
    with pytest.raises(ValueError, match="captures"):
        R.proxy_frames("gelsight_mini", 1, captures=("vhs",))
    with pytest.raises(ValueError, match="img"):
        R.shifted_holdout(np.full((50, 50, 3), 128, np.uint8))


def test_tradeoff_proxy_rows() -> None:
    from tacswitch import tradeoff

    frames = tradeoff.proxy_frames(1, "gelsight_mini", cases=(("painted", "h264"),))
    assert len(frames) == 1
    f = frames[0]
    assert f.score is not None and f.scored is f.score and f.mask.any()
    methods = tradeoff.default_methods((3,), opencv=False)
    rows = tradeoff.evaluate(frames, methods, rounds=1)
    assert {r.method for r in rows} == {"TELEA (tacswitch)", "biharmonic (tacswitch)"}
    assert all(0 < r.mae < 20 for r in rows)
    assert "| TELEA (tacswitch) | r=3 |" in tradeoff.markdown(rows)


def test_bench_cli_rejects_negative_real() -> None:
    from tacswitch.cli import main

    assert main(["bench", "--real", "-1", "--quick", "-q", "-o", "/nonexistent/never"]) != 0


def test_radial_profile_of_painted_dots() -> None:
    gel = np.full((120, 160, 3), 180, np.uint8)
    centres = marker_grid(120, 160, 3, 4, 36.0)
    img, _ = paint_markers(gel, centres, MarkerStyle(texture=0, level_jitter=0, halo=0))
    p = R.radial_profile(img, centres, radii=12)
    assert p.shape == (12,)
    assert 0.25 < p[0] < 0.30 and p[11] == pytest.approx(1.0, abs=0.01)
    assert np.all(np.diff(p) >= -1e-3)  # rises monotonically from the centre
    with pytest.raises(ValueError, match="centres"):
        R.radial_profile(img, np.array([[1.0, 1.0]]))
