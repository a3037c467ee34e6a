"""The classical fill TacDiff refines: what the network adds its residual to (numpy; no torch).

Two kinds, recorded in the model (``UNetConfig.prior``, ONNX metadata ``tacswitch.prior``):

- ``"telea"`` (models before 0.2): the holes filled by our TELEA, r = 3.
- ``"telea+biharmonic"`` (the default): the mean of TELEA (r = 3) and the biharmonic fill
  (:func:`tacswitch.inpaint_biharmonic`), plus their difference as a second input. TELEA's
  weighted mean is robust to camera noise on flat gel but flattens contact shading; the
  biharmonic surface continues gradients and curvature but carries the noise of the ring it
  starts from. On held-out simulated contacts their mean already cuts TELEA's masked error in
  contact by 7-13 %; the difference tells the network where the two disagree, i.e. where the
  hole hides structure. Both cost a few ms per frame on a CPU.

Images here are float32 in [-1, 1] (``x / 127.5 - 1``), ``H x W x 3`` BGR.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

PriorKind = Literal["telea", "telea+biharmonic"]
PRIORS: tuple[str, ...] = ("telea", "telea+biharmonic")
#: Prior of newly trained models.
DEFAULT_PRIOR: PriorKind = "telea+biharmonic"
#: TELEA radius of the prior (training and inference alike).
PRIOR_RADIUS = 3


def check_prior(kind: str) -> PriorKind:
    """``kind`` if it names a prior, else ``ValueError``."""
    if kind not in PRIORS:
        raise ValueError(f"prior: expected one of {PRIORS}; got {kind!r}")
    return kind  # type: ignore[return-value]


def has_spread(kind: str) -> bool:
    """Whether models with this prior take the ``spread`` input (TELEA minus biharmonic)."""
    return check_prior(kind) == "telea+biharmonic"


def input_channels(kind: str) -> int:
    """Channels of the network input with this prior: cond 3, mask 1, x_t (or noise) 3,
    prior 3 and, for two-fill priors, spread 3."""
    return 13 if has_spread(kind) else 10


def fills(img: NDArray[np.uint8], mask: NDArray[np.bool_], kind: str
          ) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None]:
    """The classical fills of one uint8 BGR frame: TELEA, and the biharmonic fill when ``kind``
    uses it (else None)."""
    from tacswitch.inpaint import inpaint_biharmonic, inpaint_telea

    telea = inpaint_telea(img, mask, PRIOR_RADIUS)
    smooth = inpaint_biharmonic(img, mask) if has_spread(kind) else None
    return telea, smooth


def to_net(a: NDArray[np.uint8] | NDArray[np.float32]) -> NDArray[np.float32]:
    """uint8 (or float) grey levels -> float32 in [-1, 1]."""
    return (np.asarray(a, np.float32) / np.float32(127.5) - np.float32(1.0)).astype(np.float32)


def from_net(a: NDArray[np.float32]) -> NDArray[np.uint8]:
    """float32 in [-1, 1] -> uint8 grey levels (rounded, saturated); the inverse of
    :func:`to_net`."""
    out: NDArray[np.uint8] = np.clip(np.rint((a + 1.0) * np.float32(127.5)), 0, 255
                                     ).astype(np.uint8)
    return out


def combine(telea: NDArray[np.float32], smooth: NDArray[np.float32] | None
            ) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    """``(prior, spread)`` from the fills in [-1, 1]: the mean and the difference (TELEA minus
    biharmonic), or TELEA and None for the TELEA-only prior. Works on any array shape."""
    if smooth is None:
        return telea, None
    prior = (np.float32(0.5) * (telea + smooth)).astype(np.float32)
    return prior, (telea - smooth).astype(np.float32)


def prior_planes(img: NDArray[np.uint8], mask: NDArray[np.bool_], kind: str
                 ) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    """``(prior, spread)`` of one uint8 BGR frame in [-1, 1], ``H x W x 3``: its classical
    fills (:func:`fills`) combined (:func:`combine`); spread is None for the TELEA-only prior."""
    telea, smooth = fills(img, mask, kind)
    return combine(to_net(telea), None if smooth is None else to_net(smooth))
