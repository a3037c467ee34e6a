"""Patch tiling and merging (Rust core) against exact expectations and numpy."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tacswitch.inpaint import merge_patches, tile


def gradient(h: int, w: int, c: int | None = 3) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    g = 10.0 + 0.2 * xx + 0.15 * yy
    return g if c is None else np.stack([g + 5 * k for k in range(c)], axis=2)


def numpy_average(patches: np.ndarray, origins: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The numpy equivalent of the paper's plain average."""
    acc = np.zeros(shape, np.float64)
    cnt = np.zeros(shape[:2], np.float64)
    p = patches.shape[1]
    for patch, (x, y) in zip(patches, origins, strict=True):
        h, w = min(p, shape[0] - y), min(p, shape[1] - x)
        acc[y : y + h, x : x + w] += patch[:h, :w]
        cnt[y : y + h, x : x + w] += 1
    return acc / (cnt if len(shape) == 2 else cnt[:, :, None])


def test_paper_layout_has_six_patches() -> None:
    img = np.zeros((480, 640, 3), np.uint8)
    patches, origins = tile(img, 256, 30)
    assert patches.shape == (6, 256, 256, 3) and patches.dtype == np.uint8
    assert origins.tolist() == [[0, 0], [226, 0], [384, 0], [0, 224], [226, 224], [384, 224]]


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("channels", [None, 1, 3, 4])
@pytest.mark.parametrize("mode", ["average", "feather"])
def test_unmodified_patches_merge_back_exactly(
    dtype: type, channels: int | None, mode: str
) -> None:
    rng = np.random.default_rng(0)
    shape = (480, 640) if channels is None else (480, 640, channels)
    img: np.ndarray = (rng.random(shape) * 250).astype(dtype)
    patches, origins = tile(img, 256, 30)
    out = merge_patches(patches, origins, img.shape, mode=mode)  # type: ignore[arg-type]
    assert out.dtype == img.dtype and out.shape == img.shape
    assert np.array_equal(out, img)


def test_patches_are_the_image_windows() -> None:
    img = gradient(480, 640)
    patches, origins = tile(img, 256, 30)
    for p, (x, y) in zip(patches, origins, strict=True):
        assert np.array_equal(p, img[y : y + 256, x : x + 256])


def test_average_matches_numpy_on_modified_patches() -> None:
    img = gradient(480, 640)
    patches, origins = tile(img, 256, 30)
    patches = patches + np.arange(6, dtype=np.float32)[:, None, None, None]
    ours = merge_patches(patches, origins, img.shape)
    ref = numpy_average(patches, origins, img.shape)
    assert np.abs(ours - ref).max() < 1e-4


def test_feather_has_no_seam_on_a_smooth_gradient() -> None:
    img = gradient(480, 640)
    patches, origins = tile(img, 256, 30)
    # Each patch off by a different constant, as per-patch model outputs are.
    patches = patches + 2.0 * np.arange(6, dtype=np.float32)[:, None, None, None]

    def max_second_difference(out: np.ndarray) -> float:
        dx = np.abs(out[:, :-2] - 2 * out[:, 1:-1] + out[:, 2:]).max()
        dy = np.abs(out[:-2] - 2 * out[1:-1] + out[2:]).max()
        return float(max(dx, dy))

    assert max_second_difference(img) < 1e-3
    avg = merge_patches(patches, origins, img.shape, mode="average")
    fea = merge_patches(patches, origins, img.shape, mode="feather")
    assert max_second_difference(avg) > 0.9  # the plain mean steps at patch edges
    assert max_second_difference(fea) < 0.06
    # Away from overlaps both modes give the patch itself.
    assert np.array_equal(fea[:200, :200], patches[0][:200, :200])


def test_small_images_are_padded_and_cropped_back() -> None:
    img = gradient(100, 70)
    patches, origins = tile(img, 256, 30)
    assert patches.shape == (1, 256, 256, 3) and origins.tolist() == [[0, 0]]
    # Reflect-101 padding: column 70 mirrors column 68.
    assert np.array_equal(patches[0, :100, 70], img[:, 68])
    assert np.array_equal(merge_patches(patches, origins, img.shape), img)


@settings(max_examples=60, deadline=None)
@given(
    h=st.integers(1, 90),
    w=st.integers(1, 90),
    patch=st.integers(1, 40),
    data=st.data(),
    mode=st.sampled_from(["average", "feather"]),
)
def test_tile_then_merge_is_identity(
    h: int, w: int, patch: int, data: st.DataObject, mode: str
) -> None:
    overlap = data.draw(st.integers(0, patch - 1))
    img = np.random.default_rng(h * 91 + w).random((h, w, 2)).astype(np.float32)
    patches, origins = tile(img, patch, overlap)
    assert (origins[:, 0] + patch >= w).any() and (origins[:, 1] + patch >= h).any()
    out = merge_patches(patches, origins, img.shape, mode=mode)  # type: ignore[arg-type]
    assert np.array_equal(out, img)


def test_bad_inputs_name_the_argument() -> None:
    img = np.zeros((40, 50, 3), np.float32)
    with pytest.raises(ValueError, match="overlap"):
        tile(img, 16, 16)
    with pytest.raises(ValueError, match="patch"):
        tile(img, 0, 0)
    with pytest.raises(TypeError, match="patch"):
        tile(img, 16.5, 2)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="img"):
        tile(img.astype(np.float64), 16, 2)
    patches, origins = tile(img, 16, 4)
    with pytest.raises(ValueError, match="mode"):
        merge_patches(patches, origins, img.shape, mode="median")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="origins"):
        merge_patches(patches, origins[:-1], img.shape)
    with pytest.raises(ValueError, match="origins"):
        merge_patches(patches[:1], [[0, 0]], img.shape)  # pixels covered by no patch
    with pytest.raises(ValueError, match="origins"):
        merge_patches(patches[:1], [[60, 0]], img.shape)  # outside the image
    with pytest.raises(ValueError, match="shape"):
        merge_patches(patches, origins, (40, 50, 4))
    with pytest.raises(ValueError, match="shape"):
        merge_patches(patches, origins, (40, 50))
    with pytest.raises(ValueError, match="patches"):
        merge_patches(patches[:, :, :8], origins, img.shape)
    with pytest.raises(TypeError, match="patches"):
        merge_patches(patches.astype(np.float64), origins, img.shape)
    for bad in (np.nan, np.inf, -np.inf):  # a model's NaN would otherwise spread silently
        broken = patches.copy()
        broken[1, 3, 5, 2] = bad
        with pytest.raises(ValueError, match=r"patches: .*finite"):
            merge_patches(broken, origins, img.shape)
