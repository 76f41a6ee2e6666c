"""A user's ``torch.nn.Module`` as a landmark backbone (``LandmarkEncoder(backbone=net, ...)``)."""

from __future__ import annotations

import math
from typing import NoReturn

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


#: Crops in :func:`probe_input`: more than one, so a ``forward`` that behaves otherwise on a batch
#: (reads a global, or returns constant rows, only for several crops) is seen in the probe.
PROBE_CROPS = 2


def probe_input(size: int, crops: int = PROBE_CROPS) -> torch.Tensor:
    """The fixed input a user module's identity is measured on: ``(crops, 3, size, size)``
    float32 standard normal from ``torch.Generator`` seeded 0."""
    return torch.randn(crops, 3, size, size, generator=torch.Generator().manual_seed(0))


def _alike(inputs: torch.Tensor, per_cell: bool) -> bool:
    """The inputs are all one crop (a padded batch of one), or one uniform image (``per_cell``):
    identical features for them prove nothing."""
    first = inputs[..., :1, :1] if per_cell else inputs[:1]
    return bool((inputs == first).all())


def _degenerate(out: torch.Tensor, per_cell: bool) -> str | None:
    """What makes ``out`` unable to tell different inputs apart, None when nothing does
    (vectorised). ``per_cell``: ``out`` is one image's ``(1, C, h, w)`` map, compared cell by
    cell; else one row per crop."""
    if not out.any():
        return "all zeros"
    if per_cell:
        if math.prod(out.shape[-2:]) > 1 and bool((out == out[..., :1, :1]).all()):
            return "the same value in every cell of its feature map"
    elif bool((out == out[:1]).all()):
        return "the same features for every crop"
    return None


def _same(alone: object, row: torch.Tensor) -> bool:
    """Whether a crop's features ``alone`` (a batch of one) equal its ``row`` ``(1, ...)`` in a
    batch, to the precision other batch shapes give (other CPU kernels)."""
    scale = float(row.abs().max())
    return (
        isinstance(alone, torch.Tensor)
        and alone.shape == row.shape
        and torch.allclose(alone.float(), row.float(), rtol=1e-3, atol=1e-4 * scale)
    )


def _checked_batch(count: int) -> bool:
    """Whether the ``count``-th real batch (1-based) has crops compared with themselves alone:
    batches 1, 2, 4, 8, ... (a few single-crop passes per run, not per batch)."""
    return count & (count - 1) == 0


def _got(out: object) -> object:
    """What a module returned, for a message: its shape, a meta tensor's, or its type."""
    if not isinstance(out, torch.Tensor):
        return type(out).__name__
    return f"a meta tensor {tuple(out.shape)} (no data)" if out.is_meta else tuple(out.shape)


