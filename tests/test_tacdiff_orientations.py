"""TacDiff averages its image estimate over orientations of the frame
(``inpaint_tacdiff(orientations=...)``): the flips, the average, the defaults, arguments."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tacswitch as ts
from conftest import disc_mask
from tacswitch import sim
from tacswitch.tacdiff import infer
from tacswitch.tacdiff.infer import (
    DEFAULT_ORIENTATIONS,
    ORIENTATIONS,
    inpaint_tacdiff,
    orientations_for,
)


def _frame(h: int = 64, w: int = 96, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smooth gel (the truth), its copy with dark dots, and the dots' mask."""
    truth = np.clip(sim.gel_background(h, w, seed=seed), 0, 255).astype(np.uint8)
    rng = np.random.default_rng(seed)
    off = rng.uniform(0, 24.0, 2)
    cs = [(x, y) for y in np.arange(off[1], h, 24.0) for x in np.arange(off[0], w, 24.0)]
    m = disc_mask((h, w), cs, 4.0)
    img = truth.copy()
    img[m] = 40
    return truth, img, m


@settings(max_examples=30, deadline=None)
@given(h=st.integers(1, 9), w=st.integers(1, 9), c=st.integers(1, 3), seed=st.integers(0, 99))
def test_every_orientation_is_undone_by_its_inverse(h, w, c, seed):
    a = np.random.default_rng(seed).random((c, h, w))
    seen = set()
    for o in orientations_for(8, None):
        t = infer._orient(a, o)
        assert t.shape == ((c, w, h) if o[2] else (c, h, w))
        assert np.array_equal(infer._unorient(t, o), a)
        seen.add(t.tobytes() + bytes(t.shape))
    # Eight distinct views of a generic array (the dihedral group of the rectangle's grid).
    if h > 1 and w > 1:
        assert len(seen) == 8


def test_the_fill_is_the_mean_of_the_single_orientation_estimates():
    _, img, m = _frame()
    net = infer.load_model("fast")
    noise = np.random.default_rng(0).standard_normal((3, int(m.sum())), dtype=np.float32)
    planes = infer._frame_planes(img, m, net, noise)
    parts = []
    for o in orientations_for(4, None):
        om = infer._orient(m, o)
        x0 = infer._network(infer._pad(infer._orient(planes, o), net.multiple), om, net, 1,
                            "dpmpp2m", "auto", infer.DEFAULT_OVERLAP, None)
        parts.append(infer._unorient(x0[:, :om.shape[0], :om.shape[1]], o))
    expect = img.copy()
    infer._paste(expect, np.mean(parts, axis=0).astype(np.float32), m)
    out = inpaint_tacdiff(img, m, model="fast", orientations=4)
    assert np.array_equal(out, expect)
    # The orientations disagree somewhere, so the average is not the plain fill.
    assert not np.array_equal(out, inpaint_tacdiff(img, m, model="fast", orientations=1))


def _equivariant_sample(model, x, steps, sampler):  # type: ignore[no-untyped-def]
    """A stand-in for the sampler that commutes exactly with flips and transposes: prior plus a
    fifth of the pixel's own noise."""
    return np.clip(x[:, 7:10] + 0.2 * x[:, 4:7], -1.0, 1.0).astype(np.float32)


@pytest.mark.parametrize("shape", [(50, 77), (77, 50), (64, 96)])
@pytest.mark.parametrize("pitch", [24.0, 11.0])  # 11: crowded holes, several passes
def test_an_equivariant_network_gives_the_same_fill_in_every_orientation(monkeypatch, shape,
                                                                         pitch):
    # Frames off the model's 16 px multiple pad differently in each orientation, holes reach
    # the borders, and each pixel must meet its own noise: with a network that commutes with
    # the flips, averaging must change nothing (up to rounding).
    monkeypatch.setattr(infer, "_sample", _equivariant_sample)
    h, w = shape
    rng = np.random.default_rng(int(pitch))
    truth = np.clip(sim.gel_background(h, w, seed=1), 0, 255).astype(np.uint8)
    off = rng.uniform(0, pitch, 2)
    m = disc_mask((h, w), [(x, y) for y in np.arange(off[1] - pitch, h + pitch, pitch)
                           for x in np.arange(off[0] - pitch, w + pitch, pitch)], 4.0)
    img = truth.copy()
    img[m] = 40
    for patch in ("auto", None, "crops", "holes", 48):
        one = inpaint_tacdiff(img, m, model="fast", orientations=1, patch=patch, overlap=16)
        for n in (2, 4, 8):
            out = inpaint_tacdiff(img, m, model="fast", orientations=n, patch=patch,
                                  overlap=16)
            assert np.array_equal(out[~m], img[~m])
            assert np.abs(out.astype(int) - one).max() <= 1, (patch, n)


@pytest.mark.parametrize("n", ORIENTATIONS)
def test_known_pixels_stay_and_the_fill_is_close_in_every_count(n):
    truth, img, m = _frame(seed=4)
    out = inpaint_tacdiff(img, m, model="fast", orientations=n)
    assert np.array_equal(out[~m], img[~m])
    assert np.abs(out.astype(float) - truth)[m].mean() < 3.0
    assert np.array_equal(out, inpaint_tacdiff(img, m, model="fast", orientations=n))


