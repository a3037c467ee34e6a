"""``predict_motion``: the markerless -> marker front door, which chooses between the learned
regressor (:mod:`tacswitch.motion.regressor`, onnxruntime), the ensemble
(:mod:`~tacswitch.motion.ensemble`), dense optical flow (:mod:`~tacswitch.motion.flow`) and the
training-free rules (:mod:`~tacswitch.motion.mechanics`, :mod:`~tacswitch.motion.heuristic`).

It sits above all of them; none imports it (``DESIGN.md``: imports run one way). The methods
are imported when chosen: ``import tacswitch`` loads this module, and the methods would pull in
the simulator's presets and double its import time. The regressor's names
(:class:`MotionModel`, :func:`load_model`, :func:`model_path`, ...) are re-exported here.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import (
    as_points,
    check_downsampled_size,
    check_gain,
    check_model_arg,
    check_points_in_frame,
)
from tacswitch._ort import providers, session_options
from tacswitch.motion.regressor import (
    DEFAULT_MODEL,
    SHIPPED,
    MotionModel,
    _bgr,
    default_model_path,
    load_model,
    model_path,
)

__all__ = ["DEFAULT_MODEL", "METHODS", "SHIPPED", "MotionModel", "default_model_path",
           "load_model", "model_path", "predict_motion", "session_options"]

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
            ``"refined"`` (default: within the speed budgets; lower error than ``"balanced"``
            on real frames), ``"balanced"`` (the earlier default, what the markerless slip
            scorer reads), ``"ultrafast"``, ``"fast"`` or ``"medium"`` (OpenCV's; ``"medium"``
            is ~2x slower, a little more accurate with a reference of the same capture), or
            ``"accurate"`` (DeepFlow on the same work-width frames, ~30x slower, for
            recordings; :mod:`tacswitch.motion.flow`).
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
            gel barely moves, so its gains predict ~zero), a number in [0, 1000] (mechanics: the
            dimensionless gain, e.g. ``tacswitch.motion.calibration.calibrate_press_gain(
            no_contact, presses).gain`` measured on your own sensor; outward: the largest
            motion as a fraction of the marker pitch), or ``None``: the rule's default
            (mechanics: :data:`tacswitch.motion.mechanics.MECHANICS_GAIN`, the least-squares
            gain pooled over real GelSight and GelSight Mini presses, the best single gain on
            real data across both; outward: ``OUTWARD_GAIN``, 0.03 of the pitch, fitted on
            simulated presses). The direction does not depend on it. The ensemble scales its
            learned part by the same gain (relative to the GelSight's, where both were
            fitted). ``method="model"``: a
            number in [0, 1000] that replaces the model's recorded single-frame scale
            (``MotionModel.single_frame_gain``, measured on real GelSight presses; 0.48 for the
            shipped model); single frame only.
        device: where the learned model runs (``method="model"`` and the ensemble's learned
            part): ``"auto"`` (default: a CUDA GPU when onnxruntime offers one, else the CPU),
            ``"cpu"`` or ``"cuda"`` (``ValueError`` naming ``device`` when onnxruntime has no
            CUDA here; :func:`tacswitch._ort.providers`).

    Returns:
        ``N x 2`` float32 ``(dx, dy)`` px in ``img``'s pixels, one row per centre, never NaN
        (a centre just outside the frame, a marker cut by its border, gets the motion at the
        nearest border).

    Raises:
        ValueError: naming the argument: ``centres`` farther outside the frame than an eighth
            of its side (:func:`tacswitch._checks.check_points_in_frame`: pixels of another
            resolution), frames of different shapes, an unknown method or option.
    """
    check_model_arg(model)
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
        from tacswitch.motion.flow import DEFAULT_PRESET, check_flow_options

        # Checked here because "auto" may run the mechanics rule, which ignores them (flow
        # checks its own).
        check_flow_options(algorithm or "dis", preset or DEFAULT_PRESET,
                           False if suppress_imprint is None else suppress_imprint)
    if method == "model":
        if isinstance(gain, str):
            raise ValueError("gain: applies to method='model' as a number in [0, 1000] (its "
                             f"single-frame scale), not a sensor name; got {gain!r}")
        if centres is not None:
            shape = np.shape(img)
            if len(shape) >= 2:
                check_points_in_frame(as_points(centres, "centres"), shape[0], shape[1],
                                      "centres")
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
    check_points_in_frame(pts, frame.shape[0], frame.shape[1], "centres")
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
                             "pass a number in [0, 1000]")
        return table[gain]
    return check_gain(gain)
