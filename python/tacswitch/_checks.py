"""Argument validation shared by the public functions: every error names the argument."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

VALID_CHANNELS = (1, 3, 4)
#: Default upper bound of integer arguments: every count, size and area the API takes fits in a
#: signed 32-bit integer (larger values are mistakes, and overflow the native side's types).
MAX_COUNT = 2**31 - 1


def aligned(arr: NDArray[Any]) -> NDArray[Any]:
    """``arr`` itself when C-contiguous and aligned, else an aligned C-contiguous copy.

    ``np.ascontiguousarray`` keeps an unaligned array (e.g. a view at an odd byte offset of a
    buffer) as it is; the native code needs aligned elements.
    """
    flags = arr.flags  # one flags object, not one per attribute (hot path: every frame)
    if flags.c_contiguous and flags.aligned:
        return arr
    return np.array(arr, order="C", copy=True)


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
    return aligned(img)


def as_image_u8(img: Any, name: str = "img") -> NDArray[np.uint8]:
    """:func:`as_image` for uint8 images (grey, BGR or BGRA)."""
    return as_image(img, name)


def as_count(value: Any, name: str, minimum: int, maximum: int | None = MAX_COUNT) -> int:
    """Checks an integer argument (bools refused) against ``[minimum, maximum]``.

    ``maximum=None``: no upper bound (for counts the callee caps itself, e.g. dilations that
    stop once the mask is full). Raises ``TypeError`` for a non-integer, ``ValueError`` outside
    the range; both messages read ``"NAME: expected an integer in [a, b], got ..."``.
    """
    span = f"[{minimum}, {maximum}]" if maximum is not None else f">= {minimum}"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected an integer {'in ' if maximum is not None else ''}"
                        f"{span}, got {type(value).__name__}")
    if value < minimum or (maximum is not None and value > maximum):
        raise ValueError(f"{name}: expected an integer {'in ' if maximum is not None else ''}"
                         f"{span}, got {short_repr(int(value))}")
    return int(value)


def short_repr(value: Any, limit: int = 40) -> str:
    """``repr(value)`` cut to about ``limit`` characters (a 400-digit integer in an error
    message would bury it)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit - 12]}...({len(text)} chars)"


def as_number(value: Any, name: str, minimum: float | None = None,
              maximum: float | None = None) -> float:
    """Checks a finite real argument (bools refused) against an optional closed range.

    Integers too large for a float (``10**400``) are out of range, not an OverflowError.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                      np.floating)):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}")
    try:
        v = float(value)
    except OverflowError:
        v = float("inf") if value > 0 else float("-inf")
    lo = -np.inf if minimum is None else minimum
    hi = np.inf if maximum is None else maximum
    if not np.isfinite(v) or not lo <= v <= hi:
        raise ValueError(f"{name}: expected a finite number in [{lo}, {hi}], got "
                         f"{short_repr(value)}")
    return v


def as_choice(value: Any, name: str, choices: tuple[str, ...]) -> str:
    """Checks a string argument against its allowed values."""
    if not isinstance(value, str) or value not in choices:
        allowed = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name}: must be one of {allowed}; got {value!r}")
    return value


def as_seed(seed: Any, name: str = "seed") -> int | None:
    """An optional random seed: None or an integer in ``[0, 2**32 - 1]`` (numpy's range)."""
    if seed is None:
        return None
    return as_count(seed, name, 0, 2**32 - 1)


#: JPEG quality range of the simulator and capture models (libjpeg's scale; OpenCV silently
#: clamps values outside it, so they are refused here instead).
JPEG_QUALITY_RANGE = (1, 100)


def as_jpeg_quality(quality: Any, name: str = "jpeg_quality") -> int | None:
    """An optional JPEG quality: None (lossless) or an integer in :data:`JPEG_QUALITY_RANGE`.

    Shared by the simulator (``jpeg_quality``) and the command line (``--jpeg``: pass its
    option name as ``name``).
    """
    if quality is None:
        return None
    return as_count(quality, name, *JPEG_QUALITY_RANGE)


def as_path(path: Any, name: str) -> Any:
    """``path`` when it is a ``str`` or ``os.PathLike`` (e.g. a ``pathlib.Path``), else a
    ``TypeError`` naming ``name`` (``Path(3)`` fails deep inside pathlib)."""
    import os

    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{name}: expected a path (str or os.PathLike), got "
                        f"{type(path).__name__}")
    return path


