"""The learned motion regressor: :class:`MotionModel`, an ONNX model run with onnxruntime (numpy
only; never imports torch). :func:`tacswitch.predict_motion` (:mod:`tacswitch.motion.infer`)
chooses between it and the training-free methods.

The ONNX graph holds the normalisation and the bilinear read-out at the marker centres (see
:mod:`tacswitch.motion.export`), so this module only validates arguments, brings frames to the
model's working scale and runs the session.

Why a reference frame: a single markerless frame shows the gel's shape, not how far a stuck
contact has been dragged sideways — in the simulator the stuck-zone shear leaves no trace in the
image at all, so a single-frame regressor can only guess it (measured: no better than predicting
zero). Against an earlier frame of the same contact, the imprint's own displacement shows it. The
shipped model therefore predicts the motion from ``ref`` to ``img``.

Working scale: the shipped model was trained on GelSight-Mini-like frames, 320 x 240 at
0.059 mm/px. A frame at least 1.5 times wider than the model's working width is area-downsampled
by the integer factor ``round(W / work_width)`` (640 x 480 -> 320 x 240), centres are divided by
it and the motion multiplied by it, so inputs and outputs stay in the caller's pixels.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import (
    as_image_u8,
    as_points,
    check_downsampled_size,
    check_gain,
)
from tacswitch._ort import cached, open_session

__all__ = ["DEFAULT_MODEL", "SHIPPED", "MotionModel", "default_model_path", "load_model",
           "model_path"]

#: File name of the shipped default model under ``tacswitch/models``.
DEFAULT_MODEL = "motion_unet.onnx"

#: Shipped models by name (``model="single"``): the default consistent model (pair and single
#: frame), and the single-frame model trained at scale on the simulator (first press-law
#: calibration).
SHIPPED = {"default": DEFAULT_MODEL, "single": "motion_single.onnx"}


def default_model_path() -> Path:
    """Path of the shipped default model."""
    return Path(__file__).resolve().parent.parent / "models" / DEFAULT_MODEL


def model_path(model: str | os.PathLike[str] | None) -> Path:
    """The ONNX file of ``model``: None or ``"default"`` (the shipped default), ``"single"``
    (the shipped single-frame model), or a path."""
    if model is None or (isinstance(model, str) and model in SHIPPED):
        return default_model_path().parent / SHIPPED[model or "default"]
    return Path(model)


#: Smallest frame side (px, after the model's downsampling) the network's stem can take.
MIN_SIDE_PX = 2


class MotionModel:
    """One loaded motion model (an onnxruntime session and its metadata).

    Args:
        path: ONNX file written by :func:`tacswitch.motion.export.export_onnx`; default: the
            shipped model.
        threads: intra-op threads (default ``os.cpu_count()``).
        device: ``"auto"`` (default: a CUDA GPU when onnxruntime offers one, else the CPU),
            ``"cpu"`` or ``"cuda"`` (:func:`tacswitch._ort.providers`).

    Attributes:
        arch: architecture name; ``use_ref``: whether the model needs the reference frame;
        design: ``"consistent"`` (identical frames give exactly zero motion, the reference is
        optional: without it, the single-frame motion from rest) or ``"plain"``;
        work_width, work_height: the frame size it was trained at (px);
        default_centres: ``N x 2`` float32 (x, y) grid at the working size.
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *,
                 threads: int | None = None, device: str = "auto") -> None:
        self.path = model_path(path)
        self.session, meta = open_session(self.path, threads, kind="motion", device=device)
        self.device = device
        self.metadata = dict(meta)
        self.arch = meta.get("tacswitch.arch", "?")
        self.use_ref = json.loads(meta.get("tacswitch.use_ref", "false"))
        self.design = meta.get("tacswitch.design", "plain")
        self.work_width = int(json.loads(meta.get("tacswitch.work_width", "320")))
        self.work_height = int(json.loads(meta.get("tacswitch.work_height", "240")))
        #: Scale of the single-frame output (``ref`` omitted): the simulator's presses move
        #: the gel more than real gels do for the same imprint, so a model trained on it records
        #: the least-squares scale measured on real presses (absent: 1).
        self.single_frame_gain = float(json.loads(meta.get("tacswitch.single_frame_gain", "1")))
        grid = json.loads(meta.get("tacswitch.default_centres", "[]"))
        self.default_centres = np.asarray(grid, np.float32).reshape(-1, 2)
        self._inputs = {i.name for i in self.session.get_inputs()}

    def scale_for(self, width: int) -> int:
        """Integer downsampling factor applied to a frame ``width`` px wide (1 = none)."""
        if width < 1.5 * self.work_width:
            return 1
        return max(1, round(width / self.work_width))

    def centres_for(self, height: int, width: int) -> NDArray[np.float32]:
        """The default centres (the training preset's grid) scaled to a ``height x width``
        frame: the right grid for the same sensor at any resolution, only a guess for others."""
        from tacswitch._checks import as_count

        height, width = as_count(height, "height", 1), as_count(width, "width", 1)
        sx, sy = width / self.work_width, height / self.work_height
        # Pixel centres at integers: scale about the image's outer edge (x + 0.5).
        c = (self.default_centres + 0.5) * np.array([sx, sy], np.float32) - 0.5
        return c.astype(np.float32)

    def __call__(self, img: Any, ref: Any = None, centres: Any = None, *,
                 gain: float | None = None) -> NDArray[np.float32]:
        """See :func:`predict_motion`; ``gain`` (single frame only) replaces
        :attr:`single_frame_gain`."""
        if gain is not None:
            if ref is not None:
                raise ValueError("gain: scales the model's single-frame output only (ref=None)")
            gain = check_gain(gain)
        frame = _bgr(img, "img")
        h, w = frame.shape[:2]
        if ref is not None:
            ref_arr = _bgr(ref, "ref")
            if ref_arr.shape != frame.shape:
                raise ValueError(f"ref: shape {ref_arr.shape} does not match img {frame.shape}")
            if self.design == "single":
                raise ValueError("ref: this model predicts single-frame motion from rest; call it "
                                 "without ref (or use method='flow' / 'auto' with a reference)")
        elif self.use_ref:
            raise ValueError("ref: this model predicts the motion since a reference frame; pass "
                             "the markerless frame at the start of the grasp (or the "
                             "no-contact frame)")
        else:
            ref_arr = None
        pts = self.centres_for(h, w) if centres is None else as_points(centres, "centres")
        if pts.shape[0] == 0:
            return np.zeros((0, 2), np.float32)
        k = self.scale_for(w)
        check_downsampled_size(frame.shape, k, MIN_SIDE_PX, "img")
        if k > 1:
            frame = _downsample(frame, k)
            ref_arr = None if ref_arr is None else _downsample(ref_arr, k)
            # Pixel centres at integers: x_small = (x + 0.5) / k - 0.5.
            pts = ((pts + 0.5) / k - 0.5).astype(np.float32)
        feed: dict[str, Any] = {"image": frame[None], "centres": np.ascontiguousarray(pts)}
        if "reference" in self._inputs:
            feed["reference"] = (ref_arr if ref_arr is not None else frame)[None]
        if "has_reference" in self._inputs:
            # The consistent design's switch: 0 = single-frame motion from rest.
            feed["has_reference"] = np.array([0.0 if ref_arr is None else 1.0], np.float32)
        out = self.session.run(None, feed)[0]
        scale = float(k)
        if ref_arr is None and self.design in ("consistent", "single"):
            scale *= self.single_frame_gain if gain is None else gain
        if scale != 1.0:
            out = out * np.float32(scale)
        return np.nan_to_num(out.astype(np.float32, copy=False), nan=0.0, posinf=0.0,
                             neginf=0.0)


def _bgr(img: Any, name: str) -> NDArray[np.uint8]:
    arr = as_image_u8(img, name)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"{name}: expected a BGR H x W x 3 uint8 image (the model was trained on "
                         f"colour frames); got shape {arr.shape}")
    return arr


def _downsample(img: NDArray[np.uint8], k: int) -> NDArray[np.uint8]:
    import cv2

    h, w = img.shape[:2]
    out = np.asarray(cv2.resize(img, (w // k, h // k), interpolation=cv2.INTER_AREA), np.uint8)
    return out


def load_model(path: str | os.PathLike[str] | None = None, device: str = "auto") -> MotionModel:
    """The cached :class:`MotionModel` of ``path`` on ``device`` (one onnxruntime session per
    model file and device; ``device`` as :class:`MotionModel` takes it)."""
    return cached(MotionModel, model_path(path), device)
