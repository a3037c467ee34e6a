"""The TacDiff denoiser: a small U-Net conditioned Palette-style (torch; training/export only).

What is diffused is the *residual over a classical fill*: ``r0 = RESIDUAL_SCALE * (x0 - prior)``
on the masked pixels, where ``prior`` is the frame with its holes filled classically
(:mod:`~tacswitch.tacdiff.prior`: the mean of our TELEA and biharmonic fills, a few ms on a CPU;
TELEA alone for models before 0.2). The classical fill is already within a few grey levels on
smooth gel; the network only has to add what it misses (texture and edges in contact), and with
its zero-initialised output layer an untrained network returns the classical fill exactly, so
training can only move the result away from a strong baseline where the data say so.

Input (``B x C x H x W``, H and W multiples of :data:`MULTIPLE`): the condition image with its
masked pixels replaced by noise (3, BGR in [-1, 1]; Palette), the mask (1, {0, 1}), the noisy
residual ``x_t`` on the masked pixels (3, zero elsewhere), the prior (3) and, for the
``"telea+biharmonic"`` prior, the spread (3: TELEA minus biharmonic, where the classical fills
disagree); C = 13, or 10 without the spread. Output: the v-prediction of the residual (3). The
noise level ``sigma`` in [0, 1] (``B``) enters every residual block through a sinusoidal
embedding and an MLP (scale and shift after the block's first normalisation).

Cheap on a CPU by construction: a 2x pixel-unshuffle stem (the first convolutions run at half
resolution on 4x the channels, the output comes back by pixel-shuffle), three resolution levels
below it, one residual block per level and optionally one self-attention block at the
bottleneck (1/16 of the input) for the long-range context of large holes. Widths scale with
``base``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
import torch.nn.functional as F
from torch import nn

from tacswitch.tacdiff.prior import DEFAULT_PRIOR, DEFAULT_PRIOR_RADIUS, input_channels

#: H and W of the input must be multiples of this (stem 2 x three 2x downsamplings).
MULTIPLE = 16
#: Scale of the diffused residual over TELEA (images in [-1, 1]): residuals of a few grey levels
#: become values of order 0.1-1, comparable with the unit noise.
RESIDUAL_SCALE = 8.0


@dataclass(frozen=True)
class UNetConfig:
    """Architecture of :class:`DenoiserUNet` (recorded in checkpoints and ONNX metadata).

    Attributes:
        base: channels at the first level (half resolution); the levels have
            ``base * mult`` channels.
        mults: width multipliers of the levels (the last one is the bottleneck).
        attention: a self-attention block at the bottleneck (off by default: trained on
            small crops, it would attend over far more positions on whole frames).
        emb: width of the noise-level embedding.
        prior: the classical fill the residual is taken over
            (:data:`tacswitch.tacdiff.prior.PRIORS`).
        prior_radius: TELEA radius (px) of that prior, in training and at inference (not
            part of the architecture; exported as ``tacswitch.prior_radius``). Files that do
            not record one were trained at :data:`~tacswitch.tacdiff.prior.PRIOR_RADIUS`.
    """

    base: int = 32
    mults: tuple[int, ...] = (1, 2, 3, 4)
    attention: bool = False
    emb: int = 128
    prior: str = DEFAULT_PRIOR
    prior_radius: float = DEFAULT_PRIOR_RADIUS

    @property
    def in_channels(self) -> int:
        """Input channels: cond 3, mask 1, x_t 3, prior 3 (+ spread 3)."""
        return input_channels(self.prior)

    def to_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["mults"] = list(self.mults)
        return d


def _groups(ch: int) -> int:
    for g in (8, 4, 2, 1):
        if ch % g == 0:
            return g
    return 1


def noise_embedding(sigma: torch.Tensor, dim: int) -> torch.Tensor:
    """Sinusoidal features of ``sigma`` in [0, 1] (``B``) -> ``B x dim``."""
    half = dim // 2
    steps = torch.arange(half, dtype=torch.float32, device=sigma.device)
    freqs = torch.exp(-math.log(1000.0) * steps / half)
    arg = (sigma.float() * 1000.0)[:, None] * freqs[None]
    return torch.cat([torch.sin(arg), torch.cos(arg)], dim=1)


class ResBlock(nn.Module):
    """GroupNorm-SiLU-conv twice, the noise embedding as scale/shift, a 1x1 skip if widths
    differ."""

    def __init__(self, cin: int, cout: int, emb: int) -> None:
        super().__init__()
        self.norm1 = nn.GroupNorm(_groups(cin), cin)
        self.conv1 = nn.Conv2d(cin, cout, 3, padding=1)
        self.emb = nn.Linear(emb, 2 * cout)
        self.norm2 = nn.GroupNorm(_groups(cout), cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, padding=1)
        self.skip = nn.Conv2d(cin, cout, 1) if cin != cout else nn.Identity()
        nn.init.zeros_(self.conv2.weight)
        nn.init.zeros_(self.conv2.bias)  # type: ignore[arg-type]

    def forward(self, x: torch.Tensor, e: torch.Tensor) -> torch.Tensor:
        h = self.conv1(F.silu(self.norm1(x)))
        scale, shift = self.emb(e)[:, :, None, None].chunk(2, dim=1)
        h = self.norm2(h) * (1 + scale) + shift
        h = self.conv2(F.silu(h))
        return self.skip(x) + h


class Attention(nn.Module):
    """Single-head self-attention over the pixels of a (small) feature map."""

    def __init__(self, ch: int) -> None:
        super().__init__()
        self.norm = nn.GroupNorm(_groups(ch), ch)
        self.qkv = nn.Conv2d(ch, 3 * ch, 1)
        self.out = nn.Conv2d(ch, ch, 1)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)  # type: ignore[arg-type]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        q, k, v = self.qkv(self.norm(x)).reshape(b, 3, c, h * w).unbind(1)
        att = torch.softmax(torch.einsum("bci,bcj->bij", q, k) / math.sqrt(c), dim=-1)
        y = torch.einsum("bij,bcj->bci", att, v).reshape(b, c, h, w)
        return x + self.out(y)


class DenoiserUNet(nn.Module):
    """See the module docstring. ``forward(x, sigma) -> v`` with ``x``
    ``B x cfg.in_channels x H x W``."""

    def __init__(self, cfg: UNetConfig | None = None) -> None:
        super().__init__()
        self.cfg = cfg = cfg or UNetConfig()
        widths = [cfg.base * m for m in cfg.mults]
        self.emb = nn.Sequential(nn.Linear(cfg.emb, cfg.emb), nn.SiLU(),
                                 nn.Linear(cfg.emb, cfg.emb))
        self.stem = nn.Conv2d(4 * cfg.in_channels, widths[0], 3, padding=1)
        self.down = nn.ModuleList()
        self.pool = nn.ModuleList()
        for i, w in enumerate(widths[:-1]):  # the pool before level i+1 sets its width
            self.down.append(ResBlock(w, w, cfg.emb))
            self.pool.append(nn.Conv2d(w, widths[i + 1], 3, stride=2, padding=1))
        self.mid1 = ResBlock(widths[-1], widths[-1], cfg.emb)
        self.attn = Attention(widths[-1]) if cfg.attention else nn.Identity()
        self.mid2 = ResBlock(widths[-1], widths[-1], cfg.emb)
        self.up = nn.ModuleList()
        self.unpool = nn.ModuleList()
        for i in reversed(range(len(widths) - 1)):
            self.unpool.append(nn.Conv2d(widths[i + 1], widths[i], 3, padding=1))
            self.up.append(ResBlock(2 * widths[i], widths[i], cfg.emb))
        self.head_norm = nn.GroupNorm(_groups(widths[0]), widths[0])
        self.head = nn.Conv2d(widths[0], 4 * 3, 3, padding=1)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)  # type: ignore[arg-type]

    def forward(self, x: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
        e = self.emb(noise_embedding(sigma, self.cfg.emb))
        h = self.stem(F.pixel_unshuffle(x, 2))
        skips = []
        for block, pool in zip(self.down, self.pool, strict=True):
            h = block(h, e)
            skips.append(h)
            h = pool(h)
        h = self.mid2(self.attn(self.mid1(h, e)), e)
        for unpool, block in zip(self.unpool, self.up, strict=True):
            h = unpool(F.interpolate(h, scale_factor=2.0, mode="nearest"))
            h = block(torch.cat([h, skips.pop()], dim=1), e)
        return F.pixel_shuffle(self.head(F.silu(self.head_norm(h))), 2)


def network_input(cond: torch.Tensor, mask: torch.Tensor, x_t: torch.Tensor,
                  noise: torch.Tensor, prior: torch.Tensor,
                  spread: torch.Tensor | None = None) -> torch.Tensor:
    """The network input: condition with its holes replaced by ``noise`` (Palette), the mask,
    the noisy residual on the holes, the classical prior and (two-fill priors) the spread. All
    ``B x C x H x W``; images in [-1, 1]."""
    keep = 1.0 - mask
    parts = [cond * keep + noise * mask, mask, x_t * mask, prior]
    if spread is not None:
        parts.append(spread * mask)
    return torch.cat(parts, dim=1)


def count_params(net: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in net.parameters() if p.requires_grad)