def as_rng(seed: Any, name: str = "seed") -> np.random.Generator:
    """A ``numpy.random.Generator`` from ``seed``: None (fresh randomness), an integer >= 0, a
    sequence of them (e.g. ``(dataset_seed, index)``), a ``SeedSequence`` or ``BitGenerator``,
    or a Generator (used as it is). Anything else: an error naming ``name`` (numpy's own
    names no argument)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None or isinstance(seed, (np.random.SeedSequence, np.random.BitGenerator)):
        return np.random.default_rng(seed)
    if isinstance(seed, (list, tuple, np.ndarray)):
        parts = list(np.asarray(seed, dtype=object).ravel()) if isinstance(seed, np.ndarray) \
            else list(seed)
        if not parts:
            raise ValueError(f"{name}: expected an integer >= 0 or a non-empty sequence of them; "
                             "got an empty sequence")
        values = [as_count(v, name, 0, None) for v in parts]
        return np.random.default_rng(values)
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"{name}: expected None, an integer >= 0, a sequence of them or a numpy "
                        f"Generator; got {type(seed).__name__}")
    return np.random.default_rng(as_count(seed, name, 0, None))


def as_points(pts: Any, name: str, *, check_finite: bool = True) -> NDArray[np.float32]:
    """Returns ``pts`` as a C-contiguous ``N x 2`` float32 array of ``(x, y)``.

    ``check_finite=False`` leaves the NaN/Inf check to the native call, which raises the same
    ``ValueError`` naming ``name`` (it saves a pass on hot paths).
    """
    if isinstance(pts, np.ndarray) and pts.dtype == np.bool_:
        raise TypeError(f"{name}: expected numeric (x, y) points, got a boolean array")
    try:
        arr = aligned(np.asarray(pts, dtype=np.float32))
    except (TypeError, ValueError, OverflowError) as exc:
        raise TypeError(f"{name}: expected an N x 2 array of (x, y) points ({exc})") from None
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.float32)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: expected an N x 2 array of (x, y) points; got shape {arr.shape}")
    if check_finite and not np.isfinite(arr).all():
        bad = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
        raise ValueError(f"{name}: point {bad} is not finite ({arr[bad, 0]}, {arr[bad, 1]})")
    return arr


#: How far outside the frame a point may lie, as a fraction of the frame's width / height: a
#: marker cut by the border has its centre near the border; a point farther out is taken for
#: pixels of another resolution (centres from a 640x480 frame given with a 320x240 one).
OUTSIDE_FRAME_FRACTION = 0.125


def check_points_in_frame(pts: NDArray[np.float32], height: int, width: int, name: str
                          ) -> None:
    """``ValueError`` naming ``name`` when a point ``(x, y)`` lies outside the ``width x
    height`` frame by more than :data:`OUTSIDE_FRAME_FRACTION` of its side."""
    if not len(pts):
        return
    mx, my = OUTSIDE_FRAME_FRACTION * width, OUTSIDE_FRAME_FRACTION * height
    x, y = pts[:, 0], pts[:, 1]
    out = (x < -mx) | (x > width - 1 + mx) | (y < -my) | (y > height - 1 + my)
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise ValueError(f"{name}: point {i} ({x[i]:.1f}, {y[i]:.1f}) lies outside the "
                         f"{width}x{height} frame ({int(out.sum())} of {len(pts)} points); "
                         "points are (x, y) pixels of this frame (taken at another "
                         "resolution?)")


def as_valid(valid: Any, n: int, name: str = "valid") -> NDArray[np.bool_]:
    """Returns ``valid`` as a length-``n`` bool array."""
    arr = np.asarray(valid)
    if arr.dtype != np.bool_:
        raise TypeError(f"{name}: expected a boolean array, got dtype {arr.dtype}")
    if arr.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},) to match the motion rows; got {arr.shape}")
    return aligned(arr)


def as_motion(motion: Any, name: str = "motion") -> NDArray[np.float32]:
    """Returns ``motion`` as ``N x 2`` float32; NaN rows are allowed (lost markers), Inf is not."""
    try:
        arr = np.asarray(motion, dtype=np.float32)
    except (TypeError, ValueError, OverflowError) as exc:
        raise TypeError(f"{name}: expected an N x 2 array of (dx, dy) ({exc})") from None
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.float32)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: expected an N x 2 array of (dx, dy); got shape {arr.shape}")
    if np.isinf(arr).any():
        raise ValueError(f"{name}: contains infinite values")
    return aligned(arr)


def positive_or_none(value: float | None, name: str) -> float | None:
    """Checks an optional positive finite number."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}: expected a positive number or None, got {type(value).__name__}")
    try:
        v = float(value)
    except OverflowError:
        v = float("inf")
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: must be a positive, finite number; got {value!r}")
    return v


