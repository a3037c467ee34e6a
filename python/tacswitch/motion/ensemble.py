"""Single-frame ensemble: the mechanics rule and the learned single-frame model, averaged.

Two single-frame estimators of the gel's motion under a contact, with different errors:

- the mechanics rule (:mod:`tacswitch.motion.mechanics`): the elastic law of a press applied
  to the imprint's *shape*, blind to anything but a symmetric press;
- the learned single-frame model (``motion_single.onnx``, :class:`~.regressor.MotionModel`):
  trained on the simulator (first press-law calibration) with the real sensors' optics; reads
  shading asymmetry too (an off-axis press, a partial shear) but carries the simulator's
  appearance gap.

Their mean, with equal weights (not tuned), matches or beats the better of the two in error and
cosine on the real GelSight and FOTS press measurements at hand
(``benches/bench_motion_model_real.py``; e_rmse px / cosine / share within 30°, single frame):

- real GelSight presses, the gel's grain-matched motion, held-out (odd) presses: ensemble
  1.53 / 0.66 / 60 % against the rule 1.62 / 0.64 / 51 % and the model 1.56 / 0.62 / 61 %;
- real FOTS GelSight Mini press (hand-tracked markers): 1.56 / 0.93 / 89 % against
  1.55 / 0.87 / 59 % and 1.64 / 0.93 / 85 %.

On the sheared FOTS frame (no single-frame cue to a shear) it lies between the two (3.69 / 0.17
against 3.78 / 0.03 and 3.64 / 0.23). It is behind the rule where the truth is the rule's own
physics (real frames with the
simulator's press field: 1.10 / 0.89 against 0.88 / 0.96), which is why the choice was made on
the real measurements. On a gel that does not move under a press (taxim's real GelSight Mini)
it predicts a little more false motion than the rule: 0.33 vs 0.24 px at the default gain, 0.05
vs 0.04 with the Mini's gain.

Scale: both parts follow the sensor's press gain. The rule's GelSight gain
(:data:`tacswitch.sim.presets.MECHANICS_GAINS` ``["gelsight"]``) and the model's recorded
scale (:attr:`~.regressor.MotionModel.single_frame_gain`) were fitted on the same real GelSight
presses, so a gain ``g`` scales the model by ``g / MECHANICS_GAINS["gelsight"]`` as well.

Speed: the model runs on onnxruntime's threads while the rule runs on this one (onnxruntime
releases the GIL), so the pair costs little more than the slower of the two (4.5 / 6.7 ms at
320x240 / 640x480 against the rule's 3.0 / 5.4 and the model's 4.7 / 3.1, near idle).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import check_gain
from tacswitch.motion.mechanics import MECHANICS_GAIN, mechanics_motion
from tacswitch.motion.regressor import MotionModel, load_model
from tacswitch.sim.presets import MECHANICS_GAINS

__all__ = ["ENSEMBLE_MODEL", "ensemble_motion", "learned_model", "learned_part"]

#: The shipped model whose single-frame output the ensemble uses by default.
ENSEMBLE_MODEL = "single"

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _reset_after_fork() -> None:
    # A forked child inherits the pool without its thread (work would wait forever) and maybe
    # a lock another thread held: it starts with neither.
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()


if hasattr(os, "register_at_fork"):  # POSIX: the only platforms that fork
    os.register_at_fork(after_in_child=_reset_after_fork)


def _pool() -> ThreadPoolExecutor:
    """The one-thread pool the learned half runs on (one per process, see
    :func:`_reset_after_fork`). Callers on several threads share it: their learned halves run
    one at a time (3-5 ms each), their rules in parallel."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="tacswitch-ensemble")
        return _POOL


def learned_model(model: str | os.PathLike[str] | None, device: str = "auto") -> MotionModel:
    """The cached motion model of ``model`` (None: :data:`ENSEMBLE_MODEL`) on ``device``,
    checked to predict from one frame; ``ValueError`` naming ``model`` for one that needs a
    reference."""
    net = load_model(ENSEMBLE_MODEL if model is None else model, device)
    if net.use_ref:
        raise ValueError(f"model: {net.path.name} predicts motion since a reference frame; the "
                         "ensemble needs a single-frame model (e.g. the shipped 'single')")
    return net


def _learned(net: MotionModel, img: NDArray[np.uint8], centres: NDArray[np.float32],
             gain: float) -> NDArray[np.float32]:
    # The model's single-frame output is linear in its gain: its own gain scaled here, so the
    # product (beyond the range a user's gain is checked against) is never checked as a gain.
    out = net(img, centres=centres) * np.float32(gain / MECHANICS_GAINS["gelsight"])
    return np.asarray(out, np.float32)


def learned_part(img: NDArray[np.uint8], centres: NDArray[np.float32], gain: float,
                 model: str | os.PathLike[str] | None = None) -> NDArray[np.float32]:
    """The learned model's single-frame motion ``N x 2`` float32 px at ``centres``, scaled for
    the rule's press ``gain`` (module doc). ``model``: any single-frame capable motion model
    (default :data:`ENSEMBLE_MODEL`); one that needs a reference is refused, naming ``model``;
    ``gain`` must be a number >= 0 (``ValueError`` naming it)."""
    return _learned(learned_model(model), img, centres, check_gain(gain))


def ensemble_motion(img: NDArray[np.uint8], ref: NDArray[np.uint8] | None,
                    centres: NDArray[np.float32], *, gain: float | None = None,
                    model: str | os.PathLike[str] | None = None,
                    device: str = "auto") -> NDArray[np.float32]:
    """Motion ``N x 2`` float32 ``(dx, dy)`` px of markers at rest ``centres`` (``(x, y)`` px)
    in the markerless BGR frame ``img``: the mean of the mechanics rule (against ``ref``, the
    no-contact frame, when given; else single-frame) and the learned model on ``img`` alone.

    ``gain``: the sensor's press gain (number >= 0; None: the rule's default,
    :data:`tacswitch.motion.mechanics.MECHANICS_GAIN`), scaling both parts (module doc).
    ``model``: the learned part (default :data:`ENSEMBLE_MODEL`). Identical ``img`` and ``ref``
    give exactly zero. Frames are validated by the caller (:func:`tacswitch.predict_motion`).
    ``device``: where the learned part runs (:func:`tacswitch._ort.providers`).
    """
    g = MECHANICS_GAIN if gain is None else check_gain(gain)
    net = learned_model(model, device)
    if len(centres) == 0 or (ref is not None and np.array_equal(img, ref)):
        return np.zeros((len(centres), 2), np.float32)
    learned: Future[NDArray[np.float32]] = _pool().submit(_learned, net, img, centres, g)
    rule = mechanics_motion(img, ref, centres, gain=g)
    part = learned.result()
    return ((rule + part) * np.float32(0.5)).astype(np.float32)
