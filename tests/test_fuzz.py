"""The fuzz run of issue 16 as part of the suite: hostile arguments to the public API either give
a sane result or a TypeError/ValueError whose message starts with the argument's name; plus one
regression test per case the fuzz run found (crashes, hangs, N^2 memory, silent wrong results,
errors that did not name the argument)."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import tacswitch as ts
from tacswitch import sim

FUZZ = settings(max_examples=40, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

#: Values a fuzzer throws at any scalar argument.
HOSTILE = [None, True, -1, 0, 1, 3, 2**20, 2**31, 2**64, 10**30, -(10**30), 0.0, -0.0, 0.5,
           1e-45, 3e38, -3e38, float("nan"), float("inf"), float("-inf"), "abc", "", "dark",
           b"x", [1, 2], (3,), {}, object(), np.int64(5), np.float32(2.5), np.array([1, 2])]


def _frame(h: int = 96, w: int = 128) -> np.ndarray:
    """A small rendered frame with markers (BGR uint8)."""
    centres = sim.marker_grid(h, w, 3, 4, 24.0)
    bg = sim.gel_background(h, w, seed=0)
    return sim.render_markers(bg, centres, 9.0, darkness=0.8, edge_px=1.0, seed=1)


F = _frame()
M = np.zeros(F.shape[:2], bool)
M[40:50, 60:70] = True
PTS = sim.marker_grid(96, 128, 3, 4, 24.0).astype(np.float32)


def _call_ok_or_named(fn: Any, name: str) -> Any:
    """Runs ``fn()``; an error must be TypeError/ValueError starting with ``name:``."""
    try:
        return fn()
    except (TypeError, ValueError) as exc:
        msg = str(exc)
        assert msg.split(":")[0].strip() == name, f"{name}: error does not name it: {msg!r}"
        assert "\n" not in msg.strip(), f"multi-line error: {msg!r}"
        return None


# ---------------------------------------------------------------------------------------------
# Property-based fuzzing: one hostile argument at a time, the others valid.

CASES: list[tuple[str, Any]] = [
    ("patch", lambda v: ts.tile(F, v, 0)),
    ("overlap", lambda v: ts.tile(F, 64, v)),
    ("radius", lambda v: ts.inpaint_telea(F, M, radius=v)),
    ("radius", lambda v: ts.remove_markers(F, M, method="ns", radius=v)),
    ("method", lambda v: ts.remove_markers(F, M, method=v)),
    ("dilate", lambda v: ts.remove_markers(F, dilate=v)),
    ("dilate", lambda v: ts.extract_markers(F, dilate=v)),
    ("iterations", lambda v: ts.dilate_mask(M, v)),
    ("max_dist", lambda v: ts.match_markers(PTS, PTS + 1, v)),
    ("max_dist", lambda v: ts.MarkerTracker(PTS, v)),
    ("polarity", lambda v: ts.MarkerTracker(PTS, polarity=v)),
    ("block_size", lambda v: ts.MarkerTracker(PTS, block_size=v)),
    ("threshold", lambda v: ts.MarkerTracker(PTS, threshold=v)),
    ("min_area", lambda v: ts.MarkerTracker(PTS, min_area=v)),
    ("max_area", lambda v: ts.MarkerTracker(PTS, max_area=v)),
    ("min_fill", lambda v: ts.MarkerTracker(PTS, min_fill=v)),
    ("max_aspect", lambda v: ts.MarkerTracker(PTS, max_aspect=v)),
    ("exclude_border", lambda v: ts.MarkerTracker(PTS, exclude_border=v)),
    ("polarity", lambda v: ts.extract_markers(F, polarity=v)),
    ("block_size", lambda v: ts.extract_markers(F, block_size=v)),
    ("threshold", lambda v: ts.extract_markers(F, threshold=v)),
    ("min_area", lambda v: ts.extract_markers(F, min_area=v)),
    ("max_area", lambda v: ts.extract_markers(F, max_area=v)),
    ("min_fill", lambda v: ts.extract_markers(F, min_fill=v)),
    ("max_aspect", lambda v: ts.extract_markers(F, max_aspect=v)),
    ("exclude_border", lambda v: ts.extract_markers(F, exclude_border=v)),
    ("threshold_px", lambda v: ts.SlipDetector(v)),
    ("active_fraction", lambda v: ts.SlipDetector(active_fraction=v)),
    ("image_width", lambda v: ts.SlipDetector(image_width=v)),
    ("rigid_threshold_px", lambda v: ts.SlipDetector(rigid_threshold_px=v)),
    ("shape", lambda v: ts.merge_patches(*ts.tile(F, 64, 8), shape=v)),
    ("mode", lambda v: ts.merge_patches(*ts.tile(F, 64, 8), shape=F.shape, mode=v)),
    ("origins", lambda v: ts.merge_patches(ts.tile(F, 64, 8)[0][:1], [[v, 0]], shape=(64, 64, 3))),
    ("seed", lambda v: ts.remove_markers(F, M, method="tacdiff", seed=v, model=str(Path("/no")))),
    ("model", lambda v: ts.predict_motion(F, F, model=v)
     if not isinstance(v, (str, bytes)) else None),
]


@pytest.mark.parametrize("name,call", CASES, ids=[f"{i}-{c[0]}" for i, c in enumerate(CASES)])
@FUZZ
@given(value=st.sampled_from(HOSTILE))
def test_hostile_scalar_is_accepted_or_named(name: str, call: Any, value: Any) -> None:
    try:
        _call_ok_or_named(lambda: call(value), name)
    except (FileNotFoundError, OSError) as exc:  # a valid seed reaching the missing model file
        assert name == "seed" and "model" in str(exc)


finite32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
any32 = st.floats(width=32, allow_nan=True, allow_infinity=True)


@FUZZ
@given(ref=arrays(np.float32, st.tuples(st.integers(0, 40), st.just(2)), elements=any32),
       cur=arrays(np.float32, st.tuples(st.integers(0, 40), st.just(2)), elements=finite32))
def test_match_markers_results_are_sane(ref: np.ndarray, cur: np.ndarray) -> None:
    out = _call_ok_or_named(lambda: ts.match_markers(ref, cur, return_index=True), "ref_pts")
    if out is None:
        assert not np.isfinite(ref).all()
        return
    motion, valid, index = out
    assert motion.shape == (len(ref), 2) and valid.shape == (len(ref),)
    assert np.isfinite(motion[valid]).all() and np.isnan(motion[~valid]).all()
    used = index[valid]
    assert len(np.unique(used)) == len(used)  # a detection matches at most once
    with np.errstate(over="ignore"):
        np.testing.assert_array_equal(motion[valid], cur[used] - ref[valid])


@FUZZ
@given(pts=arrays(np.float32, st.tuples(st.integers(0, 30), st.just(2)), elements=finite32))
def test_estimate_pitch_is_none_or_a_finite_distance(pts: np.ndarray) -> None:
    p = ts.estimate_pitch(pts)
    distinct = len({(float(x) + 0.0, float(y) + 0.0) for x, y in pts})
    if distinct < 2:
        assert p is None
    else:
        assert p is not None and np.isfinite(p) and p > 0


@FUZZ
@given(img=arrays(np.float32, st.tuples(st.integers(1, 40), st.integers(1, 40)), elements=finite32),
       patch=st.integers(1, 48), frac=st.floats(0, 0.9))
def test_tile_merge_round_trip_is_bit_exact(img: np.ndarray, patch: int, frac: float) -> None:
    overlap = int(frac * patch)
    p, o = ts.tile(img, patch, overlap)
    for mode in ("average", "feather"):
        out = ts.merge_patches(p, o, img.shape, mode=mode)
        np.testing.assert_array_equal(out.view(np.uint32), img.view(np.uint32))


@FUZZ
@given(vals=arrays(np.float32, st.integers(2, 4), elements=st.sampled_from(
    [3e38, -3e38, 3.4e38, -3.4e38, 1.0, -0.0, 0.0, 1e-45])))
def test_merge_of_extreme_floats_is_their_mean(vals: np.ndarray) -> None:
    """Patches covering one pixel: finite, and their mean to float32 precision of the inputs'
    scale (1, 3e38, -3e38 has no better answer than 0 or 1)."""
    patches = vals.reshape(-1, 1, 1)
    out = ts.merge_patches(patches, np.zeros((len(vals), 2), np.int64), (1, 1))
    want = vals.astype(np.float64).mean()
    assert np.isfinite(out).all()
    scale = float(np.abs(vals.astype(np.float64)).max())
    assert abs(float(out[0, 0]) - want) <= 1e-6 * max(1.0, scale)


# ---------------------------------------------------------------------------------------------
# Regression tests, one per case of the fuzz run.

@pytest.mark.parametrize("img,patch,overlap,name", [
    (np.zeros((480, 640, 3), np.uint8), 100_000, 0, "patch"),
    (np.zeros((1, 1), np.uint8), 2**20, 0, "patch"),
    (np.zeros((480, 640, 3), np.uint8), 2**31, 0, "patch"),
    (np.zeros((480, 640, 3), np.uint8), 2**64, 0, "patch"),
    (np.zeros((480, 640, 3), np.uint8), 256, 255, "overlap"),  # 86 625 patches, 17 GB
])
def test_tile_refuses_crashing_and_huge_layouts(img: np.ndarray, patch: int, overlap: int,
                                                name: str) -> None:
    with pytest.raises(ValueError, match=rf"^{name}:"):
        ts.tile(img, patch, overlap)


def _run_child(code: str, timeout: float) -> dict[str, Any]:
    """Runs ``code`` in a fresh interpreter (so a hang is a timeout and memory is its own)."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=timeout, check=True)
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def test_match_markers_of_a_million_duplicates_is_bounded() -> None:
    r = _run_child(
        "import json, numpy as np, tacswitch as ts\n"
        "z = np.zeros((10**6, 2), np.float32)\n"
        "m, v = ts.match_markers(z, z, 1.0)\n"
        "print(json.dumps({'valid': int(v.sum()), 'first': bool(v[0])}))", timeout=60)
    assert r == {"valid": 1, "first": True}