def check_extract_options(opts: dict[str, Any]) -> dict[str, Any]:
    """Validates the options :func:`tacswitch.extract_markers` and :class:`MarkerTracker` share
    (``polarity``, ``block_size``, ``threshold``, ``min_area``, ``max_area``, ``min_fill``,
    ``max_aspect``, ``exclude_border``) and returns them converted for the native side.

    Only the keys present are checked; every error names its option.
    """
    out = dict(opts)
    if "polarity" in out:
        out["polarity"] = as_choice(out["polarity"], "polarity", ("dark", "bright"))
    for name, minimum in (("block_size", 3), ("min_area", 0), ("max_area", 0)):
        if out.get(name) is not None:
            out[name] = as_count(out[name], name, minimum)
    if out.get("threshold") is not None:
        out["threshold"] = as_number(out["threshold"], "threshold", 0.0)
    if "min_fill" in out:
        out["min_fill"] = as_number(out["min_fill"], "min_fill", 0.0, 1.0)
    if "max_aspect" in out:
        out["max_aspect"] = as_number(out["max_aspect"], "max_aspect", 1.0)
    if "exclude_border" in out:
        flag = out["exclude_border"]
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"exclude_border: expected a bool, got {type(flag).__name__}")
        out["exclude_border"] = bool(flag)
    return out


def check_model_arg(model: Any, name: str = "model") -> None:
    """An ONNX model argument must be None, a path or a shipped model's name (a str)."""
    import os

    if model is not None and not isinstance(model, (str, os.PathLike)):
        raise TypeError(f"{name}: expected a path to an ONNX file, a shipped model name or None, "
                        f"got {type(model).__name__}")


def check_downsampled_size(shape: tuple[int, ...], factor: int, minimum: int,
                           name: str = "img") -> None:
    """A frame ``shape`` downsampled by ``factor`` (1: as it is) must keep both sides
    >= ``minimum`` px.

    ``minimum`` is the smallest side the consumer (e.g. a network's stride) can take.
    """
    h, w = int(shape[0]) // factor, int(shape[1]) // factor
    if min(h, w) < minimum:
        after = "" if factor == 1 else f" after the model's {factor}x downsampling ({h} x {w} px)"
        raise ValueError(f"{name}: a {shape[0]} x {shape[1]} frame is too small{after}: both "
                         f"sides must be at least {minimum} px")


#: Largest ``gain`` of the motion rules and models: 4000x the measured press gains (0.04-0.25), yet
#: small enough that the motions it scales stay finite in float32.
MAX_GAIN = 1000.0


def check_gain(gain: Any) -> float:
    """``gain`` of the training-free motion rules (:mod:`tacswitch.motion.mechanics`,
    :mod:`~tacswitch.motion.heuristic`) as a float; ``ValueError`` naming it unless a finite
    number in [0, :data:`MAX_GAIN`]."""
    if isinstance(gain, (bool, np.bool_)) or not isinstance(gain, (int, float, np.integer,
                                                                    np.floating)):
        raise ValueError(f"gain: expected a number >= 0 or a sensor name; got "
                         f"{type(gain).__name__}")
    try:
        value = float(gain)
    except OverflowError:  # an integer beyond float range (10**400): out of range, not a crash
        value = float("inf")
    if not (np.isfinite(value) and 0 <= value <= MAX_GAIN):
        raise ValueError(f"gain: must be a number in [0, {MAX_GAIN:g}]; got {short_repr(gain)}")
    return value


def process_count(workers: int, jobs: int) -> int:
    """Processes for a pool of ``jobs`` asked for with ``workers``: never more than there are
    jobs or CPU cores (each process holds its own frames and models; a thousand of them exhaust
    the machine before finishing one job). At least 1."""
    import os

    return max(1, min(workers, jobs, os.cpu_count() or 1))
