"""A user's ``torch.nn.Module`` as a landmark backbone (``LandmarkEncoder(backbone=net, ...)``)."""

from __future__ import annotations

import math

import torch
from torch import nn

from ..utils import array_sha256, code_sha256
from .checkpoint import state_dict_sha256, user_weights_label

__all__ = ["ModuleBackbone", "architecture_sha256", "probe_input"]

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def architecture_sha256(module: nn.Module) -> str:
    """Hex sha256 of ``repr(module)`` and the bytecode of the methods of its (non-torch) classes.

    Editing a ``forward`` in a notebook cell or a layer's stride changes it (so the cache key).
    """
    return code_sha256((c for m in module.modules() for c in type(m).__mro__), repr(module))


def probe_input(size: int) -> torch.Tensor:
    """The fixed input a user module's identity is measured on: ``(1, 3, size, size)`` float32
    standard normal from ``torch.Generator`` seeded 0."""
    return torch.randn(1, 3, size, size, generator=torch.Generator().manual_seed(0))


class ModuleBackbone(nn.Module):
    """Wraps a user module mapping ImageNet-normalised ``(B, 3, S, S)`` crops to ``(B, C, h, w)``
    or ``(B, C)`` features (the module is put in eval mode).

    ``roi`` pooling needs spatial output; its ``stride`` is the module's ``stride`` attribute or
    ``S / h`` when that divides, cell ``i`` centred at ``stride * i + feature_offset`` (the
    module's ``feature_offset``, default ``stride / 2``).

    Attributes:
        label: the module's class name; qualname: ``module.Class``.
        weights_sha256: :func:`~vpr_core.backbones.checkpoint.state_dict_sha256` of the module.
        architecture_sha256: :func:`architecture_sha256` of the module.
        probe_sha256: sha256 of the module's output on :func:`probe_input` (a ``forward`` that
            reads a changed global gives another: the module's identity is its behaviour).
        feature_shape, raw_dim, stride (None without spatial output), feature_offset.
    """

    mean = IMAGENET_MEAN
    std = IMAGENET_STD

    def __init__(self, module: nn.Module, input_size: int) -> None:
        super().__init__()
        self.module = module.eval()
        self.input_size = int(input_size)
        cls = type(module)
        self.label = cls.__name__
        self.qualname = f"{cls.__module__}.{cls.__qualname__}"
        state = module.state_dict()
        bad = [k for k, t in state.items() if t.is_floating_point() and not t.isfinite().all()]
        if bad:
            raise ValueError(
                f"backbone module {self.label}: its weights hold NaN or inf ({', '.join(bad[:3])})"
            )
        self.weights_sha256 = state_dict_sha256(state)
        self.weights_source = user_weights_label(self.weights_sha256)
        self.architecture_sha256 = architecture_sha256(module)
        param = next(module.parameters(), None)
        device = param.device if param is not None else torch.device("cpu")
        with torch.inference_mode():
            out = module(probe_input(self.input_size).to(device))
        if not isinstance(out, torch.Tensor) or out.ndim not in (2, 4):
            got = tuple(out.shape) if isinstance(out, torch.Tensor) else type(out).__name__
            raise ValueError(
                f"backbone module {self.label} returned {got} for a (1, 3, {self.input_size}, "
                f"{self.input_size}) crop; it must return (B, C, h, w) or (B, C) features"
            )
        if not out.isfinite().all() or not out.any():
            raise ValueError(
                f"backbone module {self.label} returns "
                f"{'all zeros' if out.isfinite().all() else 'NaN or inf'} on a random (1, 3, "
                f"{self.input_size}, {self.input_size}) input (backbones.module.probe_input): "
                "its descriptors could not tell landmarks apart"
            )
        self.probe_sha256 = array_sha256([out.detach().float().cpu().numpy()])
        self.feature_shape = tuple(int(n) for n in out.shape[1:])
        self.raw_dim = math.prod(self.feature_shape)
        self.stride: int | None = None
        self.feature_offset = 0.0
        if out.ndim == 4:
            h = self.feature_shape[1]
            stride = getattr(module, "stride", None)
            if not isinstance(stride, int) and self.input_size % h == 0:
                stride = self.input_size // h
            if isinstance(stride, int) and math.ceil(self.input_size / stride) == h:
                self.stride = stride
                self.feature_offset = float(getattr(module, "feature_offset", stride / 2))

    def feature_map(self, batch: torch.Tensor) -> torch.Tensor:
        """``(B, 3, H, W)`` normalised images -> the module's ``(B, C, h, w)`` map."""
        return self.module(batch).float()

    def forward(self, batch: torch.Tensor) -> torch.Tensor:
        """``(B, 3, S, S)`` crops -> ``(B, raw_dim)``; the module's output checked (user code)."""
        out = self.module(batch)
        n = batch.shape[0]
        if tuple(out.shape) != (n, *self.feature_shape):
            raise ValueError(
                f"backbone module {self.label} returned {tuple(out.shape)} for {n} crops; "
                f"expected {(n, *self.feature_shape)}: one row per crop, the same shape on every "
                "call"
            )
        if not out.isfinite().all():
            raise ValueError(
                f"backbone module {self.label} returned NaN or inf for finite crops (its forward)"
            )
        return out.float().flatten(1)
