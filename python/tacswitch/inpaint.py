"""The classical fills of marker removal: TELEA and biharmonic inpainting (Rust core), patch
tiling and merging, and the defaults :func:`tacswitch.removal.remove_markers` uses with them.

This module sits below both :mod:`tacswitch.removal` (the ``remove_markers`` dispatcher) and
:mod:`tacswitch.tacdiff` (which runs TELEA for its priors and the hybrid's far markers); it
imports neither.

Conventions: images are numpy ``H x W x C`` (C in 1, 3, 4; colour order **BGR**, as OpenCV) or grey
``H x W``; masks are ``H x W`` bool or uint8, True / nonzero = pixel to fill; patch origins are
``(x, y)`` in pixels of the patch's top-left corner.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch import _native
from tacswitch._checks import MAX_COUNT, aligned, as_count, as_image

MergeMode = Literal["average", "feather"]

#: dtypes the native TELEA, tiling and merging accept.
NATIVE_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))
#: Largest TELEA radius (OpenCV clamps to the same bound).
MAX_RADIUS = 100
#: Dilations (3x3 cross) of an extracted marker mask before inpainting. The paper dilates its
#: mask once, but its extraction had already grown the mask with 5x5 morphology; ours follows
#: the dark core, and one dilation leaves 6-9 % of the marker's soft edge outside the mask (a
#: dark rim that TELEA smears inward and a biharmonic fill extrapolates: on held-out simulated
#: frames the error under the markers is 1.4-2x that of two dilations). Two cover all but
#: 0.2-0.3 % of it.
DEFAULT_DILATE = 2
#: TELEA radius (px) of :func:`remove_markers` (and of the TELEA part of its ``"hybrid"``) when
#: none is given. Chosen on real frames first (``benches/studies/bench_radius.py``, our TELEA on the
#: default adaptive mask, radii 3-24; docs/notes/2026-11-marker-removal.md, "TELEA radius of the
#: default pipeline"): on the two real GelSight Mini frames with
#: markers (FOTS, held-out shifted-mask pixels) the error is lowest at 12 (2.05 at r=3, 1.98 at
#: 12, 2.00 at 16, 2.15 at 24); on the real-frame proxy (8 taxim presses per sensor x 7 marker
#: looks and captures) r=12 beats r=3 in all 64 press x column cells (masked MAE crisp / soft /
#: MJPEG / H.264, GelSight 1.20/1.23/1.74/2.45 -> 1.09/1.16/1.48/2.06, GelSight Mini
#: 1.49/1.59/2.31/2.98 -> 1.25/1.37/1.87/2.50). 12 against 16 is a near tie: 16 is 3-6 % lower
#: on the proxy's soft and compressed columns and on GelSight's crisp dots, but 1 % higher on the
#: real frames and on crisp Mini dots, 6-8 % higher on the Mini's contact markers, ~1.8x the
#: cost; speed breaks the tie. Beyond 16 the real frames get worse (2.07 at 20, 2.15 at 24) while
#: GelSight's 23 px dots keep gaining (the best radius grows with the dot size: pass
#: ``radius=16..24`` for large dots if the time allows). Simulated crisp frames (second): masked
#: MAE 1-5 % lower than at 3 on both sensors; in contact, where a wider mean flattens shading, up
#: to 2.4 % higher. Speed: 3.5-5x r=3's cost (640x480: ~8 ms idle), 37-50x below ``cv2.inpaint``
#: at the same radius. :func:`inpaint_telea` keeps OpenCV's customary 3 as its own default (a
#: drop-in called with the same arguments gives the same fill); ``"ns"`` keeps :data:`NS_RADIUS`.
DEFAULT_RADIUS = 12
#: ``remove_markers(method="ns")``'s radius when none is given: OpenCV's NS was not measured at
#: larger radii on real frames and costs ~10x more at 12 (640x480: 23 -> 266 ms).
NS_RADIUS = 3


def _as_image(img: Any, name: str = "img", *, any_channels: bool = False) -> NDArray[Any]:
    """``img`` as a C-contiguous uint8/uint16/float32 image (see :func:`as_image`)."""
    return as_image(img, name, dtypes=NATIVE_DTYPES, any_channels=any_channels)


def _as_mask(mask: Any, shape: tuple[int, ...]) -> NDArray[np.uint8]:
    """``mask`` as a C-contiguous ``H x W`` uint8 view (bool is reinterpreted, not copied)."""
    if not isinstance(mask, np.ndarray):
        raise TypeError(f"mask: expected a numpy array, got {type(mask).__name__}")
    if mask.dtype == np.bool_:
        mask = mask.view(np.uint8)
    elif mask.dtype != np.uint8:
        raise TypeError(
            f"mask: expected dtype bool or uint8, got {mask.dtype}; use (mask != 0) to convert"
        )
    if mask.ndim == 3 and mask.shape[2] == 1:
        mask = mask[:, :, 0]
    if mask.shape != tuple(shape[:2]):
        raise ValueError(f"mask: expected shape {tuple(shape[:2])} to match img; got {mask.shape}")
    return aligned(mask)


def _as_radius(radius: Any) -> int:
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.integer, np.floating)):
        raise TypeError(f"radius: expected a number of pixels, got {type(radius).__name__}")
    try:
        r = float(radius)
    except OverflowError:  # an int beyond float range
        r = float("inf")
    if not np.isfinite(r) or not 1 <= np.rint(r) <= MAX_RADIUS:
        raise ValueError(f"radius: must be between 1 and {MAX_RADIUS} pixels; got {radius!r}")
    return int(np.rint(r))


#: Float images whose known values exceed this magnitude are inpainted scaled down by a power
#: of two: TELEA's weighted mean is computed relative to a reference pixel in float32, and the
#: differences of values near +-3.4e38 would overflow to +-inf.
_FLOAT_SAFE = 2.0**100


def _float_scale(arr: NDArray[Any], mask: NDArray[np.uint8]) -> float:
    """Power of two to divide a float32 image by so its known values stay below ``_FLOAT_SAFE``
    (1.0 for integer images and ordinary floats)."""
    if arr.dtype != np.float32:
        return 1.0
    known = arr[mask == 0] if arr.ndim == 2 else arr[mask == 0].reshape(-1)
    finite = known[np.isfinite(known)]
    big = float(np.abs(finite).max()) if finite.size else 0.0
    if big <= _FLOAT_SAFE:
        return 1.0
    return float(2.0 ** (int(np.ceil(np.log2(big))) - 100))


def inpaint_telea(img: NDArray[Any], mask: NDArray[Any], radius: float = 3) -> NDArray[Any]:
    """Fills the masked pixels by Telea's fast-marching method (Rust core).

    Drop-in for ``cv2.inpaint(img, mask, radius, cv2.INPAINT_TELEA)``: the same fronts, weights
    (direction x level-set distance x geometric distance) and outward level set up to ``radius``
    pixels, so results agree with OpenCV to about one grey level where OpenCV is not defective.
    Deliberate differences:

    - no ``+0.5`` before rounding and no OpenCV normalised-gradient term (up to +-1.4 grey levels
      of noise): a flat image comes back exactly flat, float images are not biased;
    - the fronts advance in order of arrival time quantised to 1/64 pixel (ties in the order the
      pixels were reached) rather than by a heap on the exact time;
    - holes touching any image border are filled (OpenCV leaves the top row and left column);
    - each 8-connected hole sees only known pixels and its own group of holes (holes closer than
      ``2 * radius + 2`` px are solved together); OpenCV lets a hole borrow a nearby hole's
      freshly filled pixels. Groups run in parallel (rayon; ``RAYON_NUM_THREADS`` caps it),
      bit-identical to one sequential solve.

    Args:
        img: ``H x W`` or ``H x W x C`` (C in 1, 3, 4; BGR order is kept, channels are
            independent) of dtype uint8, uint16 or float32. Masked pixels may hold anything,
            NaN included; unmasked float pixels must be finite.
        mask: ``H x W`` bool or uint8; True / nonzero = fill.
        radius: neighbourhood radius in pixels, ``1..100`` (rounded like OpenCV's ``cvRound``).

    Returns:
        A new array of ``img``'s dtype and shape. Unmasked pixels are bit-identical to ``img``;
        integer outputs are rounded half up and saturated. An empty mask returns a copy.

    Raises:
        TypeError: ``img`` or ``mask`` is not a numpy array of a supported dtype.
        ValueError: bad shapes, ``radius`` out of range, a mask covering every pixel, or NaN/Inf
            in an unmasked pixel; the message names the argument.
    """
    arr = _as_image(img)
    m = _as_mask(mask, arr.shape)
    r = _as_radius(radius)
    scale = _float_scale(arr, m)
    if scale == 1.0:
        out: NDArray[Any] = _native.inpaint_telea(arr, m, r)
        return out
    # Exact: dividing by a power of two only shifts exponents; unmasked pixels are restored.
    with np.errstate(over="ignore", invalid="ignore"):
        out = _native.inpaint_telea(arr / np.float32(scale), m, r) * np.float32(scale)
    known = m == 0
    out[known] = arr[known]
    return out


def inpaint_biharmonic(img: NDArray[Any], mask: NDArray[Any]) -> NDArray[Any]:
    """Fills each hole with the smoothest surface through the known pixels around it (Rust core).

    Minimises the discrete thin-plate energy (the sum of squared 5-point Laplacians) over the
    masked pixels. Away from the image border this is the 13-point biharmonic equation that
    ``skimage.restoration.inpaint_biharmonic(img, mask, split_into_regions=True,
    channel_axis=-1)`` solves (results agree to solver precision); holes touching the border
    are filled with natural boundary conditions. Unlike TELEA's weighted mean, which flattens
    shading across a hole, it continues gradients and curvature: on contact shading it is the
    more accurate classical fill (on flat gel TELEA is as good and faster). Each group of
    coupled holes is one sparse symmetric positive definite system, factorised in float64 by
    an envelope Cholesky and solved for every channel; groups run in parallel (rayon), with the
    GIL released. 7-10x faster than scikit-image on marker masks (BENCHMARKS.md, "Biharmonic
    inpainting").

    Args:
        img: ``H x W`` or ``H x W x C`` (C in 1, 3, 4; BGR kept, channels independent) uint8,
            uint16 or float32. Masked pixels may hold anything, NaN included; unmasked float
            pixels must be finite.
        mask: ``H x W`` bool or uint8; True / nonzero = fill.

    Returns:
        A new array of ``img``'s dtype and shape; unmasked pixels are bit-identical to ``img``;
        integer outputs are rounded half up and saturated (the surface may overshoot the
        known values near strong edges; it is clipped to the dtype's range).

    Raises:
        TypeError: ``img`` or ``mask`` is not a numpy array of a supported dtype.
        ValueError: bad shapes, a mask covering every pixel, a single hole too large for the
            direct solver (about 20 000 pixels; use :func:`inpaint_telea`), or NaN/Inf in an
            unmasked pixel; the message names the argument.
    """
    arr = _as_image(img)
    m = _as_mask(mask, arr.shape)
    out: NDArray[Any] = _native.inpaint_biharmonic(arr, m)
    return out


def tile(
    img: NDArray[Any], patch: int = 256, overlap: int = 30
) -> tuple[NDArray[Any], NDArray[np.int64]]:
    """Cuts an image into overlapping ``patch x patch`` patches (the paper's layout).

    Starts are ``0, patch - overlap, 2 (patch - overlap), ...`` along each axis, the last patch
    snapped to the image edge: 640 x 480 with ``patch=256, overlap=30`` gives 3 x 2 = 6 patches at
    x = 0, 226, 384 and y = 0, 224. A side shorter than ``patch`` is padded by reflection
    (``cv2.BORDER_REFLECT_101``); :func:`merge_patches` crops it away.

    Args:
        img: ``H x W`` or ``H x W x C`` (any C >= 1) uint8, uint16 or float32 (BGR kept as is).
        patch: patch side in pixels, >= 1.
        overlap: nominal overlap in pixels, ``0 <= overlap < patch``.

    Returns:
        ``(patches, origins)``: ``N x patch x patch [x C]`` of ``img``'s dtype, row by row
        (y outer, x inner), and ``N x 2`` int64 top-left corners ``(x, y)``.

    Raises:
        TypeError / ValueError: a bad ``img``, ``patch`` or ``overlap`` (naming it), including
            a layout whose patches would need more than 2 GiB (``tile(img, 256, 255)`` on a
            640 x 480 frame asks for 86 625 patches, 17 GB).
    """
    arr = _as_image(img, any_channels=True)
    p = as_count(patch, "patch", 1)
    o = as_count(overlap, "overlap", 0)
    # The native side also refuses layouts needing more than 2 GiB of patches (e.g.
    # overlap = patch - 1: one patch per pixel), naming patch or overlap.
    if o >= p:
        raise ValueError(f"overlap: must be smaller than patch ({p}); got {o}")
    patches, origins = _native.tile(arr, p, o)
    return patches, origins


def merge_patches(
    patches: NDArray[Any],
    origins: Any,
    shape: tuple[int, ...],
    mode: MergeMode = "average",
) -> NDArray[Any]:
    """Merges square patches back into an image.

    ``"average"`` is the paper's plain mean of overlapping pixels. ``"feather"`` weighs each patch
    by a raised-cosine ramp over the overlap (from the smallest overlap between neighbouring
    origins) rising from every patch edge, which hides the seams that patches disagreeing by a
    small offset leave with a plain mean. Both are computed relative to the first covering patch,
    so unmodified patches reproduce the image bit for bit. Patch pixels outside the image (the
    padding of :func:`tile`) are ignored. Equivalent to accumulating ``weight * patch`` and
    ``weight`` in numpy and dividing.

    Args:
        patches: ``N x P x P`` or ``N x P x P x C``, uint8, uint16 or float32.
        origins: ``N x 2`` top-left corners ``(x, y)`` in pixels, as returned by :func:`tile`.
        shape: output ``(H, W)`` or ``(H, W, C)``; C must match the patches.
        mode: ``"average"`` or ``"feather"``.

    Returns:
        ``H x W [x C]`` of the patches' dtype (integers rounded half up).

    Raises:
        ValueError: shapes disagree, an origin lies outside the image, a pixel is covered by no
            patch, NaN or inf in float32 patches, or an unknown ``mode``; the message names the
            argument.
    """
    if not isinstance(patches, np.ndarray):
        raise TypeError(f"patches: expected a numpy array, got {type(patches).__name__}")
    if not isinstance(shape, (tuple, list)):
        raise TypeError(f"shape: expected a tuple (H, W) or (H, W, C), got {type(shape).__name__}")
    if patches.dtype not in NATIVE_DTYPES:
        raise TypeError(f"patches: expected dtype uint8, uint16 or float32, got {patches.dtype}")
    if patches.ndim not in (3, 4) or patches.shape[1] != patches.shape[2]:
        raise ValueError(f"patches: expected N x P x P or N x P x P x C; got {patches.shape}")
    try:
        org = np.asarray(origins, dtype=np.int64)
    except OverflowError:
        raise ValueError(f"origins: expected (x, y) integers in [0, {MAX_COUNT}]") from None
    except (TypeError, ValueError) as exc:
        raise TypeError(f"origins: expected an N x 2 array of (x, y) ({exc})") from None
    if org.ndim != 2 or org.shape != (patches.shape[0], 2):
        raise ValueError(
            f"origins: expected shape ({patches.shape[0]}, 2), one (x, y) per patch; "
            f"got {org.shape}"
        )
    if (org < 0).any() or (org > MAX_COUNT).any():
        raise ValueError(f"origins: expected (x, y) integers in [0, {MAX_COUNT}]")
    dims = tuple(as_count(v, "shape", 1) for v in shape)
    channels = patches.shape[3] if patches.ndim == 4 else None
    if len(dims) not in (2, 3) or min(dims) < 1:
        raise ValueError(f"shape: expected (H, W) or (H, W, C) of positive sizes; got {shape}")
    if len(dims) == 3 and dims[2] != channels:
        raise ValueError(f"shape: {dims[2]} channels but the patches have {channels}")
    if len(dims) == 2 and channels is not None:
        raise ValueError(f"shape: (H, W) given but the patches have {channels} channels")
    if not isinstance(mode, str) or mode not in ("average", "feather"):
        raise ValueError(f"mode: must be 'average' or 'feather'; got {mode!r}")
    if patches.dtype == np.float32 and patches.size:
        # min / max propagate NaN and show +-inf without a temporary the patches' size.
        lo, hi = float(patches.min()), float(patches.max())
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ValueError("patches: float32 patches must be finite; got NaN or inf")
    out: NDArray[Any] = _native.merge_patches(
        aligned(patches), aligned(org), dims[0], dims[1], mode
    )
    return out
