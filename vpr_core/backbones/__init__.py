"""Landmark backbones by name or spec (``"efficientnet_lite0:stage=4,input_size=96"``) or a user's
``nn.Module`` (:class:`ModuleBackbone`); each has ``mean``, ``std``, ``weights_sha256`` (identity
by content), ``weights_source`` and ``forward``; the crop side is the encoder's."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from torch import nn

from ..checks import check_int, check_options
from ..paper import ALEXNET_INPUT
from ..utils import file_sha256
from .alexnet import AlexNetConv3, resolve_weights
from .checkpoint import state_dict_sha256
from .efficientnet_lite import N_STAGES, EfficientNetLiteFeatures, default_weights_path
from .handcrafted import HOGBackbone
from .module import architecture_sha256

Factory = Callable[..., nn.Module]


Weights = str | os.PathLike | None
#: A parsed spec: :func:`parse_backbone`'s ``(name, options)``.
Parsed = tuple[str, dict[str, int]]


def _no_weights(weights: Weights) -> Path | str | None:
    return None


@dataclass(frozen=True)
class _Entry:
    factory: Factory  # factory(weights, seed, **options): a network; the crop side is the encoder's
    input_size: int
    options: dict[str, int] = field(default_factory=dict)  # option -> default (besides size)
    resolve: Callable[[Weights], Path | str | None] = _no_weights  # the weights file it reads


def _lite(variant: str) -> Factory:
    def build(weights: Weights, seed: int, stage: int) -> nn.Module:
        return EfficientNetLiteFeatures(stage=stage, weights=weights, variant=variant)

    return build


def _lite_file(variant: str) -> Callable[[Weights], Path]:
    def resolve(weights: Weights) -> Path:
        return Path(weights).expanduser() if weights is not None else default_weights_path(variant)

    return resolve


def _alexnet_conv3(weights: Weights, seed: int) -> nn.Module:
    return AlexNetConv3(weights=weights, seed=seed)


def _hog(weights: Weights, seed: int) -> nn.Module:
    if weights is not None:
        raise ValueError("the 'hog' backbone has no weights; pass weights=None")
    return HOGBackbone()


_REGISTRY: dict[str, _Entry] = {
    # 8x8x112 = 7,168-d; chosen on real data (docs/MEASUREMENTS.md "Which descriptor?")
    "efficientnet_lite0": _Entry(_lite("lite0"), 128, {"stage": 5}, _lite_file("lite0")),
    # 10x10x80 = 8,000-d, same cost as stage 5 at 128
    "efficientnet_lite0_stage4": _Entry(_lite("lite0"), 160, {"stage": 4}, _lite_file("lite0")),
    "efficientnet_lite1": _Entry(_lite("lite1"), 128, {"stage": 5}, _lite_file("lite1")),
    "efficientnet_lite2": _Entry(_lite("lite2"), 128, {"stage": 5}, _lite_file("lite2")),
    "alexnet_conv3": _Entry(_alexnet_conv3, ALEXNET_INPUT, {}, resolve_weights),
    "hog": _Entry(_hog, 64),
}
#: Valid stage range of the EfficientNet-Lite backbones.
_STAGES = range(1, N_STAGES + 1)


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
        ValueError: unknown name (lists the valid ones), an unknown option or one given twice
            (lists the backbone's), a value that is not an integer, or a stage / size out of
            range.
    """
    if not isinstance(spec, str):
        raise TypeError(
            "backbone must be a name such as 'efficientnet_lite0' or a torch.nn.Module, "
            f"got {spec!r}"
        )
    name, _, rest = spec.partition(":")
    name = name.strip()
    options = backbone_options(name)
    items = [[s.strip() for s in p.partition("=")] for p in rest.split(",") if p.strip()]
    for key, eq, _ in items:
        if not eq:
            raise ValueError(
                f"backbone {name!r}: option {key!r} in {spec!r} has no value; write key=integer, "
                f"e.g. {', '.join(f'{k}={v}' for k, v in options.items())} (the defaults)"
            )
    check_options([key for key, _, _ in items], options, f"backbone {name!r}")
    for key, _, value in items:
        try:
            options[key] = int(value)
        except ValueError:
            raise ValueError(
                f"backbone {name!r}: option {key} must be an integer, got {value!r} in {spec!r}"
            ) from None
    check_int(options["input_size"], f"input_size in {spec!r}", 16)
    if "stage" in options and options["stage"] not in _STAGES:
        raise ValueError(f"stage must be in 1..{N_STAGES}, got {options['stage']} in {spec!r}")
    return name, options


def _parsed(spec: str | Parsed) -> Parsed:
    """``spec`` parsed: a string by :func:`parse_backbone`; a :data:`Parsed` pair is trusted (the
    :class:`~vpr_core.features.Encoder` parses its backbone once, when it is made)."""
    return spec if isinstance(spec, tuple) else parse_backbone(spec)


def canonical_backbone(spec: str | Parsed) -> str:
    """One spelling per backbone configuration: options sorted, defaults dropped (``spec``: a
    string, or :func:`parse_backbone`'s pair)."""
    name, options = _parsed(spec)
    defaults = backbone_options(name)
    diff = [f"{k}={v}" for k, v in sorted(options.items()) if v != defaults[k]]
    return name + (":" + ",".join(diff) if diff else "")


def weights_sha256(spec: str | Parsed, weights: Weights = None) -> str:
    """The identity of the weights a backbone (``spec``: a string, or :func:`parse_backbone`'s
    pair) would read: the sha256 of the file's bytes, read now (never memoised by path, size or
    mtime), ``"random"``, ``"none"``, or ``"missing"`` (building the backbone then raises its
    own clear error).

    Raises:
        FileNotFoundError: AlexNet finds no weights file at all (the message says how to get one).
    """
    found = _REGISTRY[_parsed(spec)[0]].resolve(weights)
    if found is None or isinstance(found, str):
        return "none" if found is None else found
    return file_sha256(found) if found.is_file() else "missing"


def build_backbone(spec: str | Parsed, weights: Weights = None, seed: int = 0) -> nn.Module:
    """The network of a backbone name or spec (or :func:`parse_backbone`'s pair), in eval mode
    (the spec's ``input_size`` is the encoder's crop side; :func:`feature_shape` gives the
    network's output at a side).

    The arguments are trusted: :class:`~vpr_core.features.Encoder` checks them once.
    ``weights``: a path, ``"random"`` for AlexNet, None: the default lookup; ``seed`` seeds a
    random initialisation.
    """
    base, options = _parsed(spec)
    network = {k: v for k, v in options.items() if k != "input_size"}
    model: Any = _REGISTRY[base].factory(weights, seed, **network)
    return model.eval()


def feature_shape(model: nn.Module, input_size: int) -> tuple[int, ...]:
    """``model``'s feature shape on ``(B, 3, S, S)`` crops, ``S = input_size``: its feature map's
    ``(C, h, w)`` where it has one, else its output's ``(D,)`` (measured on one zero crop)."""
    net: Any = model
    with torch.inference_mode():
        x = torch.zeros(1, 3, input_size, input_size)
        out = net.feature_map(x) if hasattr(net, "feature_map") else net(x)
    return tuple(int(n) for n in out.shape[1:])


__all__ = [
    "architecture_sha256",
    "available_backbones",
    "parse_backbone",
    "state_dict_sha256",
    "weights_sha256",
]
