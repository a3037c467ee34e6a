"""The classical fill TacDiff refines: what the network adds its residual to (numpy; no torch).

Three kinds, recorded in the model (``UNetConfig.prior``, ONNX metadata ``tacswitch.prior``):

- ``"telea"`` (models before 0.2): the holes filled by our TELEA, r = 3.
- ``"telea+biharmonic"`` (models of 0.2): the mean of TELEA (r = 3) and the biharmonic fill
  (:func:`tacswitch.inpaint_biharmonic`), plus their difference as a second input. TELEA's
  weighted mean is robust to camera noise on flat gel but flattens contact shading; the
  biharmonic surface continues gradients and curvature but carries the noise of the ring it
  starts from. On held-out simulated contacts their mean cut TELEA's masked error in contact
  by 7-13 %; the difference tells the network where the two disagree. On real frames it is
  poisoned: the biharmonic surface extrapolates the darkened ring real markers leave around
  them (soft paint edges, halo, codec ringing), a grey ghost dot in every hole.
- ``"telea+biharmonic-grown"`` (the default of new models): the same mean and difference, but
  the biharmonic fill is solved on each hole grown by :data:`PRIOR_GROW` px (within its own
  Voronoi cell, so neighbouring holes never merge) and kept on the hole only: its boundary
  values and slopes come from gel further out, past the ring. Chosen on the real-frame proxy
  (:mod:`tacswitch.realproxy`; masks as ``remove_markers`` builds them, adaptive): masked MAE
  over MJPEG/H.264 frames 2.03 (GelSight) / 2.19 (Mini) against 3.26 / 2.94 for the plain mean
  and 2.27 / 2.68 for TELEA, better than both on every proxy case, crisp markers included;
  ghost -0.21 / -0.14 grey levels. Growth 6 px is slightly better on compressed frames and
  worse on crisp ones; the price is detail near the hole's edge on clean simulated contacts
  (masked MAE in contact 4.93 vs 4.24 for the plain mean), which the network sees in its
  condition and can restore.

Images here are float32 in [-1, 1] (``x / 127.5 - 1``), ``H x W x 3`` BGR.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from tacswitch.inpaint import inpaint_biharmonic, inpaint_telea

PriorKind = Literal["telea", "telea+biharmonic", "telea+biharmonic-grown"]
PRIORS: tuple[str, ...] = ("telea", "telea+biharmonic", "telea+biharmonic-grown")
#: Prior of newly trained models (older models record theirs and keep it).
DEFAULT_PRIOR: PriorKind = "telea+biharmonic-grown"
#: TELEA radius (px) of the prior of models that do not record their own (ONNX metadata
#: ``tacswitch.prior_radius``, safetensors config ``prior_radius``): every model before 0.4 was
#: trained with 3.
PRIOR_RADIUS = 3
#: TELEA radius (px) of the prior of newly trained models (``TrainConfig.prior_radius``,
#: ``tacswitch train tacdiff --prior-radius``): ``remove_markers``' own radius. On real frames
#: with painted or compressed markers the wide TELEA averages past the dark ring a marker leaves,
#: and the 0.3 weights run zero-shot on an r = 12 prior already beat r = 3 there
#: (``benches/bench_prior_radius.py``). Fine-tuning keeps the start model's radius.
DEFAULT_PRIOR_RADIUS = 12
#: Radii a prior may use (px; TELEA takes 1-100, a model file may record up to 64).
RADIUS_RANGE = (1.0, 64.0)
#: Growth of each hole (px) before the biharmonic solve of ``"telea+biharmonic-grown"``.
PRIOR_GROW = 4


def check_prior(kind: str) -> PriorKind:
    """``kind`` if it names a prior, else ``ValueError``."""
    if kind not in PRIORS:
        raise ValueError(f"prior: expected one of {PRIORS}; got {kind!r}")
    return kind  # type: ignore[return-value]


def check_radius(radius: object, name: str = "prior_radius") -> float:
    """``radius`` as a float if it is a TELEA radius in :data:`RADIUS_RANGE` px, else
    ``ValueError`` naming ``name``."""
    try:
        r = float(radius)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a TELEA radius in px; got {radius!r}") from None
    if not RADIUS_RANGE[0] <= r <= RADIUS_RANGE[1]:  # also refuses NaN
        raise ValueError(f"{name}: expected a TELEA radius in [{RADIUS_RANGE[0]:g}, "
                         f"{RADIUS_RANGE[1]:g}] px; got {radius!r}")
    return r


def has_spread(kind: str) -> bool:
    """Whether models with this prior take the ``spread`` input (TELEA minus biharmonic)."""
    return check_prior(kind) != "telea"


def grow_holes(mask: NDArray[np.bool_], px: float) -> NDArray[np.bool_]:
    """Each hole (connected component of ``mask``) grown by ``px`` (Euclidean), but only
    within its own Voronoi cell and leaving a two-pixel wall of known pixels where two cells
    meet, so holes never merge (a merged hole would lose the gel between markers as data, and
    the biharmonic system grows with the square of a hole's size)."""
    import cv2

    m = np.asarray(mask, bool)
    if px <= 0 or not m.any():
        return m.copy()
    # Distance to, and label of, the nearest hole for every pixel.
    dist, lab = cv2.distanceTransformWithLabels(np.where(m, 0, 1).astype(np.uint8), cv2.DIST_L2,
                                                5, labelType=cv2.DIST_LABEL_CCOMP)
    wall = np.zeros_like(m)
    dx = lab[:, 1:] != lab[:, :-1]
    dy = lab[1:, :] != lab[:-1, :]
    wall[:, 1:] |= dx
    wall[:, :-1] |= dx
    wall[1:, :] |= dy
    wall[:-1, :] |= dy
    out: NDArray[np.bool_] = ((dist <= px) & ~wall) | m
    return out


def input_channels(kind: str) -> int:
    """Channels of the network input with this prior: cond 3, mask 1, x_t (or noise) 3,
    prior 3 and, for two-fill priors, spread 3."""
    return 13 if has_spread(kind) else 10


def _solves(img: NDArray[np.uint8], m: NDArray[np.bool_], kind: str,
            radius: float = PRIOR_RADIUS) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None]:
    """TELEA of ``img`` on ``m`` and the biharmonic fill ``kind`` uses (None for the TELEA-only
    prior). For ``"telea+biharmonic-grown"`` the biharmonic image is solved on the grown holes:
    only its values on ``m`` are the prior's (the grown ring is the frame in :func:`fills`)."""
    telea = inpaint_telea(img, m, radius)
    if not has_spread(kind):
        return telea, None
    if kind != "telea+biharmonic-grown":
        return telea, inpaint_biharmonic(img, m)
    try:
        return telea, inpaint_biharmonic(img, grow_holes(m, PRIOR_GROW))
    except ValueError:
        # A hole that grown is beyond the biharmonic solver's size limit: the ungrown holes
        # still give a prior (or the same error as the plain biharmonic prior).
        return telea, inpaint_biharmonic(img, m)


