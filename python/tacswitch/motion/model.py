"""Motion regressors (torch; imported only by training and export code).

Every network here maps uint8 BGR frames to a dense ``(dx, dy)`` field in input pixels and is
read out at marker centres by bilinear sampling (:func:`sample_at`), never at truncated integer
pixels. The conversion of the uint8 BGR frame to network input lives once, in :class:`Normalise`,
the first layer of every model, so training, the exported ONNX graph and every caller see the same
colour order and scaling: there is no separate preprocessing step to get wrong (the paper's slip
scripts fed BGR frames to an RGB-trained model).

Architectures (:data:`ARCHS`):

- ``"deeplabv3"``: the paper's reference, torchvision DeepLabV3 with a MobileNetV3-Large backbone,
  output stride 16, upsampled to full size (built with ``weights=None, weights_backbone=None``);
- ``"lraspp"``: torchvision LR-ASPP MobileNetV3-Large (lighter head);
- ``"unet"``: a small depthwise-separable U-Net whose field is read out at stride 4 (the field is
  smooth at the scale of a marker pitch, so the bilinear read-out replaces a full-size decoder).

With ``use_ref=True`` the network also receives the markerless no-contact reference frame; it sees
``[img, img - ref]`` (the difference is what carries the contact).

:class:`ConsistentMotionNet` (the shipped design) is consistent by construction: identical frames
give exactly zero motion, a global brightness change is normalised away, and the reference frame
is optional (single-frame mode).
"""

from __future__ import annotations

from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

ARCHS = ("unet", "lraspp", "deeplabv3")
#: uint8 -> network input: ``(x - PIXEL_MEAN) / PIXEL_SCALE``, same for B, G and R.
PIXEL_MEAN = 128.0
PIXEL_SCALE = 64.0
#: The heads regress ``motion / MOTION_SCALE`` (px): keeps the outputs near unit range.
MOTION_SCALE = 8.0


class Normalise(nn.Module):
    """``B x H x W x 3`` uint8 BGR (numpy's layout, as is) -> ``B x C x H x W`` float32.

    ``C = 3`` (the frame) or ``6`` (frame and frame minus reference).
    """

    def forward(self, img: torch.Tensor, ref: torch.Tensor | None = None) -> torch.Tensor:
        x = (img.permute(0, 3, 1, 2).float() - PIXEL_MEAN) / PIXEL_SCALE
        if ref is None:
            return x
        r = (ref.permute(0, 3, 1, 2).float() - PIXEL_MEAN) / PIXEL_SCALE
        return torch.cat([x, x - r], dim=1)


def sample_at(field: torch.Tensor, centres: torch.Tensor, height: int, width: int
              ) -> torch.Tensor:
    """Bilinear read-out of ``field`` (``B x 2 x h x w`` covering an ``height x width`` image)
    at ``centres`` (``B x N x 2`` (x, y) input pixels, pixel centres at integers) -> ``B x N x 2``.

    With ``align_corners=False`` the grid maps the image's outer edges, so the same formula holds
    for a full-size field and for one at any stride that tiles the image. Outside the image the
    border value is used (a marker pushed off the frame keeps its edge's motion, never NaN).
    """
    gx = (2.0 * centres[..., 0] + 1.0) / width - 1.0
    gy = (2.0 * centres[..., 1] + 1.0) / height - 1.0
    grid = torch.stack([gx, gy], dim=-1).unsqueeze(1)  # B x 1 x N x 2
    out = F.grid_sample(field, grid, mode="bilinear", padding_mode="border", align_corners=False)
    return out[:, :, 0, :].permute(0, 2, 1)


