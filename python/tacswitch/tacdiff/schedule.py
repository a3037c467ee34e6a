"""Noise schedule and samplers of TacDiff (numpy only; the network is elsewhere).

Continuous time ``t`` in [0, 1]; the noisy image is ``x_t = alpha(t) x0 + sigma(t) eps`` with the
cosine schedule ``alpha = cos(pi t / 2)``, ``sigma = sin(pi t / 2)`` (variance preserving). It
has zero terminal SNR: at ``t = 1`` the sample is pure noise, as at inference, so the first step
sees what training saw (no train/test gap at the start, which is what makes 1-4 steps work).

The network predicts ``v = alpha eps - sigma x0`` (v-prediction): well defined at both ends,
unlike eps-prediction at ``t = 1`` (where x0 = (x_t - sigma eps) / alpha divides by zero) or
x0-prediction at ``t = 0``. Its noise-level input is ``sigma(t)`` in [0, 1] (any step schedule
works at inference).

Samplers (``step`` functions) map x0/eps estimates to the next sample:

- DDIM (deterministic, first order): ``x_s = alpha_s x0 + sigma_s eps``.
- DPM-Solver++(2M): second-order multistep in ``lambda = log(alpha / sigma)``, using the previous
  step's x0. The first step (from ``lambda = -inf``) and the last (to ``sigma = 0``) are first
  order by construction: the last returns x0 exactly.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

Sampler = Literal["ddim", "dpmpp2m"]
SAMPLERS: tuple[str, ...] = ("ddim", "dpmpp2m")
#: Most steps a sampler accepts (the paper's ancestral baseline used 1000).
MAX_STEPS = 1000


def alpha_sigma(t: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(alpha(t), sigma(t))`` of the cosine schedule; exact 0/1 at the ends."""
    tt = np.clip(np.asarray(t, np.float64), 0.0, 1.0)
    a, s = np.cos(0.5 * np.pi * tt), np.sin(0.5 * np.pi * tt)
    # cos(pi/2) is 6e-17 in floating point: make the terminal SNR exactly zero.
    a = np.where(tt >= 1.0, 0.0, a)
    return a, s


def timesteps(steps: int) -> NDArray[np.float64]:
    """``steps + 1`` times from 1 (pure noise) to 0 (clean), uniform in ``t``."""
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)):
        raise TypeError(f"steps: expected an integer, got {type(steps).__name__}")
    if not 1 <= steps <= MAX_STEPS:
        raise ValueError(f"steps: must be between 1 and {MAX_STEPS}; got {steps}")
    return np.linspace(1.0, 0.0, int(steps) + 1)


def v_to_x0_eps(x_t: NDArray[np.float32], v: NDArray[np.float32], t: float
                ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """x0 and eps estimates from a v prediction at time ``t`` (exact inversion: alpha² +
    sigma² = 1)."""
    a, s = (float(u) for u in alpha_sigma(t))
    x0 = a * x_t - s * v
    eps = s * x_t + a * v
    return x0.astype(np.float32, copy=False), eps.astype(np.float32, copy=False)


def _lambda(t: float) -> float:
    a, s = (float(u) for u in alpha_sigma(t))
    if a == 0.0:
        return -np.inf
    if s == 0.0:
        return np.inf
    return float(np.log(a / s))


class Solver:
    """One sampling run: call :meth:`step` for each consecutive pair of :func:`timesteps`.

    Args:
        kind: ``"ddim"`` or ``"dpmpp2m"``.
    """

    def __init__(self, kind: Sampler = "dpmpp2m") -> None:
        if kind not in SAMPLERS:
            raise ValueError(f"sampler: must be one of {SAMPLERS}; got {kind!r}")
        self.kind = kind
        self._prev: tuple[NDArray[np.float32], float] | None = None  # (x0, lambda) of last step

    def step(self, x_t: NDArray[np.float32], x0: NDArray[np.float32], eps: NDArray[np.float32],
             t: float, t_next: float) -> NDArray[np.float32]:
        """The sample at ``t_next < t`` from the estimates at ``t``."""
        a_n, s_n = (float(u) for u in alpha_sigma(t_next))
        lam, lam_n = _lambda(t), _lambda(t_next)
        prev, self._prev = self._prev, (x0, lam)
        if s_n == 0.0:
            return x0.copy()
        if self.kind == "ddim" or prev is None or not np.isfinite(lam) or \
                not np.isfinite(prev[1]):
            return (a_n * x0 + s_n * eps).astype(np.float32, copy=False)
        # DPM-Solver++(2M) (Lu et al. 2022, multistep data prediction, second order).
        _a, s = (float(u) for u in alpha_sigma(t))
        h = lam_n - lam
        r = (lam - prev[1]) / h
        d = (1.0 + 1.0 / (2.0 * r)) * x0 - (1.0 / (2.0 * r)) * prev[0]
        out = (s_n / s) * x_t - a_n * np.expm1(-h) * d
        return out.astype(np.float32, copy=False)
