"""EfficientNet-Lite's BN-folded blocks through fused oneDNN convolutions (CPU inference), run
for an input shape only where they give the module path's bits (checked on its first batch)."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, cast

import torch
import torch.nn.functional as F

if TYPE_CHECKING:
    from .efficientnet_lite import Conv2dSame, EfficientNetLite, MBConvBlock

logger = logging.getLogger("vpr_core")

__all__ = ["BitCheckedFusion"]

Window = tuple[int, int, int, int]


def _conv(conv: Conv2dSame, x: torch.Tensor, relu6: bool) -> tuple[torch.Tensor, Window | None]:
    """A BN-folded ``conv`` (+ ReLU6 on the accumulators) as one oneDNN call. Stride-2 layers take
    their TF "same" padding inside the call (symmetric, widened to keep the stride phase)
    instead of an ``F.pad`` copy; their output then has an extra row/column, and the returned
    ``(row, col, h, w)`` window says where the wanted output lies (None: all of it)."""
    pads, window = list(conv.padding), None  # type: ignore[arg-type]
    if conv._dynamic:
        left, right, top, bottom = conv.same_pads(x.shape[-2], x.shape[-1])
        s_h, s_w = conv.stride
        pad_h = top + s_h * math.ceil(max(bottom - top, 0) / s_h)
        pad_w = left + s_w * math.ceil(max(right - left, 0) / s_w)
        pads = [pad_h, pad_w]
        rows, cols = math.ceil(x.shape[-2] / s_h), math.ceil(x.shape[-1] / s_w)
        window = ((pad_h - top) // s_h, (pad_w - left) // s_w, rows, cols)
    y = torch.ops.mkldnn._convolution_pointwise(
        x,
        conv.weight,
        conv.bias,
        pads,
        list(conv.stride),
        list(conv.dilation),
        conv.groups,
        "hardtanh" if relu6 else "none",
        [0.0, 6.0] if relu6 else [],
        "",
    )
    return y, window


def _onednn_feature_map(net: EfficientNetLite, x: torch.Tensor) -> torch.Tensor:
    """:meth:`EfficientNetLite.extract_stage` of a BN-folded net over its blocks, through fused
    oneDNN convolutions (1.25x faster on the study's crops, ``benchmarks/study_floor.py``). The
    stem keeps its ``F.pad``: 3 channels are cheap to pad, and with in-call padding its kernel,
    and its bits, change."""
    stem = net._conv_stem
    pads = stem.same_pads(x.shape[-2], x.shape[-1])
    x = F.pad(x, pads) if any(pads) else x
    x = torch.ops.mkldnn._convolution_pointwise(
        x, stem.weight, stem.bias, [0, 0], list(stem.stride), [1, 1], 1, "hardtanh", [0.0, 6.0], ""
    )
    for block in cast("list[MBConvBlock]", net._blocks):
        y = _conv(block._expand_conv, x, relu6=True)[0] if block.has_expand else x
        y, window = _conv(block._depthwise_conv, y, relu6=True)
        y = _conv(block._project_conv, y, relu6=False)[0]  # 1x1: per pixel
        if window is not None:  # slice after the projection: fewer channels to copy later
            r, c, h, w = window
            y = y[:, :, r : r + h, c : c + w]
        x = y + x if block.skip else y
    return x


def _usable(x: torch.Tensor) -> bool:
    return (
        x.device.type == "cpu"
        and x.dtype == torch.float32
        and not torch.is_grad_enabled()
        and torch.backends.mkldnn.is_available()
        and hasattr(torch.ops.mkldnn, "_convolution_pointwise")
    )


class BitCheckedFusion:
    """:func:`_onednn_feature_map` where it gives the module path's bits: the first batch of each
    shape and thread count runs both and compares them bit for bit (on one Intel Xeon a
    1 x 3 x 96 x 96 batch of stage 4 differed); a shape where they differ, or where the fused
    call fails, keeps the module path, as does ``enabled = False``. ``agrees``: the verdicts."""

    def __init__(self) -> None:
        self.enabled = True
        self.agrees: dict[tuple[Any, ...], bool] = {}

    def __call__(
        self,
        net: EfficientNetLite,
        x: torch.Tensor,
        module_path: Callable[[torch.Tensor], torch.Tensor],
    ) -> torch.Tensor:
        if not (self.enabled and _usable(x)):
            return module_path(x)
        key = (tuple(x.shape), torch.get_num_threads())
        fast = self.agrees.get(key)
        if fast:
            return _onednn_feature_map(net, x)
        ref = module_path(x)
        if fast is None:
            try:
                fast, why = torch.equal(_onednn_feature_map(net, x), ref), "gives other bits"
            except RuntimeError as exc:  # a oneDNN build without this primitive
                fast, why = False, f"failed ({exc})"
            self.agrees[key] = fast
            if not fast:
                logger.debug("fused oneDNN path %s at %s: module path kept", why, key)
        return ref
