"""Padded landmark sets: the batched path's view of one side (queries or references).

Every image's ``(K_i, D)`` descriptors are zero padded to ``K = max K_i`` and stacked to
``(N * K, D)``; a mask marks the real landmarks. Box sizes and per-image IoU matrices are kept for
Eq. (2) and soft-NMS.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Union

import numpy as np
import torch

from ..boxes import box_iou, check_boxes

__all__ = ["LandmarkSets", "Side", "iou_stack", "prepare_side"]

LandmarkSets = Union[np.ndarray, Sequence[np.ndarray]]  # noqa: UP007


@dataclass
class Side:
    """Padded landmark sets of one side (query or reference); built by :func:`prepare_side`."""

    raw: torch.Tensor  # (N*K, D) descriptors as given (float32/float64), zero padded
    d32: torch.Tensor  # (N*K, D) normalised, matmul dtype
    mask: torch.Tensor  # (N, K) bool valid landmark
    count: torch.Tensor  # (N,) float64 number of landmarks
    wh: torch.Tensor  # (N, K, 2) float64 box sizes
    boxes: list[np.ndarray]
    n: int
    k: int
    dim: int
    padded: bool

    _norm64: torch.Tensor | None = None
    _unit64: torch.Tensor | None = None

    def images(self, sel: slice | torch.Tensor) -> torch.Tensor:
        """``(n * K, D)`` normalised matmul-dtype descriptors of the images ``sel``.

        Args:
            sel: a ``slice`` of image indices (a view, no copy) or an int64 index tensor.
        """
        if isinstance(sel, slice):
            return self.d32[sel.start * self.k: sel.stop * self.k]
        return self.d32.view(self.n, self.k, -1).index_select(0, sel).view(-1, self.dim)

    def unit_images64(self, sel: slice | torch.Tensor) -> torch.Tensor:
        """``(n * K, D)`` float64 unit descriptors of the images ``sel`` (cache built once)."""
        if self._unit64 is None:
            self._unit64 = self.raw.double() / self.norm64()[:, None]
        if isinstance(sel, slice):
            return self._unit64[sel.start * self.k: sel.stop * self.k]
        return self._unit64.view(self.n, self.k, -1).index_select(0, sel).view(-1, self.dim)

    def build_caches(self, unit64: bool) -> None:
        """Compute the lazy float64 caches now (before worker threads share this side)."""
        self.norm64()
        if unit64:
            self.unit_images64(slice(0, 0))

    def norm64(self) -> torch.Tensor:
        """``(N*K,)`` float64 descriptor norms (1 for zero rows), computed once."""
        if self._norm64 is None:
            n = torch.linalg.vector_norm(self.raw, dim=1, dtype=torch.float64)
            self._norm64 = torch.where(n > 0, n, torch.ones_like(n))
        return self._norm64


def _as_list(x: LandmarkSets, name: str, kind: str) -> list[np.ndarray]:
    """One array per image from a sequence or a stacked ``(N, K, kind)`` array."""
    if isinstance(x, (np.ndarray, torch.Tensor)):
        arr = np.asarray(x.detach().cpu() if isinstance(x, torch.Tensor) else x)
        if arr.ndim != 3:
            raise ValueError(f"{name} as one array must be (N, K, {kind}), got shape {arr.shape}")
        return list(arr)
    try:
        return [np.asarray(v) for v in x]
    except TypeError as e:
        raise ValueError(f"{name} must be a sequence of arrays or one (N, K, ...) array") from e


def prepare_side(desc: LandmarkSets, boxes: LandmarkSets, side: str, mm_dtype: torch.dtype,
                 device: torch.device) -> Side:
    """Check, pad and normalise one side's landmark sets.

    Args:
        desc: sequence of ``(K_i, D)`` arrays, or one ``(N, K, D)`` array / tensor.
        boxes: sequence of ``(K_i, 4)`` ``(x, y, w, h)`` arrays, or one ``(N, K, 4)`` array.
        side: ``"query"`` or ``"reference"`` (used in error messages).
        mm_dtype: dtype of the normalised descriptors used in the matmul.
        device: torch device of every tensor.

    Returns:
        :class:`Side`.
    """
    bl = _as_list(boxes, f"{side}_boxes", "4")
    if isinstance(desc, (np.ndarray, torch.Tensor)) and np.ndim(desc) == 3:
        stacked = np.asarray(desc.detach().cpu() if isinstance(desc, torch.Tensor) else desc)
        if stacked.dtype not in (np.float32, np.float64):
            stacked = stacked.astype(np.float64)
        n, k, dim = stacked.shape
        counts = [k] * n
    else:
        dl = _as_list(desc, f"{side}_desc", "D")
        n = len(dl)
        dl = [np.zeros((0, 0)) if d.ndim == 1 and d.size == 0 else d for d in dl]
        for i, d in enumerate(dl):
            if d.ndim != 2:
                raise ValueError(f"{side}_desc[{i}] must be (K, D), got shape {d.shape}")
        dims = sorted({d.shape[1] for d in dl if d.shape[0]})
        if len(dims) > 1:
            raise ValueError(f"{side}_desc mixes descriptor dimensions {dims}")
        dim = dims[0] if dims else 0
        counts = [d.shape[0] for d in dl]
        k = max(counts + [1])
        dtype = np.float32 if all(d.dtype == np.float32 for d in dl) else np.float64
        stacked = np.zeros((n, k, dim), dtype=dtype)
        for i, d in enumerate(dl):
            if d.shape[0]:
                stacked[i, : d.shape[0]] = d
    if len(bl) != n:
        raise ValueError(f"{side}_desc has {n} images but {side}_boxes has {len(bl)}")
    if n == 0:
        raise ValueError(f"{side}_desc is empty")
    raw = torch.from_numpy(np.ascontiguousarray(stacked)).to(device).reshape(n * k, dim)
    raw_mm = raw.to(mm_dtype)
    norm = torch.linalg.vector_norm(raw_mm, dim=1)  # NaN / inf anywhere shows in the norm
    if not bool(torch.isfinite(norm).all()):
        raise ValueError(f"{side}_desc contains NaN or inf")
    inv = torch.where(norm > 0, 1.0 / torch.where(norm > 0, norm, 1.0), torch.zeros_like(norm))
    d32 = (raw_mm * inv[:, None]).contiguous()
    wh = np.zeros((n, k, 2), dtype=np.float64)
    mask = np.zeros((n, k), dtype=bool)
    bs = []
    for i, (c, b) in enumerate(zip(counts, bl)):
        b = check_boxes(b, f"{side}_boxes[{i}]", c)
        bs.append(b)
        wh[i, :c] = b[:, 2:]
        mask[i, :c] = True
    return Side(
        raw=raw,
        d32=d32,
        mask=torch.from_numpy(mask).to(device),
        count=torch.tensor(counts, dtype=torch.float64, device=device),
        wh=torch.from_numpy(wh).to(device),
        boxes=bs,
        n=n,
        k=k,
        dim=dim,
        padded=bool(min(counts) != k),
    )


def iou_stack(side: Side, device: torch.device) -> torch.Tensor:
    """(N, K, K) float64 per-image IoU matrices (zero padded), via :func:`vpr_core.boxes.box_iou`."""
    out = np.zeros((side.n, side.k, side.k), dtype=np.float64)
    for i, b in enumerate(side.boxes):
        c = b.shape[0]
        if c:
            out[i, :c, :c] = box_iou(b, b)
    return torch.from_numpy(out).to(device)

