"""Issue 32, item 9: the fuzz findings of the API, one regression test each.

Hangs and N x N memory of the ``outward`` rule, a sequence manifest that escapes its folder, and
errors that named no argument or came from deep inside (numpy ufuncs, LinAlgError, a cv2
assertion). Each error must now be one TypeError/ValueError whose message starts with the
argument's name.
"""

from __future__ import annotations

import json
import shutil
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import tacswitch as ts
from tacswitch import sim
from tacswitch.motion.heuristic import OUTWARD_GAIN, change_map
from tacswitch.motion.infer import load_model

FUZZ = settings(max_examples=25, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


def _named(exc: BaseException, name: str) -> None:
    """``exc`` is a one-line message that starts with ``name:``."""
    msg = str(exc)
    assert msg.split(":")[0].strip() == name, f"does not name {name!r}: {msg!r}"
    assert "\n" not in msg.strip(), f"multi-line error: {msg!r}"
    assert len(msg) < 400, f"overlong error: {msg[:100]!r}..."


def _raises_named(fn: Any, name: str,
                  kinds: tuple[type[BaseException], ...] = (TypeError, ValueError)) -> None:
    with pytest.raises(kinds) as info:
        fn()
    assert type(info.value) in (TypeError, ValueError), repr(info.value)
    _named(info.value, name)


@pytest.fixture(scope="module")
def press() -> tuple[np.ndarray, np.ndarray]:
    """A simulated GelSight Mini press: ``(frame, no-contact reference)``, 240 x 320 BGR."""
    s = sim.render_sample("gelsight_mini", 1)
    return s.image, s.reference


# --- outward: no N x N array, no hang on big frames ---------------------------------------------

def _old_outward(img: np.ndarray, ref: np.ndarray | None, centres: np.ndarray,
                 gain: float = OUTWARD_GAIN) -> np.ndarray:
    """The rule as it was before the fix (N x N pitch, full-resolution blur), for comparison."""
    import cv2

    from tacswitch.motion.flow import sample_field

    n = len(centres)
    if n == 0 or (ref is not None and np.array_equal(img, ref)):
        return np.zeros((n, 2), np.float32)
    if n < 2:
        pitch = 1.0
    else:
        d = np.linalg.norm(centres[:, None, :] - centres[None, :, :], axis=2)
        np.fill_diagonal(d, np.inf)
        pitch = float(np.median(d.min(1)))
    dm = change_map(img, ref)
    sub = dm[::2, ::2]
    med = float(np.median(sub))
    floor = med + 3.0 * 1.4826 * float(np.median(np.abs(sub - med)))
    wmap = np.maximum(dm - floor, 0.0).astype(np.float32)
    wmap = cv2.GaussianBlur(wmap, (0, 0), max(1.0, pitch / 4))
    total = float(wmap.sum())
    wmax = float(wmap.max())
    if total <= 0 or wmax <= 0:
        return np.zeros((n, 2), np.float32)
    ys, xs = np.mgrid[0:dm.shape[0], 0:dm.shape[1]]
    centre = np.array([(wmap * xs).sum() / total, (wmap * ys).sum() / total], np.float32)
    local = sample_field(np.repeat(wmap[..., None], 2, axis=2), centres)[:, 0] / wmax
    v = centres - centre
    r = np.linalg.norm(v, axis=1, keepdims=True)
    unit = np.divide(v, r, out=np.zeros_like(v), where=r > 1e-6)
    return (unit * (gain * pitch * local)[:, None]).astype(np.float32)


coords = st.floats(-40.0, 360.0, allow_nan=False, width=32)
# Inside the 320 x 240 frame and up to an eighth of its height outside it: farther out,
# predict_motion refuses the centres (pixels of another resolution).
coords_near_frame = st.floats(-30.0, 269.0, allow_nan=False, width=32)


@FUZZ
@given(centres=arrays(np.float32, st.tuples(st.integers(0, 60), st.just(2)),
                      elements=coords_near_frame),
       dup=st.booleans(), single=st.booleans())
def test_outward_matches_the_old_rule_on_small_inputs(press: tuple[np.ndarray, np.ndarray],
                                                      centres: np.ndarray, dup: bool,
                                                      single: bool) -> None:
    img, ref = press
    if dup and len(centres) > 1:
        centres[-1] = centres[0]  # duplicated centres: nearest distance 0, as before
    r = None if single else ref
    new = ts.predict_motion(img, r, centres, method="outward")
    old = _old_outward(img, r, centres)
    np.testing.assert_allclose(new, old, rtol=1e-4, atol=1e-5)


@FUZZ
@given(pts=arrays(np.float32, st.tuples(st.integers(2, 80), st.just(2)),
                  elements=st.one_of(coords, st.sampled_from([0.0, 1.0, 1e6, -3e38, 3e38]))))
def test_grid_nearest_distances_equal_the_brute_force(pts: np.ndarray) -> None:
    from tacswitch.motion.heuristic import _brute_nearest, _nearest

    q = np.arange(len(pts))
    np.testing.assert_array_equal(_nearest(pts, q), _brute_nearest(pts, q))


def test_outward_matches_the_old_rule_on_the_default_grid(press: tuple[np.ndarray,
                                                                          np.ndarray]) -> None:
    img, ref = press
    centres = load_model().centres_for(*img.shape[:2])
    for r in (ref, None):
        new = ts.predict_motion(img, r, method="outward")
        np.testing.assert_allclose(new, _old_outward(img, r, centres), rtol=1e-5, atol=1e-6)


def test_outward_on_200k_centres_is_bounded(press: tuple[np.ndarray, np.ndarray]) -> None:
    """The old rule built an N x N distance array: 1.5 GB at 8,000 centres, 298 GiB at
    200,000 (MemoryError)."""
    img, ref = press
    rng = np.random.default_rng(0)
    centres = rng.uniform([-5, -5], [325, 245], (200_000, 2)).astype(np.float32)
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        out = ts.predict_motion(img, ref, centres, method="outward")
        secs = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert out.shape == (200_000, 2) and np.isfinite(out).all()
    assert np.abs(out).max() > 0
    assert peak < 256 * 2**20, f"peak {peak / 2**20:.0f} MiB"
    assert secs < 30, f"{secs:.1f} s"
    # The pitch from a stride of the centres is what uniform random points have: a median
    # nearest distance of sqrt(ln 2 / pi) / sqrt(density).
    from tacswitch.motion.heuristic import _pitch

    expected = np.sqrt(np.log(2) / np.pi) / np.sqrt(200_000 / (330 * 250))
    assert 0.9 * expected < _pitch(centres) < 1.1 * expected


def test_outward_on_a_4000_px_frame_is_quick_and_agrees(press: tuple[np.ndarray,
                                                                       np.ndarray]) -> None:
    """4000 x 4000: did not finish in 120 s (a full-resolution Gaussian of sigma ~90 px)."""
    import cv2

    img, ref = press
    big = np.asarray(cv2.resize(img, (4000, 4000), interpolation=cv2.INTER_LINEAR))
    t0 = time.perf_counter()
    out = ts.predict_motion(big, method="outward")
    secs = time.perf_counter() - t0
    assert np.isfinite(out).all() and np.abs(out).max() > 0
    assert secs < 30, f"{secs:.1f} s"
    # Against the old full-resolution rule on a frame large enough for the fast path.
    mid = np.asarray(cv2.resize(img, (1280, 960), interpolation=cv2.INTER_LINEAR))
    mref = np.asarray(cv2.resize(ref, (1280, 960), interpolation=cv2.INTER_LINEAR))
    centres = load_model().centres_for(960, 1280)
    new = ts.predict_motion(mid, mref, centres, method="outward")
    old = _old_outward(mid, mref, centres)
    cos = (new * old).sum() / (np.linalg.norm(new) * np.linalg.norm(old))
    assert cos > 0.999
    assert np.linalg.norm(new - old) < 0.02 * np.linalg.norm(old)


def test_200k_centres_with_flow_and_mechanics(press: tuple[np.ndarray, np.ndarray]) -> None:
    """cv2.remap asserted on a 200,000 x 1 map (a side >= SHRT_MAX)."""
    img, ref = press
    rng = np.random.default_rng(1)
    centres = rng.uniform([0, 0], [319, 239], (200_000, 2)).astype(np.float32)
    few = centres[:50]
    for method in ("flow", "mechanics"):
        out = ts.predict_motion(img, ref, centres, method=method)
        assert out.shape == (200_000, 2) and np.isfinite(out).all()
        # The same motion as when the centres are read a few at a time.
        np.testing.assert_array_equal(out[:50], ts.predict_motion(img, ref, few, method=method))


@pytest.mark.parametrize("method", ["outward", "mechanics", "ensemble", "auto"])
def test_a_9_by_2000_frame_gives_a_result_or_names_img(method: str) -> None:
    """The background fit's 1-row grid made its normal equations singular (LinAlgError)."""
    img = np.full((9, 2000, 3), 120, np.uint8)
    img[3:6, 990:1010] = 200
    try:
        out = ts.predict_motion(img, method=method)
    except (TypeError, ValueError) as exc:
        _named(exc, "img")
    else:
        assert np.isfinite(out).all()


# --- errors that name their argument -------------------------------------------------------------

@pytest.mark.parametrize("gain", [10**400, -(10**400)], ids=["1e400", "-1e400"])
@pytest.mark.parametrize("method", ["outward", "mechanics", "ensemble"])
def test_an_overflowing_gain_is_named(press: tuple[np.ndarray, np.ndarray], gain: int,
                                      method: str) -> None:
    img, _ = press
    _raises_named(lambda: ts.predict_motion(img, method=method, gain=gain), "gain")


def test_calibrate_press_gain_names_patch_and_min_peak(press: tuple[np.ndarray,
                                                                     np.ndarray]) -> None:
    from tacswitch.motion.calibration import calibrate_press_gain

    img, ref = press
    _raises_named(lambda: calibrate_press_gain(ref, [img], patch=400), "patch")
    _raises_named(lambda: calibrate_press_gain(ref, [img], patch=2.5), "patch")
    _raises_named(lambda: calibrate_press_gain(ref, [img], min_peak="a"), "min_peak")
    _raises_named(lambda: calibrate_press_gain(ref, [img], min_peak=None), "min_peak")
    _raises_named(lambda: calibrate_press_gain(ref, [img], step=0), "step")


def test_contact_energy_ratio_checks_its_frames(press: tuple[np.ndarray, np.ndarray]) -> None:
    from tacswitch.motion.reference import contact_energy_ratio, is_new_contact

    img, ref = press
    _raises_named(lambda: contact_energy_ratio(img, ref[:100]), "ref")
    _raises_named(lambda: contact_energy_ratio(img, None), "ref")
    _raises_named(lambda: contact_energy_ratio(None, ref), "img")
    _raises_named(lambda: is_new_contact(img, ref.astype(np.float32)), "ref")
    assert contact_energy_ratio(img, img) == 1.0


def test_markerless_tracker_checks_model_at_construction() -> None:
    from tacswitch.motion.sequence import MarkerlessTracker

    _raises_named(lambda: MarkerlessTracker(None, model=3), "model")


def test_remove_markers_blames_an_unknown_keyword_itself() -> None:
    img = sim.render_sample("gelsight_mini", 2).image_markers
    with pytest.raises(TypeError) as info:
        ts.remove_markers(img, None, bogus_kw=1)
    _named(info.value, "bogus_kw")
    assert "remove_markers" in str(info.value) and "extract_markers()" not in str(info.value)
    # extract_markers' own options still pass through.
    ts.remove_markers(img, None, polarity="dark", min_fill=0.3)


@pytest.mark.parametrize("kwargs,name", [
    ({"preset": None}, "preset"),
    ({"preset": 3}, "preset"),
    ({"seed": -1}, "seed"),
    ({"seed": 1.5}, "seed"),
    ({"seed": "x"}, "seed"),
    ({"seed": (1, -2)}, "seed"),
    ({"jpeg_quality": 101}, "jpeg_quality"),
    ({"jpeg_quality": -1}, "jpeg_quality"),
    ({"jpeg_quality": 50.5}, "jpeg_quality"),
])
def test_render_sample_names_bad_arguments(kwargs: dict[str, Any], name: str) -> None:
    _raises_named(lambda: sim.render_sample(**kwargs), name)


def test_render_sample_keeps_accepting_seed_tuples_and_generators() -> None:
    a = sim.render_sample("gelsight_mini", (3, 1))
    b = sim.render_sample("gelsight_mini", np.random.default_rng((3, 1)))
    np.testing.assert_array_equal(a.image, b.image)


@pytest.mark.parametrize("centres", [
    np.array([[np.nan, 3.0]]), np.array([[np.inf, 3.0]]), [["a", "b"]], [[1.0, 2.0, 3.0]]])
def test_render_preset_names_bad_centres(centres: Any) -> None:
    from tacswitch.sim.markers import render_preset

    _raises_named(lambda: render_preset(sim.get_preset("gelsight"), centres), "centres")
    _raises_named(lambda: sim.render_markers(np.zeros((20, 20, 3)), centres, 5.0), "centres")


def test_render_preset_takes_a_name_and_names_a_bad_preset() -> None:
    from tacswitch.sim.markers import render_preset

    assert render_preset("gelsight_mini", seed=0).shape == (240, 320, 3)
    _raises_named(lambda: render_preset(None), "preset")


@pytest.mark.parametrize("q", [101, -1, 2.5, "90"])
def test_generate_dataset_checks_jpeg_quality_before_writing(tmp_path: Path, q: Any) -> None:
    """``tacswitch simulate --jpeg 101`` / ``--jpeg -1`` were accepted (OpenCV clamped them)."""
    from tacswitch.sim.dataset import generate_dataset

    _raises_named(lambda: generate_dataset(tmp_path / "ds", n=1, progress=False,
                                           options={"jpeg_quality": q}), "jpeg_quality")
    assert not (tmp_path / "ds").exists()


def test_jpeg_quality_check_is_shared() -> None:
    from tacswitch._checks import as_jpeg_quality

    assert as_jpeg_quality(None) is None
    assert as_jpeg_quality(1) == 1 and as_jpeg_quality(np.int64(100)) == 100
    for bad in (0, 101, -1, True, 50.0):
        _raises_named(lambda bad=bad: as_jpeg_quality(bad, "--jpeg"), "--jpeg")


# --- datasets ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def sequences(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tacswitch.sim.dataset import generate_dataset

    root = tmp_path_factory.mktemp("seq")
    generate_dataset(root, preset="gelsight_mini", n=1, seed=3, sequences=True, progress=False,
                     options={"frames": 8})
    return root


def _edit(src: Path, dst: Path, fn: Any) -> Path:
    """A copy of dataset ``src`` in ``dst`` with its first record changed by ``fn(rec, root)``."""
    shutil.copytree(src, dst)
    man = dst / "manifest.jsonl"
    rec = json.loads(man.read_text().splitlines()[0])
    fn(rec, dst)
    man.write_text(json.dumps(rec) + "\n")
    return dst


def test_sequence_dataset_loads(sequences: Path) -> None:
    from tacswitch.data import SequenceDataset

    item = SequenceDataset(sequences)[0]
    assert item["images"].shape[0] == 8


def test_sequence_frame_file_outside_the_folder_is_refused(sequences: Path,
                                                           tmp_path: Path) -> None:
    from tacswitch.data import SequenceDataset

    secret = tmp_path / "secret.png"
    shutil.copy(next((sequences / "sequences" / "000000").glob("frame_000.png")), secret)

    def escape(rec: dict[str, Any], root: Path) -> None:
        rec["frames"][0]["files"]["image"] = "../../../secret.png"

    root = _edit(sequences, tmp_path / "ds", escape)
    with pytest.raises(ValueError, match=r"^root:.*outside") as info:
        SequenceDataset(root)[0]
    _named(info.value, "root")

    def escape_ref(rec: dict[str, Any], root: Path) -> None:
        rec["files"]["reference"] = str(secret)

    root = _edit(sequences, tmp_path / "ds2", escape_ref)
    with pytest.raises(ValueError, match=r"^root:.*outside"):
        SequenceDataset(root)[0]


def test_sequence_of_mixed_frame_sizes_is_named(sequences: Path, tmp_path: Path) -> None:
    import cv2

    from tacswitch.data import SequenceDataset

    def shrink(rec: dict[str, Any], root: Path) -> None:
        f = root / rec["dir"] / rec["frames"][2]["files"]["image"]
        cv2.imwrite(str(f), np.zeros((10, 12, 3), np.uint8))

    root = _edit(sequences, tmp_path / "ds", shrink)
    with pytest.raises(ValueError, match=r"^root:.*frame 2.*10 x 12.*240 x 320") as info:
        SequenceDataset(root)[0]
    _named(info.value, "root")


def test_sequence_without_frames_is_named(sequences: Path, tmp_path: Path) -> None:
    from tacswitch.data import SequenceDataset

    def empty(rec: dict[str, Any], root: Path) -> None:
        rec["frames"] = []

    root = _edit(sequences, tmp_path / "ds", empty)
    with pytest.raises(ValueError, match=r"^root:.*no frames"):
        SequenceDataset(root)[0]


def test_dataset_json_without_classes_is_named(sequences: Path, tmp_path: Path) -> None:
    from tacswitch.data import SequenceDataset

    root = _edit(sequences, tmp_path / "ds", lambda rec, root: None)
    head = json.loads((root / "dataset.json").read_text())
    del head["classes"]
    (root / "dataset.json").write_text(json.dumps(head))
    with pytest.raises(ValueError, match=r"^root:.*classes"):
        SequenceDataset(root)


@pytest.mark.parametrize("root", [3, None, 2.5, [b"x"]])
def test_dataset_root_of_another_type_is_named(root: Any) -> None:
    from tacswitch.data import SequenceDataset, TactileDataset, read_manifest

    for cls in (TactileDataset, SequenceDataset, read_manifest):
        _raises_named(lambda cls=cls: cls(root), "root")
