"""The sparse variant of the ground-truth-free held-out check (realproxy.sparse_holdouts /
sparse_heldout_scores): a quarter of the shifted holes at a time."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from tacswitch import realproxy as R
from tacswitch.sim.markers import MarkerStyle, marker_grid, paint_markers


def _frame() -> np.ndarray:
    # A gel with shading (a flat one is filled exactly by every method).
    yy, xx = np.mgrid[0:200, 0:240]
    shade = 150 + 40 * np.sin(xx / 37.0) * np.cos(yy / 29.0)
    clean = np.repeat(shade[:, :, None], 3, axis=2).astype(np.uint8)
    centres = marker_grid(200, 240, 6, 7, 32.0)
    img, _ = paint_markers(clean, centres, MarkerStyle(texture=0, level_jitter=0))
    return img


def test_sets_split_the_holes_every_other_row_and_column() -> None:
    holdout, _ = R.shifted_holdout(_frame())
    sets = R.sparse_holdouts(holdout)
    assert len(sets) == 4
    union = np.zeros_like(holdout)
    for s in sets:
        assert not (union & s).any()
        union |= s
        n, _, _, c = cv2.connectedComponentsWithStats(s.astype(np.uint8), connectivity=8)
        c = c[1:]
        d = np.hypot(*(c[:, None] - c[None]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        # Two pitches apart along the grid (sqrt(2) pitch would be a diagonal neighbour).
        assert n - 1 >= 4 and d.min() > 1.9 * 32
    np.testing.assert_array_equal(union, holdout)
    assert len(R.sparse_holdouts(holdout, 1)) == 1


def test_sparse_scores_pool_the_sets() -> None:
    img = _frame()
    holdout, hidden = R.shifted_holdout(img)
    seen = []

    def fill(frame, extra):  # records what it is asked to fill
        seen.append(int(extra.sum()))
        # This set shows the markers copied onto it; the other sets show the true gel.
        np.testing.assert_array_equal(frame[extra], hidden[extra])
        np.testing.assert_array_equal(frame[~extra], img[~extra])
        return R.own_mask_fill("telea")(frame, extra)

    mae, signed = R.sparse_heldout_scores(img, fill, holdout, hidden)
    assert len(seen) == 4 and sum(seen) == holdout.sum()
    assert 0 < mae < 3 and abs(signed) < 3
    dense = R.heldout_scores(img, R.own_mask_fill("telea"), holdout, hidden,
                             R.threshold_mask(img))[0]
    assert mae != dense


def test_bad_arguments() -> None:
    holdout, _ = R.shifted_holdout(_frame())
    with pytest.raises(ValueError, match="phases"):
        R.sparse_holdouts(holdout, 0)
    with pytest.raises(ValueError, match="pitch"):
        R.sparse_holdouts(holdout, pitch=0.0)
    assert R.sparse_holdouts(np.zeros_like(holdout)) == []