def test_defaults_follow_the_models_width(tmp_path):
    import shutil

    assert DEFAULT_ORIENTATIONS == 4
    assert len(orientations_for(None, None)) == 4
    assert len(orientations_for(None, "default")) == 4
    assert len(orientations_for(None, "fast")) == 1
    assert len(orientations_for(None, infer.model_path("fast"))) == 1
    # By the network's width, not its file: a copy of the fast model (e.g. what a fine-tune
    # that kept its fast start writes) is still run once, a copy of the default four times.
    for name, n in (("fast", 1), ("default", 4)):
        copy = tmp_path / f"{name}_copy.onnx"
        shutil.copy(infer.model_path(name), copy)
        assert infer.default_orientations(infer.load_model(copy)) == n
        assert len(orientations_for(None, str(copy))) == n
    _, img, m = _frame(48, 64, 5)
    assert np.array_equal(inpaint_tacdiff(img, m, model="fast"),
                          inpaint_tacdiff(img, m, model="fast", orientations=1))
    assert np.array_equal(inpaint_tacdiff(img, m, model=tmp_path / "fast_copy.onnx"),
                          inpaint_tacdiff(img, m, model="fast", orientations=1))
    assert np.array_equal(inpaint_tacdiff(img, m),
                          inpaint_tacdiff(img, m, orientations=4))


def test_crowded_holes_average_within_each_pass():
    # Dots every 11 px: several passes, each averaged over the orientations.
    rng = np.random.default_rng(2)
    truth = np.clip(sim.gel_background(64, 96, seed=2), 0, 255).astype(np.uint8)
    off = rng.uniform(0, 11.0, 2)
    m = disc_mask((64, 96), [(x, y) for y in np.arange(off[1], 64, 11.0)
                             for x in np.arange(off[0], 96, 11.0)], 4.0)
    img = truth.copy()
    img[m] = 40
    out = inpaint_tacdiff(img, m, model="fast", orientations=4)
    assert np.array_equal(out[~m], img[~m])
    assert not np.array_equal(out, inpaint_tacdiff(img, m, model="fast", orientations=1))
    assert np.abs(out.astype(float) - truth)[m].mean() < 3.0


@pytest.mark.parametrize("bad", [0, 3, 16, -4, True, 2.0, "4", [4]])
def test_orientations_is_checked(bad):
    _, img, m = _frame(32, 32, 0)
    with pytest.raises(ValueError, match=r"^orientations: "):
        inpaint_tacdiff(img, m, orientations=bad)
    with pytest.raises(ValueError, match=r"^orientations: "):
        ts.remove_markers(img, m, method="tacdiff", orientations=bad)


def test_a_bad_model_argument_is_named_before_the_orientations():
    _, img, m = _frame(32, 32, 0)
    with pytest.raises(TypeError, match=r"^model: "):
        orientations_for(None, 123)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"^model: "):
        inpaint_tacdiff(img, np.zeros_like(m), model=123)  # type: ignore[arg-type]


def test_remove_markers_and_hybrid_pass_it_on():
    _, img, m = _frame(seed=6)
    for n in (1, 4):
        assert np.array_equal(
            ts.remove_markers(img, m, method="tacdiff", model="fast", orientations=n),
            inpaint_tacdiff(img, m, model="fast", orientations=n))
    with pytest.raises(ValueError, match=r"^orientations: applies to method='tacdiff'"):
        ts.remove_markers(img, m, method="telea", orientations=4)
    # The hybrid checks it even where the network would not run (flat gel, no contact).
    flat = np.full((32, 32, 3), 128, np.uint8)
    hole = np.zeros((32, 32), bool)
    hole[10:14, 10:14] = True
    with pytest.raises(ValueError, match=r"^orientations: "):
        ts.tacdiff.inpaint_hybrid(flat, hole, orientations=5)


def test_hybrid_forwards_the_orientations(monkeypatch):
    from tacswitch.tacdiff import hybrid

    seen = []
    real = infer.inpaint_tacdiff

    def spy(*a, **kw):
        seen.append(kw.get("orientations"))
        return real(*a, **kw)

    monkeypatch.setattr(hybrid, "inpaint_tacdiff", spy)  # the name hybrid calls
    truth, _, m = _frame(seed=5)
    ref = truth.copy()
    ref[:, :48] -= 40  # the holes on the left are in the contact: the network runs
    hybrid.inpaint_hybrid(truth, m, ref, model="fast")
    hybrid.inpaint_hybrid(truth, m, ref, model="fast", orientations=2)
    assert seen == [None, 2]


def test_remove_markers_cli_orientations(tmp_path, capsys):
    from tacswitch.cli import main

    _, img, _ = _frame(seed=3)
    cv2.imwrite(str(tmp_path / "a.png"), img)
    base = ["remove-markers", str(tmp_path / "a.png"), "--method", "tacdiff", "--model", "fast",
            "-q"]
    assert main([*base, "-o", str(tmp_path / "o4"), "--orientations", "4"]) == 0
    mask = ts.extract_markers(img, dilate="auto", exclude_border=False).mask
    expect = ts.remove_markers(img, mask, method="tacdiff", model="fast", orientations=4)
    assert np.array_equal(cv2.imread(str(tmp_path / "o4" / "a.png")), expect)
    with pytest.raises(SystemExit) as err:
        main([*base, "-o", str(tmp_path / "x"), "--orientations", "3"])
    assert err.value.code == 2
    assert "--orientations" in capsys.readouterr().err
    assert main(["remove-markers", str(tmp_path / "a.png"), "-o", str(tmp_path / "t"),
                 "--orientations", "2", "-q"]) == 0
    assert "--orientations is ignored by --method telea" in capsys.readouterr().err
