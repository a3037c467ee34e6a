"""Marker motion from a markerless frame with onnxruntime (numpy only; never imports torch).

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

from tacswitch._checks import as_image_u8, as_points, check_downsampled_size, check_model_arg
from tacswitch._ort import cached, open_session, session_options

__all__ = ["METHODS", "SHIPPED", "MotionModel", "default_model_path", "load_model", "model_path",
           "predict_motion", "session_options"]

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
            from tacswitch.motion.mechanics import check_gain

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


#: Smallest frame side (px) the training-free methods accept: DIS works on 8 x 8 patches and
#: both methods smooth over a marker's size.
MIN_IMAGE_SIDE_PX = 8

#: Methods of :func:`predict_motion`.
METHODS = ("auto", "ensemble", "model", "flow", "outward", "mechanics")


def predict_motion(img: Any, ref: Any = None, centres: Any = None, *, method: str = "auto",
                   model: str | os.PathLike[str] | None = None, algorithm: str | None = None,
                   preset: str | None = None, suppress_imprint: bool | None = None,
                   gain: float | str | None = None, device: str = "auto"
                   ) -> NDArray[np.float32]:
    """The 2D motion each marker would have had, from a markerless frame.

    Args:
        img: markerless frame, ``H x W x 3`` uint8 **BGR** (OpenCV order).
        ref: a markerless reference frame of the same sensor (same shape): the motion returned
            is the markers' motion from ``ref`` to ``img``. ``method="flow"`` needs it; the
            shipped model uses it when its metadata says so (``MotionModel.use_ref``: an earlier
            frame of the same contact, e.g. the grasp start, or the no-contact frame).
        centres: ``N x 2`` float32 marker rest centres ``(x, y)`` px in ``img``'s pixels (pixel
            centres at integers; with ``ref``, positions in ``ref``). Default: the model's
            training grid (the GelSight Mini preset's 9 x 11 grid, pitch 28.5 px at 320 x 240)
            scaled to the frame, for every method; pass your sensor's own centres (e.g.
            ``tacswitch.extract_markers(ref_with_markers).centres``) otherwise.
        method: ``"auto"`` (default): without ``ref``, ``"ensemble"``; with ``ref`` (the
            no-contact frame or a frame of the same contact), ``"flow"`` — the choices that
            scored best on real frames with real marker motion
            (``benches/bench_motion_video_real.py``; until this release a no-contact ``ref``
            ran the ensemble, which kept ~1/6 of a real Mini press's motion);
            ``"ensemble"`` (the mean of the mechanics rule and the learned single-frame model,
            :mod:`tacswitch.motion.ensemble`; with or without ``ref``, which only the rule
            uses), ``"model"`` (the ONNX model), ``"flow"`` (training-free dense optical flow
            ``ref -> img`` read at the centres, :mod:`tacswitch.motion.flow`; exactly zero for
            identical frames, insensitive to a global brightness change), ``"outward"`` (the
            no-learning baseline: outward from the contact by the local image change,
            :mod:`tacswitch.motion.heuristic`; works with or without ``ref``) or
            ``"mechanics"`` (no learning: the simulator's elastic law for a press applied to
            the imprint the frame shows, :mod:`tacswitch.motion.mechanics`; outward motion
            that fades over a gel thickness outside the contact; with or without ``ref``).
        model: ONNX model path or shipped name (default: the shipped model); sessions are
            cached per path. ``method="ensemble"``: its learned part (default ``"single"``; a
            single-frame capable model). Other methods, ``"auto"`` included, use it only for
            the default centres.
        algorithm: ``method="flow"`` (or ``"auto"`` when it runs flow): ``"dis"`` (default),
            ``"farneback"``, ``"deepflow"``, ``"pcaflow"`` or ``"rlof"`` (the last three from
            opencv-contrib, 10-100x slower).
        preset: ``method="flow"`` (or ``"auto"`` when it runs flow) with DIS only:
            ``"balanced"`` (default: within the speed budgets), ``"ultrafast"``, ``"fast"`` or
            ``"medium"`` (OpenCV's; ``"medium"`` is ~2x slower, a little more accurate with a
            reference of the same capture).
        suppress_imprint: ``method="flow"`` (or ``"auto"`` when it runs flow): ``True`` when
            ``ref`` is the no-contact frame: the flow is trusted less where an imprint
            appeared (its shading is not motion) and filled from the gel around it
            (:func:`tacswitch.motion.flow.flow_motion`); default ``False`` (a reference of the
            same contact).
        gain: ``method="mechanics"``, ``"ensemble"``, ``"outward"`` or ``"auto"`` (used when
            it runs the ensemble, i.e. without ``ref``; ignored when it runs flow): how far a
            press moves this sensor's gel, which one image does not show. A sensor name,
            ``"gelsight"`` or ``"gelsight_mini"`` (gains fitted on that sensor's real presses:
            :data:`tacswitch.sim.presets.MECHANICS_GAINS` / ``OUTWARD_GAINS``; the real Mini's
            gel barely moves, so its gains predict ~zero), a number >= 0 (mechanics: the
            dimensionless gain, e.g. ``tacswitch.motion.calibration.calibrate_press_gain(
            no_contact, presses).gain`` measured on your own sensor; outward: the largest
            motion as a fraction of the marker pitch), or ``None``: the rule's default
            (mechanics: :data:`tacswitch.motion.mechanics.MECHANICS_GAIN`, the least-squares
            gain pooled over real GelSight and GelSight Mini presses, the best single gain on
            real data across both; outward: ``OUTWARD_GAIN``, 0.03 of the pitch, fitted on
            simulated presses). The direction does not depend on it. The ensemble scales its
            learned part by the same gain (relative to the GelSight's, where both were
            fitted). ``method="model"``: a
            number >= 0 that replaces the model's recorded single-frame scale
            (``MotionModel.single_frame_gain``, measured on real GelSight presses; 0.48 for the
            shipped model); single frame only.
        device: where the learned model runs (``method="model"`` and the ensemble's learned
            part): ``"auto"`` (default: a CUDA GPU when onnxruntime offers one, else the CPU),
            ``"cpu"`` or ``"cuda"`` (``ValueError`` naming ``device`` when onnxruntime has no
            CUDA here; :func:`tacswitch._ort.providers`).

    Returns:
        ``N x 2`` float32 ``(dx, dy)`` px in ``img``'s pixels, one row per centre, never NaN
        (a centre outside the frame gets the motion at the nearest border).
    """
    check_model_arg(model)
    from tacswitch._ort import providers

    providers(device)  # checked whichever method runs
    if method not in METHODS:
        raise ValueError(f"method: unknown {method!r}; choose from {list(METHODS)}")
    auto = method == "auto"
    if auto and ref is None:
        # Without a reference: the mean of the mechanics rule and the learned single-frame
        # model, as good as the better of the two or better on the real GelSight / FOTS presses
        # (held-out real GelSight presses 1.53 px / cosine 0.66 vs the rule's 1.62 / 0.64,
        # zero 2.22; FOTS press cosine 0.93 vs 0.87); see motion/ensemble.py.
        method = "ensemble"
    if method not in ("flow", "auto"):
        for name, value in (("algorithm", algorithm), ("preset", preset),
                            ("suppress_imprint", suppress_imprint)):
            if value is not None:
                raise ValueError(f"{name}: applies to method='flow' only; got method={method!r}")
    rule_gain = (None if gain is None or method == "model"
                 else _rule_gain("ensemble" if auto else method, gain))
    if auto:
        from tacswitch.motion.flow import check_flow_options

        # Checked here because "auto" may run the mechanics rule, which ignores them (flow
        # checks its own).
        check_flow_options(algorithm or "dis", preset or "balanced",
                           False if suppress_imprint is None else suppress_imprint)
    if method == "model":
        if isinstance(gain, str):
            raise ValueError("gain: applies to method='model' as a number >= 0 (its single-frame "
                             f"scale), not a sensor name; got {gain!r}")
        return load_model(model, device)(img, ref=ref, centres=centres, gain=gain)
    frame = _bgr(img, "img")
    check_downsampled_size(frame.shape, 1, MIN_IMAGE_SIDE_PX, "img")
    ref_arr = None
    if ref is not None:
        ref_arr = _bgr(ref, "ref")
        if ref_arr.shape != frame.shape:
            raise ValueError(f"ref: shape {ref_arr.shape} does not match img {frame.shape}")
    elif method == "flow":
        raise ValueError("ref: method='flow' measures the motion between two frames; pass the "
                         "markerless no-contact frame (or the frame at the grasp start)")
    pts = (load_model(model).centres_for(*frame.shape[:2]) if centres is None
           else as_points(centres, "centres"))
    if method == "auto":
        # With a reference, flow, whatever the reference shows: on real GelSight Mini videos
        # with tracked markers (benches/bench_motion_video_real.py) flow from the no-contact
        # frame keeps the press's magnitude (ratio ~0.9-1.0) where the ensemble, the earlier
        # choice against a no-contact reference, predicted ~1/6 of it; on taxim's real
        # GelSight presses (grain-matched truth) flow was already the better of the two.
        method = resolve_method(method, frame, ref_arr)
    if method == "flow":
        from tacswitch.motion.flow import DEFAULT_PRESET, flow_motion

        assert ref_arr is not None
        return flow_motion(frame, ref_arr, pts, algorithm=algorithm or "dis",
                           preset=preset or DEFAULT_PRESET,
                           suppress_imprint=False if suppress_imprint is None else suppress_imprint)
    if method == "ensemble":
        from tacswitch.motion.ensemble import ensemble_motion

        # "auto" keeps the shipped learned part: its `model` names the default centres only.
        return ensemble_motion(frame, ref_arr, pts, gain=rule_gain,
                               model=None if auto else model, device=device)
    if method == "mechanics":
        from tacswitch.motion.mechanics import mechanics_motion

        if rule_gain is None:
            return mechanics_motion(frame, ref_arr, pts)
        return mechanics_motion(frame, ref_arr, pts, gain=rule_gain)
    from tacswitch.motion.heuristic import outward_motion

    if rule_gain is None:
        return outward_motion(frame, ref_arr, pts)
    return outward_motion(frame, ref_arr, pts, gain=rule_gain)


def resolve_method(method: str, img: Any = None, ref: Any = None) -> str:
    """The method :func:`predict_motion` runs for ``method`` on ``img`` (validated BGR uint8)
    and ``ref`` (None: single frame): ``"auto"`` stands for ``"ensemble"`` without a
    reference and ``"flow"`` with one; any other name is returned as is."""
    del img  # the choice depends on whether there is a reference only
    if method != "auto":
        return method
    return "ensemble" if ref is None else "flow"


def _rule_gain(method: str, gain: Any) -> float:
    """``gain`` of :func:`predict_motion` as a number for ``method`` (validated)."""
    from tacswitch.sim.presets import MECHANICS_GAINS, OUTWARD_GAINS

    if method not in ("mechanics", "ensemble", "outward"):
        raise ValueError(f"gain: applies to method='mechanics', 'ensemble' or 'outward' only; "
                         f"got method={method!r}")
    if isinstance(gain, str):
        table = OUTWARD_GAINS if method == "outward" else MECHANICS_GAINS
        if gain not in table:
            raise ValueError(f"gain: unknown sensor {gain!r}; choose from {sorted(table)} or "
                             "pass a number >= 0")
        return table[gain]
    from tacswitch.motion.mechanics import check_gain

    return check_gain(gain)