def fills(img: NDArray[np.uint8], mask: NDArray[np.bool_], kind: str,
          radius: float = PRIOR_RADIUS) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None]:
    """The classical fills of one uint8 BGR frame: TELEA of ``radius`` px, and the biharmonic
    fill when ``kind`` uses it (else None; for ``"telea+biharmonic-grown"`` solved on the grown
    holes, the pixels outside ``mask`` left as in ``img``)."""
    m = np.asarray(mask, bool)
    telea, solved = _solves(img, m, kind, radius)
    if solved is None or kind != "telea+biharmonic-grown":
        return telea, solved
    smooth = img.copy()
    smooth[m] = solved[m]
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


def prior_on_mask(img: NDArray[np.uint8], mask: NDArray[np.bool_], kind: str,
                  index: NDArray[np.intp] | None = None, radius: float = PRIOR_RADIUS
                  ) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    """``(prior, spread)`` of :func:`prior_planes` on the masked pixels only (``N x 3``, in the
    row-major order of ``img[mask]``; ``index`` is ``np.flatnonzero(mask)`` if the caller has
    it). Off the mask the prior is the frame itself and the spread is 0 exactly (both fills keep
    the known pixels), so a caller can fill those from ``img`` without converting and combining
    three whole frames; the values are bit-identical to :func:`prior_planes`'."""
    m = np.asarray(mask, bool)
    idx = np.flatnonzero(m) if index is None else index

    def on_mask(a: NDArray[np.uint8]) -> NDArray[np.uint8]:
        return a.reshape(-1, a.shape[-1] if a.ndim == 3 else 1)[idx]

    telea, solved = _solves(img, m, kind, radius)
    return combine(to_net(on_mask(telea)), None if solved is None else to_net(on_mask(solved)))


def prior_planes(img: NDArray[np.uint8], mask: NDArray[np.bool_], kind: str,
                 radius: float = PRIOR_RADIUS
                 ) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    """``(prior, spread)`` of one uint8 BGR frame in [-1, 1], ``H x W x 3``: its classical
    fills (:func:`fills`, TELEA of ``radius`` px) combined (:func:`combine`); spread is None for
    the TELEA-only prior."""
    telea, smooth = fills(img, mask, kind, radius)
    return combine(to_net(telea), None if smooth is None else to_net(smooth))
