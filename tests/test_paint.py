"""tacswitch.sim.markers.paint_markers: realistic markers on any clean frame."""

from __future__ import annotations

import numpy as np
import pytest

from tacswitch.sim.markers import (
    FOOTPRINT_LEVEL,
    MarkerStyle,
    marker_grid,
    paint_markers,
    sample_style,
)


def _clean(h: int = 120, w: int = 160) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.stack([140 + 40 * x / w, 160 + 20 * y / h, 180 - 30 * x / w], axis=2)
    return np.rint(img).astype(np.uint8)


def _ratio_at(img: np.ndarray, clean: np.ndarray, x: float, y: float) -> float:
    iy, ix = round(y), round(x)
    return float(img[iy, ix].astype(float).sum() / clean[iy, ix].astype(float).sum())


def test_painted_and_pasted_centre_levels() -> None:
    clean = _clean()
    c = np.array([[80.0, 60.0]])
    painted, _ = paint_markers(clean, c, MarkerStyle(texture=0, level_jitter=0))
    pasted, _ = paint_markers(clean, c, MarkerStyle(kind="pasted", darkness=1.0, edge_px=2.0,
                                                    halo=0.0, texture=0, level_jitter=0))
    assert 0.25 <= _ratio_at(painted, clean, 80, 60) <= 0.30
    assert _ratio_at(pasted, clean, 80, 60) < 0.01
    # The rim is soft: half way at the radius, not a step.
    r = MarkerStyle().diameter / 2
    assert 0.35 < _ratio_at(painted, clean, 80 + r, 60) < 0.75


def test_footprint_is_every_changed_pixel_and_clean_untouched() -> None:
    clean = _clean()
    before = clean.copy()
    centres = marker_grid(120, 160, 3, 4, 36.0)
    img, fp = paint_markers(clean, centres, MarkerStyle(), rng=0)
    np.testing.assert_array_equal(clean, before)
    change = np.abs(img.astype(int) - clean).max(axis=2)
    assert fp.dtype == np.bool_ and fp.shape == clean.shape[:2]
    assert (change[~fp] <= 1).all()  # outside: at most the rounding of <= 0.5 levels
    assert (change[fp] >= 1).mean() > 0.95
    # The halo and soft rim reach past the 50 % disc.
    disc_area = np.pi * (MarkerStyle().diameter / 2) ** 2 * len(centres)
    assert fp.sum() > 1.3 * disc_area
    assert FOOTPRINT_LEVEL == 0.5


def test_displacement_moves_markers_and_border_markers_are_cut() -> None:
    clean = _clean()
    c = np.array([[50.0, 50.0], [0.0, 60.0]])  # the second one is cut by the left border
    a, fa = paint_markers(clean, c, MarkerStyle(texture=0, level_jitter=0))
    b, fb = paint_markers(clean, c, MarkerStyle(texture=0, level_jitter=0),
                          displacement=np.array([[10.0, 0.0], [0.0, 0.0]]))
    assert _ratio_at(b, clean, 60, 50) < 0.35 < _ratio_at(a, clean, 60, 50)
    assert fa[60, 0] and fb[60, 0]
    # Same dots elsewhere on the gel: the footprint differs only by the local gel level.
    assert abs(int(fa.sum()) - int(fb.sum())) < 0.03 * fa.sum()


def test_grey_frames_and_seeded_texture() -> None:
    clean = _clean()[:, :, 1].copy()
    c = marker_grid(120, 160, 2, 2, 50.0)
    a, _ = paint_markers(clean, c, rng=3)
    b, _ = paint_markers(clean, c, rng=3)
    d, _ = paint_markers(clean, c, rng=4)
    assert a.shape == clean.shape
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, d)


def test_sample_style_ranges() -> None:
    kinds = set()
    for s in range(30):
        st = sample_style(s, diameter=20.0)
        kinds.add(st.kind)
        assert 18.0 <= st.diameter <= 22.0
        if st.kind == "painted":
            assert 0.70 <= st.darkness <= 0.75
        else:
            assert st.darkness >= 0.95 and st.texture == 0
        assert 1.2 <= st.edge_px <= 3.0
    assert kinds == {"pasted", "painted"}
    assert sample_style(0, kind="pasted").kind == "pasted"


@pytest.mark.parametrize("kwargs, name", [
    ({"kind": "inked"}, "kind"),
    ({"darkness": 1.5}, "darkness"),
    ({"edge_px": 0.0}, "edge_px"),
    ({"diameter": -3.0}, "diameter"),
    ({"halo": -0.1}, "halo"),
])
def test_bad_style_names_the_field(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        MarkerStyle(**kwargs)


def test_bad_input_errors() -> None:
    c = np.array([[10.0, 10.0]])
    with pytest.raises(TypeError, match="clean"):
        paint_markers(_clean().astype(np.float32), c)
    with pytest.raises(ValueError, match="clean"):
        paint_markers(np.zeros((8, 8, 4), np.uint8), c)
    with pytest.raises(ValueError, match="centres"):
        paint_markers(_clean(), np.zeros((3,)))
    with pytest.raises(ValueError, match="displacement"):
        paint_markers(_clean(), c, displacement=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="diameters"):
        paint_markers(_clean(), c, diameters=np.array([-1.0]))
    with pytest.raises(TypeError, match="style"):
        paint_markers(_clean(), c, "painted")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="kind"):
        sample_style(0, kind="inked")  # type: ignore[arg-type]