def test_marker_tracker_memory_is_linear() -> None:
    """10^5 markers: the all-pairs neighbour search needed > 5.6 GB; now a few tens of MB."""
    r = _run_child(
        "import json, resource, numpy as np, tacswitch as ts\n"
        "g = np.stack(np.meshgrid(np.arange(317), np.arange(317)), -1).reshape(-1, 2)[:10**5]\n"
        "ref = (g * 10.0).astype(np.float32)\n"
        "base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "tr = ts.MarkerTracker(ref)\n"
        "m, v = tr.update(ref + np.float32(2))\n"
        "peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "print(json.dumps({'mb': (peak - base) / 1024, 'valid': float(v.mean())}))", timeout=60)
    assert r["valid"] == 1.0
    assert r["mb"] < 300, r


def test_remove_markers_ns_refuses_a_full_mask() -> None:
    with pytest.raises(ValueError, match=r"^mask:"):
        ts.remove_markers(F, np.ones(F.shape[:2], bool), method="ns")


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_remove_markers_ns_dtypes(dtype: type) -> None:
    with pytest.raises(ValueError, match=r"^img:"):
        ts.remove_markers(F.astype(dtype), M, method="ns")
    grey: np.ndarray = F[:, :, 1].astype(dtype)  # grey works, as OpenCV allows
    out = ts.remove_markers(grey, M, method="ns")
    assert out.dtype == dtype and (out[~M] == grey[~M]).all()


def test_telea_of_huge_floats_is_finite() -> None:
    img = np.full((20, 20), 3e38, np.float32)
    img[:, :10] = -3e38
    mask = np.zeros((20, 20), bool)
    mask[8:12, 8:12] = True
    out = ts.inpaint_telea(img, mask)
    assert np.isfinite(out).all()
    assert (np.abs(out[mask]) <= 3e38).all()
    np.testing.assert_array_equal(out[~mask], img[~mask])
    # The scaling is exact: a scaled-down image gives the same fill, scaled.
    small = ts.inpaint_telea(img / np.float32(2.0**100), mask)
    np.testing.assert_array_equal(out[mask], small[mask] * np.float32(2.0**100))


def test_merge_of_plus_minus_3e38_is_zero_not_minus_inf() -> None:
    img = np.full((8, 12), 3e38, np.float32)
    p, o = ts.tile(img, 8, 4)
    p[1] = -3e38
    out = ts.merge_patches(p, o, img.shape)
    assert np.isfinite(out).all() and (out[:, 4:8] == 0).all()


def test_match_with_overflowing_motion_is_unmatched() -> None:
    motion, valid = ts.match_markers([[3e38, 0]], [[-3e38, 0]])
    assert not valid[0] and np.isnan(motion).all()


def test_estimate_pitch_of_two_distant_points_is_their_distance() -> None:
    assert ts.estimate_pitch([[0, 0], [1e20, 0]]) == pytest.approx(1e20, rel=1e-6)
    assert ts.estimate_pitch([[3e38, 0], [-3e38, 0]]) == pytest.approx(6e38, rel=1e-6)
    assert ts.estimate_pitch([[5, 5], [5, 5]]) is None


def test_merge_keeps_negative_zero() -> None:
    img = np.zeros((50, 70), np.float32)
    img[::3, ::2] = -0.0
    p, o = ts.tile(img, 16, 5)
    for mode in ("average", "feather"):
        out = ts.merge_patches(p, o, img.shape, mode=mode)
        assert np.array_equal(np.signbit(out), np.signbit(img))


def _unaligned(a: np.ndarray) -> np.ndarray:
    buf = np.zeros(a.nbytes + 1, np.uint8)
    out = np.ndarray(a.shape, a.dtype, buf.data, 1)
    out[...] = a
    assert not out.flags.aligned and out.flags.c_contiguous
    return out


def test_unaligned_arrays_are_accepted() -> None:
    img = F[:, :, 0].astype(np.float32)
    np.testing.assert_array_equal(ts.inpaint_telea(_unaligned(img), M),
                                  ts.inpaint_telea(img, M))
    p, o = ts.tile(_unaligned(img), 32, 4)
    np.testing.assert_array_equal(ts.merge_patches(_unaligned(p), _unaligned(o), img.shape), img)
    assert ts.estimate_pitch(_unaligned(PTS)) == ts.estimate_pitch(PTS)
    np.testing.assert_array_equal(ts.match_markers(_unaligned(PTS), PTS)[1],
                                  ts.match_markers(PTS, PTS)[1])
    tr = ts.MarkerTracker(_unaligned(PTS))
    assert tr.update(_unaligned(PTS + 1))[1].all()


@pytest.mark.parametrize("name,call", [
    ("dilate", lambda: ts.remove_markers(F, dilate=-1)),
    ("dilate", lambda: ts.remove_markers(F, dilate=2.5)),  # type: ignore[arg-type]
    ("patch", lambda: ts.tile(F, 10**30, 0)),
    ("overlap", lambda: ts.tile(F, 64, 10**30)),
    ("origins", lambda: ts.merge_patches(np.zeros((1, 4, 4), np.uint8), [[10**30, 0]], (4, 4))),
    ("shape", lambda: ts.merge_patches(np.zeros((1, 4, 4), np.uint8), [[0, 0]], 4)),  # type: ignore[arg-type]
    ("shape", lambda: ts.merge_patches(np.zeros((1, 4, 4), np.uint8), [[0, 0]], (10**30, 4))),
    ("block_size", lambda: ts.MarkerTracker(PTS, block_size=10**30)),
    ("min_area", lambda: ts.MarkerTracker(PTS, min_area=10**30)),
    ("max_area", lambda: ts.MarkerTracker(PTS, max_area=2**64)),
    ("polarity", lambda: ts.MarkerTracker(PTS, polarity=None)),
    ("polarity", lambda: ts.extract_markers(F, polarity=None)),  # type: ignore[arg-type]
    ("threshold", lambda: ts.extract_markers(F, threshold="abc")),  # type: ignore[arg-type]
    ("min_fill", lambda: ts.extract_markers(F, min_fill=None)),  # type: ignore[arg-type]
    ("block_size", lambda: ts.extract_markers(F, block_size=10**30)),
    ("max_area", lambda: ts.extract_markers(F, max_area=2**64)),
    ("threshold", lambda: ts.MarkerTracker(PTS, threshold="abc")),
    ("min_fill", lambda: ts.MarkerTracker(PTS, min_fill=None)),
    ("max_dist", lambda: ts.match_markers(PTS, PTS, "x")),  # type: ignore[call-overload]
    ("image_width", lambda: ts.SlipDetector(image_width="abc")),  # type: ignore[arg-type]
    ("radius", lambda: ts.inpaint_telea(F, M, radius=10**30)),
    ("seed", lambda: ts.remove_markers(F, M, method="tacdiff", seed=-1)),
    ("model", lambda: ts.remove_markers(F, M, method="tacdiff", model=123)),  # type: ignore[arg-type]
    ("model", lambda: ts.predict_motion(F, model=123)),  # type: ignore[arg-type]
    ("motion_or_img", lambda: ts.SlipDetector().update(np.zeros((0, 0), np.uint8))),
    ("img", lambda: ts.predict_motion(np.zeros((1, 640, 3), np.uint8),
                                      np.zeros((1, 640, 3), np.uint8))),
    ("img", lambda: ts.predict_motion(np.zeros((1, 1, 3), np.uint8),
                                      np.zeros((1, 1, 3), np.uint8))),
])
def test_errors_name_the_argument(name: str, call: Any) -> None:
    with pytest.raises((TypeError, ValueError), match=rf"^{name}:"):
        call()


def test_marker_tracker_can_be_shared_between_threads() -> None:
    tr = ts.MarkerTracker(PTS)
    errors: list[BaseException] = []

    def work() -> None:
        try:
            for k in range(100):
                tr.update(PTS + np.float32(0.01 * (k % 3)))
                tr.update(F)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert tr.frame == 800


# --- datasets ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tacswitch.sim.dataset import generate_dataset

    root = tmp_path_factory.mktemp("ds")
    generate_dataset(root, preset="gelsight_mini", n=1, seed=3, progress=False)
    return root


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_dataset_mask_of_another_size_is_an_error(dataset: Path, tmp_path: Path) -> None:
    import cv2

    from tacswitch.data import TactileDataset

    root = _copy(dataset, tmp_path / "ds")
    ds = TactileDataset(root)
    rec = ds.records[0]
    mask_file = root / rec["dir"] / rec["files"]["marker_mask"]
    cv2.imwrite(str(mask_file), np.zeros((7, 9), np.uint8))
    with pytest.raises(ValueError, match=r"^path:.*marker_mask.*7 x 9.*240 x 320"):
        ds[0]


def test_dataset_dir_outside_the_root_is_refused(dataset: Path, tmp_path: Path) -> None:
    from tacswitch.data import TactileDataset

    root = _copy(dataset, tmp_path / "ds")
    man = root / "manifest.jsonl"
    rec = json.loads(man.read_text().splitlines()[0])
    rec["dir"] = "../../outside"
    man.write_text(json.dumps(rec) + "\n")
    with pytest.raises(ValueError, match=r"^root:.*outside"):
        TactileDataset(root)[0]


@pytest.mark.parametrize("header,manifest", [
    ("{not json", None),
    ("[1, 2]", None),
    (None, "{broken\n"),
    (None, "[]\n"),
    (None, '{"dir": "samples/000000"}\n'),  # a record missing its fields
])
def test_corrupt_dataset_files_give_one_line_errors(dataset: Path, tmp_path: Path,
                                                    header: str | None,
                                                    manifest: str | None) -> None:
    from tacswitch.data import TactileDataset

    root = _copy(dataset, tmp_path / "ds")
    if header is not None:
        (root / "dataset.json").write_text(header)
    if manifest is not None:
        (root / "manifest.jsonl").write_text(manifest)
    with pytest.raises(ValueError, match=r"^root:"):
        TactileDataset(root)[0]
    with pytest.raises((TypeError, IndexError), match=r"^i:"):
        TactileDataset(dataset)["0"]  # type: ignore[index]
