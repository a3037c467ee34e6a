"""tacswitch.tacdiff.prior: the grown-hole biharmonic prior that real rings cannot poison."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tacswitch.tacdiff import prior as P


def _holes(h: int = 80, w: int = 120, pitch: int = 20, r: int = 5) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    m = np.zeros((h, w), bool)
    for cy in range(10, h, pitch):
        for cx in range(10, w, pitch):
            m |= (x - cx) ** 2 + (y - cy) ** 2 <= r * r
    return m


def test_grow_holes_grows_each_hole_without_merging() -> None:
    m = _holes()
    n0 = cv2.connectedComponents(m.astype(np.uint8), connectivity=8)[0]
    for px in (2, 4, 9, 30):
        g = P.grow_holes(m, px)
        assert (g | m).sum() == g.sum() and g.sum() > m.sum()
        assert cv2.connectedComponents(g.astype(np.uint8), connectivity=8)[0] == n0, px
    d = cv2.distanceTransform((~m).astype(np.uint8), cv2.DIST_L2, 5)
    g4 = P.grow_holes(m, 4)
    assert (d[g4] <= 4).all() and ((d <= 3.5) & ~g4).sum() == 0  # only the walls stay out
    np.testing.assert_array_equal(P.grow_holes(m, 0), m)


def test_grown_biharmonic_ignores_a_dark_ring_plain_biharmonic_extrapolates() -> None:
    h, w = 80, 120
    y, x = np.mgrid[0:h, 0:w]
    clean = np.dstack([100 + 0.3 * x, 120 + 0.2 * y, 140 + 0.0 * x]).astype(np.float32)
    m = _holes(h, w)
    d = cv2.distanceTransform((~m).astype(np.uint8), cv2.DIST_L2, 5)
    # A dark ring 1-2 px wide around every hole, as soft rims and codec ringing leave it.
    img = clean - 12.0 * ((d > 0) & (d <= 2))[:, :, None]
    img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    truth = np.rint(clean).astype(np.uint8)
    _, plain = P.fills(img, m, "telea+biharmonic")
    _, grown = P.fills(img, m, "telea+biharmonic-grown")
    assert plain is not None and grown is not None
    err_plain = (plain[m].astype(float) - truth[m]).mean()
    err_grown = (grown[m].astype(float) - truth[m]).mean()
    assert err_plain < -6 and abs(err_grown) < 1.0
    np.testing.assert_array_equal(grown[~m], img[~m])
    prior, spread = P.prior_planes(img, m, "telea+biharmonic-grown")
    assert spread is not None and prior.shape == img.shape
    assert np.abs(spread[~m]).max() == 0


def test_prior_kinds() -> None:
    assert "telea+biharmonic-grown" in P.PRIORS
    assert P.has_spread("telea+biharmonic-grown") and not P.has_spread("telea")
    assert P.input_channels("telea+biharmonic-grown") == 13
    with pytest.raises(ValueError, match="prior"):
        P.check_prior("biharmonic")


def test_grown_prior_falls_back_when_the_grown_hole_is_too_large(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import tacswitch.inpaint as inp

    real = inp.inpaint_biharmonic
    m = _holes()
    limit = int(m.sum())

    def limited(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
        # Stands in for the solver's size limit (hit by huge holes only, slow to reach).
        if np.count_nonzero(mask) > limit:
            raise ValueError("mask: a hole of N pixels is too large for biharmonic inpainting")
        return real(img, mask)

    monkeypatch.setattr(P, "inpaint_biharmonic", limited)  # where prior.fills looks it up
    img = np.full((80, 120, 3), 120, np.uint8)
    _, smooth = P.fills(img, m, "telea+biharmonic-grown")
    assert smooth is not None
    np.testing.assert_array_equal(smooth, real(img, m))