class ModuleBackbone(nn.Module):
    """Wraps a user module mapping ImageNet-normalised ``(B, 3, S, S)`` crops to ``(B, C, h, w)``
    or ``(B, C)`` features (the module is put in eval mode).

    ``roi`` pooling needs spatial output; its ``stride`` is the module's ``stride`` attribute or
    ``S / h`` when that divides, cell ``i`` centred at ``stride * i + feature_offset`` (the
    module's ``feature_offset``, default ``stride / 2``).

    The module's output is checked on :func:`probe_input` when wrapped (and a probe crop alone
    must give its features inside the batch: no dependence on the rest of the batch), and on
    every real batch of different crops (``forward``) or non-uniform image (``feature_map``):
    all zeros or the same features for every crop (every cell) are refused, naming the module;
    every call is checked for its shape, for NaN or inf and for an output that requires grad
    (vectorised: negligible cost). On real batches 1, 2, 4, 8, ... a few crops, at their
    positions, are compared with the same crops alone (a batch of one each).

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
        probe = probe_input(self.input_size).to(device)
        with torch.inference_mode():
            out = module(probe)
        size = f"({PROBE_CROPS}, 3, {self.input_size}, {self.input_size})"
        if not isinstance(out, torch.Tensor) or out.ndim not in (2, 4) or out.is_meta:
            got = _got(out)
            raise ValueError(
                f"backbone module {self.label} returned {got} for a {size} batch of crops; it "
                "must return (B, C, h, w) or (B, C) features holding numbers"
            )
        self._refuse_grad(out, f"a {size} batch of crops")
        fault = (
            "NaN or inf"
            if not out.isfinite().all()
            else _degenerate(out, False)
            if len(out) == len(probe)
            else None
        )
        if fault is None and out.ndim in (2, 4) and len(out) == len(probe) > 1:
            with torch.inference_mode():
                alone = module(probe[:1])
            if not _same(alone, out[:1]):
                fault = "other features for a crop alone than for the same crop in a batch"
        if fault is not None:
            self._refuse(fault, f"a random {size} input (backbones.module.probe_input)")
        self.probe_sha256 = array_sha256([out.detach().float().cpu().numpy()])
        self._batches = 0  # real batches seen (forward): some compared crop by crop
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

    @property
    def _fix(self) -> str:
        s = self.input_size
        return (
            "its descriptors could not tell landmarks apart. Check its forward on a batch of "
            f"different crops: {self.label}(...).eval()(torch.randn(4, 3, {s}, {s})) must give "
            "4 different rows, finite and not all zero, whatever the batch size (a forward "
            "that reads a global or a state left by an earlier call, or divides by a statistic "
            "of the batch, may not)"
        )

    def _refuse(self, fault: str, where: str, fix: str | None = None) -> NoReturn:
        """The one error for a module output that cannot describe landmarks: ``fault`` (NaN or
        inf, all zeros, ...) on ``where``, and the fix (default :attr:`_fix`)."""
        raise ValueError(
            f"backbone module {self.label} returns {fault} on {where}: {fix or self._fix}"
        )

    def _refuse_grad(self, out: torch.Tensor, where: str) -> None:
        """Refuse an output that requires grad: the package runs the module under
        ``torch.inference_mode()``, so its forward turned autograd back on."""
        if out.requires_grad:
            raise ValueError(
                f"backbone module {self.label} returns a tensor that requires grad on {where}, "
                "although the package runs it under torch.inference_mode(): its forward turns "
                "autograd back on (torch.enable_grad, torch.inference_mode(False), "
                "requires_grad_); remove that from its forward, or return out.detach()"
            )

    def _check_positions(self, batch: torch.Tensor, out: torch.Tensor) -> None:
        """On real batches 1, 2, 4, 8, ... (:func:`_checked_batch`), a few crops at their
        positions (the first, the last and a seeded one between; then one) against the same
        crops alone: a forward that depends on the batch's size, order or other crops is refused."""
        self._batches += 1
        n = batch.shape[0]
        if n < 2 or not _checked_batch(self._batches):
            return
        between = int(
            torch.randint(n, (1,), generator=torch.Generator().manual_seed(self._batches))
        )
        positions = sorted({0, between, n - 1}) if self._batches == 1 else [between]
        for p in positions:
            if not _same(self.module(batch[p : p + 1]), out[p : p + 1]):
                self._refuse(
                    f"other features for crop {p} of a real batch of {n} crops than for the "
                    "same crop alone",
                    f"real batch {self._batches} (its forward)",
                    "a crop's features must not depend on the batch it is in (its size, order "
                    "or other crops): check its forward on torch.randn(8, 3, S, S) against each "
                    "crop alone (a statistic of the batch, a term by position, a reordering)",
                )

    def _check_real(self, mode: str, out: torch.Tensor, inputs: torch.Tensor, where: str) -> None:
        """Refuse degenerate output on every real input of ``mode`` (``crop``: different crops;
        ``roi``: a non-uniform image)."""
        per_cell = mode == "roi"
        if _alike(inputs, per_cell):
            return
        fault = _degenerate(out, per_cell)
        if fault is not None:
            self._refuse(fault, where)

    def feature_map(self, batch: torch.Tensor) -> torch.Tensor:
        """``(1, 3, H, W)`` normalised image -> the module's ``(1, C, h, w)`` map (``roi``),
        checked: one map with the probe's ``C`` channels, finite, not degenerate."""
        out = self.module(batch)
        n, size = batch.shape[0], tuple(batch.shape)
        channels = self.feature_shape[0]
        if (
            not isinstance(out, torch.Tensor)
            or out.ndim != 4
            or out.shape[:2] != (n, channels)
            or out.is_meta
        ):
            got = _got(out)
            raise ValueError(
                f"backbone module {self.label} returned {got} for a {size} image "
                f"(pooling='roi'); expected ({n}, {channels}, h, w): one feature map per image "
                f"with the {channels} channels it gives on crops. Fix its forward to keep the "
                "batch dimension and work on images of any size, or use pooling='crop'"
            )
        self._refuse_grad(out, f"a {size} image (pooling='roi')")
        if not out.isfinite().all():
            self._refuse(
                "NaN or inf",
                f"a finite {size} image (pooling='roi', its feature map)",
                "check its forward on images of that size (an overflow, a division by zero), "
                "or use pooling='crop'",
            )
        self._check_real("roi", out, batch, f"a real {size} image (pooling='roi')")
        return out.float()

    def forward(self, batch: torch.Tensor) -> torch.Tensor:
        """``(B, 3, S, S)`` crops -> ``(B, raw_dim)``; the module's output checked (user code)."""
        out = self.module(batch)
        n = batch.shape[0]
        if (
            not isinstance(out, torch.Tensor)
            or tuple(out.shape) != (n, *self.feature_shape)
            or out.is_meta
        ):
            got = _got(out)
            raise ValueError(
                f"backbone module {self.label} returned {got} for {n} crops; "
                f"expected {(n, *self.feature_shape)}: one row per crop, the same shape on every "
                "call. Fix its forward to keep the batch dimension (B crops in, B rows out)"
            )
        self._refuse_grad(out, f"{n} crops (its forward)")
        if not out.isfinite().all():
            self._refuse(
                "NaN or inf",
                f"{n} finite crops (its forward)",
                "check it on real crops (an overflow, a division by zero)",
            )
        self._check_real("crop", out, batch, f"a real batch of {n} different crops")
        self._check_positions(batch, out)
        return out.float().flatten(1)
