"""TacDiff fills crowded holes in separate passes (``inpaint_tacdiff(separation=...)``,
:mod:`tacswitch.tacdiff.passes`): the passes, the one-pass fast path, crowded holes, arguments."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tacswitch as ts
from conftest import disc_mask
from tacswitch import sim
from tacswitch.tacdiff.infer import SEPARATION, inpaint_tacdiff
from tacswitch.tacdiff.passes import hole_passes, pass_masks


def _cheb(a: np.ndarray, b: np.ndarray) -> int:
    """Chebyshev distance between the nearest pixels of two ``N x 2`` pixel sets."""
    return int(np.abs(a[:, None, :] - b[None, :, :]).max(axis=2).min())


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), density=st.floats(0.02, 0.4),
       separation=st.integers(0, 7))
def test_no_two_holes_of_one_pass_are_within_separation(seed, density, separation):
    m = np.random.default_rng(seed).random((18, 22)) < density
    labels, pass_of = hole_passes(m, separation)
    n, ref = cv2.connectedComponents(m.astype(np.uint8), connectivity=8)
    assert np.array_equal(labels, ref) and len(pass_of) == n
    assert (pass_of[1:] >= 0).all() and pass_of[0] == -1
    masks = pass_masks(labels, pass_of)
    assert all(pm.any() for pm in masks)  # passes numbered without gaps
    union = np.zeros_like(m)
    for pm in masks:
        assert not (union & pm).any()
        union |= pm
    assert np.array_equal(union, m)
    pix = {i: np.argwhere(labels == i) for i in range(1, n)}
    for i in range(1, n):
        near = [j for j in range(1, n) if j != i and _cheb(pix[i], pix[j]) <= separation]
        # Never a neighbour in the same pass...
        assert all(pass_of[j] != pass_of[i] for j in near)
        # ... and greedy: a hole in pass c has an earlier neighbour in every pass below c.
        earlier = {int(pass_of[j]) for j in near if j < i}
        assert set(range(int(pass_of[i]))) <= earlier


def test_a_marker_grid_is_one_pass(gelsight_grid):
    m = disc_mask((480, 640), gelsight_grid.tolist(), 13.0)  # 48 holes of 27 px, pitch ~ 75
    _, pass_of = hole_passes(m, SEPARATION)
    assert len(pass_of) == 49 and pass_of.max() == 0


@pytest.mark.parametrize("sensor", ["gelsight", "gelsight_mini"])
def test_real_presses_with_painted_markers_are_one_pass(sensor):
    # Real taxim frames with markers painted at the sensor's pitch, masked as remove_markers
    # does (adaptive growth): the usual grid never triggers a second pass.
    from tacswitch import realproxy as R

    for f in R.proxy_frames(sensor, 2, styles=("painted", "crisp"), captures=("lossless",)):
        _, pass_of = hole_passes(R.default_mask(f.img), SEPARATION)
        assert len(pass_of) > 40 and pass_of.max() == 0, f.name


def test_close_pair_is_split_and_far_pair_is_not():
    m = np.zeros((40, 60), bool)
    m[10:15, 10:15] = True
    m[10:15, 22:27] = True  # Chebyshev distance 8 (7 px of gel between): within 8
    _, pass_of = hole_passes(m, 8)
    assert sorted(pass_of[1:].tolist()) == [0, 1]
    _, pass_of = hole_passes(m, 7)  # 8 > 7: one pass
    assert pass_of[1:].tolist() == [0, 0]


def _smooth_gel(h: int, w: int, seed: int) -> np.ndarray:
    return np.clip(sim.gel_background(h, w, seed=seed), 0, 255).astype(np.uint8)


def _dots(h: int, w: int, pitch: float, r: float, seed: int) -> np.ndarray:
    off = np.random.default_rng(seed).uniform(0, pitch, 2)
    cs = [(x, y) for y in np.arange(off[1], h, pitch) for x in np.arange(off[0], w, pitch)]
    return disc_mask((h, w), cs, r)


def test_sparse_grid_output_equals_one_pass():
    img = _smooth_gel(96, 128, 1)
    m = _dots(96, 128, 40.0, 5.0, 1)  # gaps of ~29 px
    a = inpaint_tacdiff(img, m, model="fast")
    b = inpaint_tacdiff(img, m, model="fast", separation=0)
    assert np.array_equal(a, b)


@pytest.mark.parametrize("seed", [0, 2])
def test_crowded_dots_are_filled_in_passes_and_closer_to_truth(seed):
    # Smooth gel with dots every 11 px (2-3 px of gel between them, 38 % of the frame masked):
    # every hole's context holds other holes, as on the shifted held-out check.
    truth = _smooth_gel(96, 128, seed)
    m = _dots(96, 128, 11.0, 4.0, seed)
    _, pass_of = hole_passes(m, SEPARATION)
    assert pass_of.max() >= 1  # 2-3 px of gel between row and column neighbours
    img = truth.copy()
    img[m] = 40  # markers: the network never reads the pixels under its mask
    sep = inpaint_tacdiff(img, m, model="fast")
    one = inpaint_tacdiff(img, m, model="fast", separation=0)
    assert not np.array_equal(sep, one)
    err_sep = np.abs(sep.astype(float) - truth)[m].mean()
    err_one = np.abs(one.astype(float) - truth)[m].mean()
    assert err_sep < 0.8 * err_one
    # Deterministic, and the known pixels bit-identical.
    assert np.array_equal(sep, inpaint_tacdiff(img, m, model="fast"))
    assert np.array_equal(sep[~m], img[~m])


def test_remove_markers_tacdiff_uses_the_passes():
    truth = _smooth_gel(64, 96, 3)
    m = _dots(64, 96, 11.0, 4.0, 3)
    img = truth.copy()
    img[m] = 40
    out = ts.remove_markers(img, m, method="tacdiff", model="fast")
    assert np.array_equal(out, inpaint_tacdiff(img, m, model="fast"))
    one = inpaint_tacdiff(img, m, model="fast", separation=0)
    assert not np.array_equal(out, one)
    # remove_markers(separation=...) and the CLI's --separation reach it.
    assert np.array_equal(ts.remove_markers(img, m, method="tacdiff", model="fast",
                                            separation=0), one)
    with pytest.raises(ValueError, match=r"^separation: "):
        ts.remove_markers(img, m, method="tacdiff", model="fast", separation=-1)


def test_remove_markers_cli_separation(tmp_path, capsys):
    from tacswitch.cli import main

    truth = _smooth_gel(64, 96, 3)
    img = truth.copy()
    img[_dots(64, 96, 11.0, 4.0, 3)] = 40
    cv2.imwrite(str(tmp_path / "a.png"), img)
    base = ["remove-markers", str(tmp_path / "a.png"), "--method", "tacdiff", "--model", "fast",
            "-q"]
    assert main([*base, "-o", str(tmp_path / "s0"), "--separation", "0"]) == 0
    assert main([*base, "-o", str(tmp_path / "s4")]) == 0
    mask = ts.extract_markers(img, dilate="auto", exclude_border=False).mask
    expect = ts.remove_markers(img, mask, method="tacdiff", model="fast", separation=0)
    assert np.array_equal(cv2.imread(str(tmp_path / "s0" / "a.png")), expect)
    assert main([*base, "-o", str(tmp_path / "x"), "--separation", "-1"]) == 2
    assert "--separation: must be >= 0" in capsys.readouterr().err
    assert main(["remove-markers", str(tmp_path / "a.png"), "-o", str(tmp_path / "t"),
                 "--separation", "2", "-q"]) == 0
    assert "--separation is ignored by --method telea" in capsys.readouterr().err


@pytest.mark.parametrize("bad, exc", [(-1, ValueError), (2.5, TypeError), (True, TypeError),
                                      ("8", TypeError)])
def test_separation_is_checked(bad, exc):
    img = _smooth_gel(32, 32, 0)
    m = np.zeros((32, 32), bool)
    m[10:14, 10:14] = True
    with pytest.raises(exc, match=r"^separation: "):
        inpaint_tacdiff(img, m, separation=bad)


def test_hole_passes_checks_its_arguments():
    with pytest.raises(ValueError, match=r"^separation: "):
        hole_passes(np.zeros((4, 4), bool), -2)
    with pytest.raises(ValueError, match=r"^mask: "):
        hole_passes(np.zeros((4, 4, 3), bool), 8)


@pytest.mark.parametrize("patch", [None, "crops", "holes", 64])
def test_passes_run_with_every_region_mode(patch):
    truth = _smooth_gel(64, 96, 4)
    m = _dots(64, 96, 11.0, 4.0, 4)
    img = truth.copy()
    img[m] = 40
    out = inpaint_tacdiff(img, m, model="fast", patch=patch)
    assert np.array_equal(out[~m], img[~m])
    assert np.abs(out.astype(float) - truth)[m].mean() < 3.0


def test_hybrid_forwards_the_separation(monkeypatch):
    from tacswitch.tacdiff import hybrid, infer

    seen = []
    real = infer.inpaint_tacdiff

    def spy(*a, **kw):
        seen.append(kw.get("separation"))
        return real(*a, **kw)

    monkeypatch.setattr(hybrid, "inpaint_tacdiff", spy)  # the name hybrid calls
    # A reference whose left half differs by 40 levels: the holes there are in the contact, so
    # the network runs.
    truth = _smooth_gel(64, 96, 5)
    m = _dots(64, 96, 24.0, 4.0, 5)
    ref = truth.copy()
    ref[:, :48] -= 40
    hybrid.inpaint_hybrid(truth, m, ref, model="fast")
    hybrid.inpaint_hybrid(truth, m, ref, model="fast", separation=0)
    assert seen == [SEPARATION, 0]


def test_hybrid_checks_the_separation_even_without_contact():
    from tacswitch.tacdiff import inpaint_hybrid

    img = _smooth_gel(32, 32, 0)
    m = np.zeros((32, 32), bool)
    m[10:14, 10:14] = True
    with pytest.raises(ValueError, match=r"^separation: "):
        inpaint_hybrid(img, m, separation=-1)  # flat gel: the network would not run
