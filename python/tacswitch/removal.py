"""``remove_markers``: the marker -> markerless front door, which chooses between the classical
fills (:mod:`tacswitch.inpaint`: TELEA, biharmonic; NS from OpenCV) and the diffusion model
(:mod:`tacswitch.tacdiff`: TacDiff, hybrid).

It sits above both; neither imports it (``DESIGN.md``: imports run one way).

Conventions: images are numpy ``H x W x C`` (C in 1, 3, 4; colour order **BGR**, as OpenCV) or grey
``H x W``; masks are ``H x W`` bool or uint8, True / nonzero = pixel to fill.
"""

from __future__ import annotations

import functools
import inspect
import os
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_count, as_seed, check_model_arg
from tacswitch.inpaint import (
    DEFAULT_RADIUS,
    NS_RADIUS,
    _as_image,
    _as_mask,
    _as_radius,
    inpaint_biharmonic,
    inpaint_telea,
)
from tacswitch.markers import extract_markers

InpaintMethod = Literal["telea", "biharmonic", "ns", "tacdiff", "hybrid"]
#: Methods that need the learned model (tacswitch.tacdiff, onnxruntime).
_MODEL_METHODS = ("tacdiff", "hybrid")


def _check_ns_input(arr: NDArray[Any], m: NDArray[np.uint8]) -> None:
    """What ``cv2.inpaint(..., INPAINT_NS)`` accepts, checked up front with errors naming the
    argument: uint8 grey or 3-channel, uint16/float32 grey; a mask leaving a known pixel;
    finite known float pixels."""
    grey = arr.ndim == 2 or arr.shape[2] == 1
    if arr.dtype == np.uint8 and not (grey or arr.shape[2] == 3):
        raise ValueError(f"img: method 'ns' takes grey or 3-channel uint8 images; got {arr.shape}")
    if arr.dtype != np.uint8 and not grey:
        raise ValueError(f"img: method 'ns' takes {arr.dtype} images as grey H x W only "
                         f"(OpenCV's limit); got {arr.shape}; use method='telea'")
    if m.all():
        raise ValueError("mask: covers every pixel; at least one known pixel is needed")
    if arr.dtype == np.float32:
        known = arr.reshape(arr.shape[0], arr.shape[1])[m == 0]
        if not np.isfinite(known).all():
            raise ValueError("img: unmasked pixels must be finite (NaN/Inf found)")


@functools.lru_cache(maxsize=1)
def _extract_keywords() -> tuple[str, ...]:
    """The options of :func:`tacswitch.extract_markers` that :func:`remove_markers` passes on."""
    return tuple(p for p in inspect.signature(extract_markers).parameters
                 if p not in ("img", "dilate"))


def _check_extract_keywords(opts: dict[str, Any]) -> None:
    """The extra keywords of :func:`remove_markers` must be options of
    :func:`tacswitch.extract_markers` (else Python's own error would blame extract_markers,
    or none at all when a mask is given)."""
    allowed = _extract_keywords()
    for key in opts:
        if key not in allowed:
            raise TypeError(f"{key}: not an argument of remove_markers (its extra keywords are "
                            f"extract_markers' options: {', '.join(allowed)})")