def _cbr(ci: int, co: int, k: int = 3, s: int = 1, groups: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(ci, co, k, s, (k - 1) // 2, groups=groups, bias=False),
                         nn.BatchNorm2d(co), nn.ReLU(inplace=True))


class _DS(nn.Sequential):
    """Depthwise 3x3 (stride ``s``) then pointwise 1x1, each with BN and ReLU."""

    def __init__(self, ci: int, co: int, s: int = 1) -> None:
        super().__init__(_cbr(ci, ci, 3, s, groups=ci), _cbr(ci, co, 1))


class SmallUNet(nn.Module):
    """Encoder to stride 32, decoder back to stride 4 with skips; ``widths`` at strides 4..32.

    The stem is a 4x4 stride-4 patch convolution: a full-resolution stage would cost most of the
    time and the field is only read out at stride 4.
    """

    def __init__(self, in_ch: int = 3, widths: tuple[int, ...] = (32, 64, 96, 128),
                 stem_stride: int = 4) -> None:
        super().__init__()
        w1, w2, w3, w4 = widths
        # stem_stride=1: the input is already at stride 4 (feature maps), a 1x1 mixing stem.
        self.stem = _cbr(in_ch, w1, stem_stride, stem_stride)  # /4
        self.e1 = _DS(w1, w1)
        self.e2 = nn.Sequential(_DS(w1, w2, 2), _DS(w2, w2))    # /8
        self.e3 = nn.Sequential(_DS(w2, w3, 2), _DS(w3, w3))    # /16
        self.e4 = nn.Sequential(_DS(w3, w4, 2), _DS(w4, w4))    # /32: context of a whole contact
        self.l3 = _cbr(w3, w4, 1)
        self.d3 = _DS(w4, w3)
        self.l2 = _cbr(w2, w3, 1)
        self.d2 = _DS(w3, w2)
        self.l1 = _cbr(w1, w2, 1)
        self.d1 = _DS(w2, w2)
        self.head = nn.Conv2d(w2, 2, 1)

    @staticmethod
    def _up(x: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
        return F.interpolate(x, size=like.shape[-2:], mode="bilinear", align_corners=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        s1 = self.e1(self.stem(x))
        s2 = self.e2(s1)
        s3 = self.e3(s2)
        s4 = self.e4(s3)
        y = self.d3(self._up(s4, s3) + self.l3(s3))
        y = self.d2(self._up(y, s2) + self.l2(s2))
        y = self.d1(self._up(y, s1) + self.l1(s1))
        return self.head(y)  # stride 4


class _TorchvisionSeg(nn.Module):
    """A torchvision segmentation model with 2 outputs, its first conv widened for ``in_ch``."""

    def __init__(self, arch: str, in_ch: int) -> None:
        super().__init__()
        from torchvision.models import segmentation as seg

        if arch == "deeplabv3":
            net = seg.deeplabv3_mobilenet_v3_large(weights=None, weights_backbone=None,
                                                   num_classes=2, aux_loss=False)
        else:
            net = seg.lraspp_mobilenet_v3_large(weights=None, weights_backbone=None,
                                                num_classes=2)
        if in_ch != 3:
            first = net.backbone["0"][0]
            net.backbone["0"][0] = nn.Conv2d(in_ch, first.out_channels, first.kernel_size,
                                             first.stride, first.padding, bias=False)
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)["out"]  # full size


class MotionNet(nn.Module):
    """uint8 BGR frame (+ optional reference) -> motion ``(dx, dy)`` px at given centres.

    ``forward(img, centres, ref=None)``: ``img``/``ref`` ``B x H x W x 3`` uint8 BGR, ``centres``
    ``B x N x 2`` (x, y) px -> ``B x N x 2`` (dx, dy) px. :meth:`field` gives the dense field.
    """

    def __init__(self, arch: str = "unet", use_ref: bool = False, **kw: Any) -> None:
        super().__init__()
        if arch not in ARCHS:
            raise ValueError(f"arch: must be one of {ARCHS}; got {arch!r}")
        self.arch, self.use_ref = arch, use_ref
        self.norm = Normalise()
        in_ch = 6 if use_ref else 3
        self.body: nn.Module = SmallUNet(in_ch, **kw) if arch == "unet" else \
            _TorchvisionSeg(arch, in_ch)

    def field(self, img: torch.Tensor, ref: torch.Tensor | None = None) -> torch.Tensor:
        """Dense ``B x 2 x h x w`` motion (px) covering the frame (h, w: the net's stride)."""
        if self.use_ref and ref is None:
            raise ValueError("ref: this model was trained with the reference frame; pass it")
        x = self.norm(img, ref if self.use_ref else None)
        return self.body(x) * MOTION_SCALE

    def forward(self, img: torch.Tensor, centres: torch.Tensor,
                ref: torch.Tensor | None = None) -> torch.Tensor:
        f = self.field(img, ref)
        return sample_at(f, centres, img.shape[1], img.shape[2])


class FrameNorm(nn.Module):
    """``B x H x W x 3`` uint8 BGR -> ``B x 3 x H x W`` float32, each frame and channel
    normalised by its own mean and standard deviation.

    A global brightness or contrast change of a frame (``a * img + b`` per channel) leaves its
    normalised image unchanged, up to rounding and clipping: the model downstream cannot see it.
    """

    def forward(self, img: torch.Tensor) -> torch.Tensor:
        x = img.permute(0, 3, 1, 2).float()
        m = x.mean(dim=(2, 3), keepdim=True)
        c = x - m
        # sqrt(mean(c^2)) rather than Tensor.std: one ONNX op chain, no Bessel factor; +1 grey
        # level keeps a flat frame finite.
        sd = torch.sqrt((c * c).mean(dim=(2, 3), keepdim=True)) + 1.0
        return c / sd


class ConsistentMotionNet(nn.Module):
    """Marker motion that is consistent by construction (a :class:`SmallUNet` ``G`` inside).

    ``G(x, d)`` maps a normalised frame ``x`` (:class:`FrameNorm`) and a difference image ``d``
    to the frame's marker motion *from rest* (a dense field, stride 4):

    - single frame (``ref`` omitted, the paper's setting): ``G(x, 0)``;
    - with a reference frame: ``G(x, x - r) - G(r, 0)``: the motion from ``ref`` to ``img``.

    For ``img == ref`` the two terms are the same computation on the same input: the motion is
    exactly zero. A global brightness change of either frame is normalised away before ``G``.
    ``use_ref`` is False: the reference is optional.
    """

    def __init__(self, widths: tuple[int, ...] = (32, 64, 96, 128)) -> None:
        super().__init__()
        self.arch, self.use_ref, self.design = "unet", False, "consistent"
        self.norm = FrameNorm()
        self.body = SmallUNet(6, widths)

    def _g(self, x: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
        return self.body(torch.cat([x, d], dim=1)) * MOTION_SCALE

    def pair_fields(self, x: torch.Tensor, r: torch.Tensor
                    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(single(ref), pair)`` from already normalised frames ``x``, ``r`` (training on
        crops of frames normalised whole, so the statistics are those inference sees)."""
        b = x.shape[0]
        f = self._g(torch.cat([r, x]), torch.cat([torch.zeros_like(r), x - r]))
        return f[:b], f[b:] - f[:b]

    def field(self, img: torch.Tensor, ref: torch.Tensor | None = None,
              has_ref: torch.Tensor | None = None) -> torch.Tensor:
        """Dense motion (px): single-frame without ``ref``; with ``ref``, from ``ref`` to ``img``.

        ``has_ref`` (a ``1``-element 0/1 tensor, the exported graph's switch): with 0 the result
        is the single-frame field of ``img`` whatever ``ref`` holds (one graph serves both)."""
        x = self.norm(img)
        if ref is None:
            return self._g(x, torch.zeros_like(x))
        r = self.norm(ref)
        b = x.shape[0]
        h = (torch.ones(1, dtype=x.dtype, device=x.device) if has_ref is None
             else has_ref.to(x.dtype))
        f = self._g(torch.cat([x, r]), torch.cat([(x - r) * h, torch.zeros_like(r)]))
        return f[:b] - h * f[b:]

    def forward(self, img: torch.Tensor, centres: torch.Tensor,
                ref: torch.Tensor | None = None, has_ref: torch.Tensor | None = None
                ) -> torch.Tensor:
        f = self.field(img, ref, has_ref)
        return sample_at(f, centres, img.shape[1], img.shape[2])


class SingleFrameMotionNet(nn.Module):
    """The single-frame output ``G(x, 0)`` of a trained :class:`ConsistentMotionNet`, alone (the
    paper's setting: one markerless frame -> each marker's motion from rest).

    Exported as its own graph (design ``"single"``: inputs ``image`` and ``centres`` only) when
    the pair output of the same weights is not wanted: there is no reference frame to confuse
    with, and nothing of the pair branch runs.
    """

    def __init__(self, net: ConsistentMotionNet) -> None:
        super().__init__()
        self.arch, self.use_ref, self.design = net.arch, False, "single"
        self.net = net

    def forward(self, img: torch.Tensor, centres: torch.Tensor,
                ref: torch.Tensor | None = None) -> torch.Tensor:
        if ref is not None:
            raise ValueError("ref: a single-frame model predicts the motion from rest; "
                             "call it without ref")
        return self.net(img, centres)


class CorrMotionNet(ConsistentMotionNet):
    """The consistent design on a local correlation volume instead of the frames' difference.

    Shared features ``f`` (stride 4) of each normalised frame; ``C(a, b)`` is the correlation of
    ``a`` with ``b`` shifted by every offset within ``radius`` feature cells (``radius * 4`` px);
    ``H(a, C)`` a :class:`SmallUNet` on ``[a, C]`` gives motion from rest:

    - single frame: ``H(f_x, C(f_x, f_x))``;
    - with a reference: ``H(f_x, C(f_x, f_r)) - H(f_r, C(f_r, f_r))``: exactly zero for
      identical frames (the two terms are then the same computation).
    """

    def __init__(self, feat: int = 16, radius: int = 4,
                 widths: tuple[int, ...] = (32, 64, 96, 128)) -> None:
        nn.Module.__init__(self)
        self.arch, self.use_ref, self.design = "corr", False, "consistent"
        self.norm = FrameNorm()
        self.radius = radius
        self.feat = nn.Sequential(_cbr(3, feat, 4, 4), _DS(feat, feat))
        self.body = SmallUNet(feat + (2 * radius + 1) ** 2, widths, stem_stride=1)

    def corr(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """``B x (2 radius + 1)^2 x h x w``: mean over channels of ``a(p) * b(p + d)``."""
        r = self.radius
        h, w = a.shape[-2:]
        bp = F.pad(b, (r, r, r, r))
        return torch.cat([(a * bp[:, :, dy:dy + h, dx:dx + w]).mean(1, keepdim=True)
                          for dy in range(2 * r + 1) for dx in range(2 * r + 1)], dim=1)

    def _h(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        return self.body(torch.cat([a, self.corr(a, b)], dim=1)) * MOTION_SCALE

    def pair_fields(self, x: torch.Tensor, r: torch.Tensor
                    ) -> tuple[torch.Tensor, torch.Tensor]:
        b = x.shape[0]
        f = self.feat(torch.cat([x, r]))
        fx, fr = f[:b], f[b:]
        out = self._h(torch.cat([fr, fx]), torch.cat([fr, fr]))
        return out[:b], out[b:] - out[:b]

    def field(self, img: torch.Tensor, ref: torch.Tensor | None = None,
              has_ref: torch.Tensor | None = None) -> torch.Tensor:
        x = self.norm(img)
        if ref is None:
            fx = self.feat(x)
            return self._h(fx, fx)
        b = x.shape[0]
        f = self.feat(torch.cat([x, self.norm(ref)]))
        fx, fr = f[:b], f[b:]
        h = (torch.ones(1, dtype=x.dtype, device=x.device) if has_ref is None
             else has_ref.to(x.dtype))
        # h = 0: the reference term drops out and the first correlates the frame with itself.
        fr_eff = fx + h * (fr - fx)
        out = self._h(torch.cat([fx, fr]), torch.cat([fr_eff, fr]))
        return out[:b] - h * out[b:]


def build_net(arch: str = "unet", use_ref: bool = False, design: str = "plain"
              ) -> MotionNet | ConsistentMotionNet:
    """The network of a training configuration: ``design="consistent"`` gives a
    :class:`ConsistentMotionNet` (``arch="unet"``: on the frames' difference) or a
    :class:`CorrMotionNet` (``arch="corr"``: on a correlation volume); ``"plain"`` a
    :class:`MotionNet`."""
    if design == "consistent":
        if arch == "corr":
            return CorrMotionNet()
        if arch != "unet":
            raise ValueError(f"arch: the consistent design uses 'unet' or 'corr'; got {arch!r}")
        return ConsistentMotionNet()
    if design != "plain":
        raise ValueError(f"design: must be 'plain' or 'consistent'; got {design!r}")
    return MotionNet(arch, use_ref)


def count_params(model: nn.Module) -> int:
    """Number of parameters."""
    return sum(p.numel() for p in model.parameters())
