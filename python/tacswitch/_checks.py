"""Argument validation shared by the public functions: every error names the argument."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

VALID_CHANNELS = (1, 3, 4)


def as_image(
    img: Any,
    name: str = "img",
    *,
    dtypes: tuple[np.dtype, ...] = (np.dtype(np.uint8),),
    any_channels: bool = False,
) -> NDArray[Any]:
    """Returns ``img`` as a C-contiguous ``H x W`` or ``H x W x C`` array of one of ``dtypes``.

    C must be 1, 3 or 4 unless ``any_channels``.
    Copies only when the layout is not C-contiguous. Raises ``TypeError`` for a non-array or
    another dtype, ``ValueError`` for a bad shape; messages name ``name``.
    """
    if not isinstance(img, np.ndarray):
        raise TypeError(f"{name}: expected a numpy array, got {type(img).__name__}")
    if img.dtype not in dtypes:
        wanted = ", ".join(str(d) for d in dtypes)
        hint = ("np.clip(x, 0, 255).astype(np.uint8) for 0..255 floats"
                if dtypes == (np.dtype(np.uint8),) else "img.astype(np.float32)")
        raise TypeError(f"{name}: expected dtype {wanted}, got {img.dtype}; convert explicitly, "
                        f"e.g. {hint}")
    bad_channels = img.ndim == 3 and (
        img.shape[2] < 1 or (not any_channels and img.shape[2] not in VALID_CHANNELS)
    )
    if img.ndim not in (2, 3) or bad_channels:
        raise ValueError(
            f"{name}: expected a grey H x W or BGR H x W x 3 (or BGRA x 4) image; "
            f"got shape {img.shape}"
        )
    if img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"{name}: image must be at least 1 x 1 pixels; got shape {img.shape}")
    return np.ascontiguousarray(img)


def as_image_u8(img: Any, name: str = "img") -> NDArray[np.uint8]:
    """:func:`as_image` for uint8 images (grey, BGR or BGRA)."""
    return as_image(img, name)


def as_count(value: Any, name: str, minimum: int) -> int:
    """Checks an integer argument (bools refused) against a minimum."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name}: must be >= {minimum}; got {value}")
    return int(value)


def as_points(pts: Any, name: str, *, check_finite: bool = True) -> NDArray[np.float32]:
    """Returns ``pts`` as a C-contiguous ``N x 2`` float32 array of ``(x, y)``.

    ``check_finite=False`` leaves the NaN/Inf check to the native call, which raises the same
    ``ValueError`` naming ``name`` (it saves a pass on hot paths).
    """
    if isinstance(pts, np.ndarray) and pts.dtype == np.bool_:
        raise TypeError(f"{name}: expected numeric (x, y) points, got a boolean array")
    try:
        arr = np.ascontiguousarray(pts, dtype=np.float32)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected an N x 2 array of (x, y) points ({exc})") from None
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.float32)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: expected an N x 2 array of (x, y) points; got shape {arr.shape}")
    if check_finite and not np.isfinite(arr).all():
        bad = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
        raise ValueError(f"{name}: point {bad} is not finite ({arr[bad, 0]}, {arr[bad, 1]})")
    return arr


def as_valid(valid: Any, n: int, name: str = "valid") -> NDArray[np.bool_]:
    """Returns ``valid`` as a length-``n`` bool array."""
    arr = np.asarray(valid)
    if arr.dtype != np.bool_:
        raise TypeError(f"{name}: expected a boolean array, got dtype {arr.dtype}")
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},) to match the motion rows; got {arr.shape}")
    return np.ascontiguousarray(arr)


def as_motion(motion: Any, name: str = "motion") -> NDArray[np.float32]:
    """Returns ``motion`` as ``N x 2`` float32; NaN rows are allowed (lost markers), Inf is not."""
    try:
        arr = np.asarray(motion, dtype=np.float32)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected an N x 2 array of (dx, dy) ({exc})") from None
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.float32)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: expected an N x 2 array of (dx, dy); got shape {arr.shape}")
    if np.isinf(arr).any():
        raise ValueError(f"{name}: contains infinite values")
    return np.ascontiguousarray(arr)


def positive_or_none(value: float | None, name: str) -> float | None:
    """Checks an optional positive finite number."""
    if value is None:
        return None
    v = float(value)
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be a positive, finite number; got {value!r}")
    return v