def remove_markers(
    img: NDArray[Any],
    mask: NDArray[Any] | None = None,
    method: InpaintMethod = "telea",
    radius: float | None = None,
    dilate: int | Literal["auto"] | None = None,
    *,
    steps: int | None = None,
    ref: NDArray[Any] | None = None,
    seed: int | None = 0,
    model: str | os.PathLike[str] | None = None,
    separation: int | None = None,
    orientations: int | None = None,
    device: str = "auto",
    **extract_opts: Any,
) -> NDArray[Any]:
    """Removes the painted markers of a tactile image (marker -> markerless).

    Args:
        img: ``H x W x 3`` uint8 **BGR** (grey ``H x W`` and BGRA accepted; uint16/float32 work
            with a given ``mask`` and ``method="telea"``).
        mask: ``H x W`` bool/uint8 marker mask. It must cover the markers' soft edges: a rim
            of darkened gel left outside it is smeared into the fill (TELEA) or extrapolated
            (biharmonic, TacDiff). None: extract the markers first with
            :func:`tacswitch.extract_markers` (markers cut by the frame border included) and
            grow the mask as ``dilate`` says.
        method: ``"telea"`` (:func:`inpaint_telea`, the Rust core), ``"biharmonic"``
            (:func:`inpaint_biharmonic`, the Rust core; smoother on contact shading), ``"ns"``
            (``cv2.inpaint(img, mask, radius, cv2.INPAINT_NS)``, uint8/uint16/float32 grey or
            3-channel, as OpenCV allows), ``"tacdiff"`` (the diffusion model, onnxruntime;
            uint8 BGR only, :func:`tacswitch.tacdiff.inpaint_tacdiff`) or ``"hybrid"`` (TacDiff
            on the markers in or near the contact, TELEA elsewhere,
            :func:`tacswitch.tacdiff.inpaint_hybrid`).
        radius: inpainting radius in pixels (TELEA, NS, and the TELEA part of ``"hybrid"``).
            None (default): :data:`DEFAULT_RADIUS` (12, the best on real frames) for TELEA and
            hybrid, :data:`NS_RADIUS` (3) for NS.
        dilate: growth of the extracted mask (ignored when ``mask`` is given). None (default)
            or ``"auto"``: adaptive, per marker, until the ring around it is consistent with
            the local background (``extract_markers(dilate="auto")``): about one pixel on crisp
            lossless markers, several on soft or compressed ones. An integer: that many 3x3-cross
            dilations instead (the previous default was :data:`DEFAULT_DILATE`).
        steps: TacDiff sampler steps, 1..1000 (default 1: the shipped model's best masked
            error).
        ref: ``"hybrid"`` only: a no-contact frame of the same sensor to find the contact
            against (default: found from local texture).
        seed: TacDiff noise seed (None: fresh randomness each call).
        model: TacDiff ONNX file, or ``"fast"`` for the shipped narrow model (default: the
            shipped model).
        separation: TacDiff / hybrid: holes within this many px of one another are filled in
            separate passes (default :data:`tacswitch.tacdiff.infer.SEPARATION`, 4; 0: one
            pass), see :func:`tacswitch.tacdiff.inpaint_tacdiff`.
        orientations: TacDiff / hybrid: the network runs the frame in this many orientations
            (1, 2, 4 or 8: as is, mirrored, turned) and averages them; None (default): 4 for
            the default model (about 2 % lower error on real frames with painted markers, 3x
            the time), 1 for a narrow model such as ``model="fast"``. See
            :func:`tacswitch.tacdiff.inpaint_tacdiff`.
        device: TacDiff / hybrid: where the network runs: ``"auto"`` (default: a CUDA GPU
            when onnxruntime offers one, else the CPU), ``"cpu"`` or ``"cuda"``
            (``ValueError`` naming ``device`` when onnxruntime has no CUDA here). The
            classical methods run on the CPU.
        **extract_opts: passed to :func:`tacswitch.extract_markers` when ``mask`` is None.

    Returns:
        A new image of ``img``'s dtype and shape; unmasked pixels are bit-identical to ``img``.

    Raises:
        TypeError / ValueError: bad arguments (the message names the argument), or a method that
            is not available.
    """
    if not isinstance(method, str) or method not in ("telea", "biharmonic", "ns", *_MODEL_METHODS):
        raise ValueError("method: must be 'telea', 'biharmonic', 'ns', 'tacdiff' or 'hybrid'; "
                         f"got {method!r}")
    _check_extract_keywords(extract_opts)
    if mask is None and isinstance(img, np.ndarray) and img.dtype != np.uint8:
        # Checked first: the generic check would advise float32, which extraction refuses too.
        raise TypeError(f"img: without a mask the markers are extracted, which needs dtype "
                        f"uint8; got {img.dtype}; convert explicitly (e.g. "
                        "np.clip(img, 0, 255).astype(np.uint8)) or pass mask=")
    arr = _as_image(img)
    if method in _MODEL_METHODS:
        check_model_arg(model)
        seed = as_seed(seed)
        # The TacDiff entry points check these and own their defaults.
        passes: dict[str, Any] = {"orientations": orientations, "device": device}
        if separation is not None:
            passes["separation"] = separation
    elif not isinstance(device, str) or device not in ("auto", "cpu", "cuda"):
        # Named even here; the classical fills run on the CPU whatever the device.
        raise ValueError(f"device: must be 'auto', 'cpu' or 'cuda'; got {device!r}")
    if method not in _MODEL_METHODS and orientations is not None:
        raise ValueError("orientations: applies to method='tacdiff' or 'hybrid' only; got "
                         f"method={method!r}")
    if mask is None:
        auto = dilate is None or (isinstance(dilate, str) and dilate == "auto")
        # Unbounded: extraction caps dilations at H + W (more change nothing).
        grow: int | Literal["auto"] = "auto" if auto else as_count(dilate, "dilate", 0, None)
        # The mask covers markers cut by the frame edge whatever exclude_border says.
        m = extract_markers(arr, dilate=grow, **extract_opts).mask.view(np.uint8)
        if m.all():
            raise ValueError(f"dilate: the marker mask grown by {grow!r} covers every pixel; "
                             "nothing is left to inpaint from")
    else:
        m = _as_mask(mask, arr.shape)
    if radius is None:
        radius = NS_RADIUS if method == "ns" else DEFAULT_RADIUS
    else:
        # Checked for every method, so a bad value is named even where the fill has no radius
        # (biharmonic solves over the whole hole; the CLI warns that --radius is ignored there).
        _as_radius(radius)
    if method == "telea":
        return inpaint_telea(arr, m, radius)
    if method == "biharmonic":
        return inpaint_biharmonic(arr, m)
    # TacDiff is imported on demand: it would double the time of ``import tacswitch``.
    if method == "tacdiff":
        from tacswitch.tacdiff import DEFAULT_STEPS, inpaint_tacdiff

        k = DEFAULT_STEPS if steps is None else steps
        return inpaint_tacdiff(arr, m, k, seed=seed, model=model, **passes)
    if method == "hybrid":
        from tacswitch.tacdiff import inpaint_hybrid

        return inpaint_hybrid(arr, m, ref, steps=steps, radius=radius, seed=seed,
                              model=model, **passes)[0]
    r = _as_radius(radius)
    _check_ns_input(arr, m)
    if not m.any():
        return arr.copy()
    import cv2

    filled = cv2.inpaint(arr, m, r, cv2.INPAINT_NS)
    # OpenCV leaves its own borders alone but rounds everywhere; keep unmasked pixels exact.
    out = arr.copy()
    sel = m.astype(bool)
    out[sel] = filled.reshape(arr.shape)[sel]
    return out
