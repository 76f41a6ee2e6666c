"""The block engine's inputs (package-private): one side's landmark sets parsed and checked once
(:func:`prepare_side`, the boundary check of every matching call), descriptors made safe unit
rows, the sets padded to one tensor per side (:class:`Side`), and the selections of images a
block takes from a side. ``vpr_core.matching`` exports what the engine shares."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Union

import numpy as np
import torch

from ..checks import check_boxes, check_finite, check_shape

__all__ = [
    "PAD",
    "SAFE_MAGNITUDE",
    "LandmarkSets",
    "Selection",
    "Side",
    "check_same_dim",
    "landmark_lists",
    "normalised_centres",
    "prepare_side",
    "rescale_rows",
    "selection_index",
    "selection_size",
    "unit_rows",
]

#: Rows whose max-abs lies outside this range are rescaled before any norm: inside it, a float32
#: sum of D < 2^28 squares neither overflows nor underflows.
SAFE_MAGNITUDE = (2.0**-60, 2.0**50)
#: Below any cosine: padded landmarks never win an argmax.
PAD = -4.0

LandmarkSets = Union[np.ndarray, Sequence[np.ndarray]]  # noqa: UP007
#: Images of one side in a block: a contiguous range or an int64 index tensor.
Selection = Union[slice, torch.Tensor]  # noqa: UP007


def selection_index(sel: Selection, local: torch.Tensor) -> torch.Tensor:
    """Absolute image indices of block-local image indices ``local``."""
    return local + sel.start if isinstance(sel, slice) else sel[local]


def selection_size(sel: Selection) -> int:
    """Number of images in ``sel``."""
    return sel.stop - sel.start if isinstance(sel, slice) else int(sel.numel())


# ---- safe unit descriptors ---------------------------------------------------------------
def rescale_rows(x: np.ndarray) -> np.ndarray:
    """Scale rows of huge or tiny magnitude by a power of two so that no norm over/underflows.

    A row whose max-abs lies outside :data:`SAFE_MAGNITUDE` is multiplied by ``2^-e`` (exact) so
    its max-abs lands in ``[0.5, 1)``; cosines do not change. Other rows (and NaN / inf rows)
    keep their bits; ``x`` itself is never modified.

    Args:
        x: ``(..., D)`` float array.

    Returns:
        ``x`` when no row needed it, else a rescaled copy.
    """
    if x.size == 0:
        return x
    mag = np.maximum(x.max(axis=-1), -x.min(axis=-1))  # max-abs without an |x| temporary
    low, high = SAFE_MAGNITUDE
    bad = (mag > 0) & ((mag > high) | (mag < low)) & np.isfinite(mag)
    if not bad.any():
        return x
    exp = np.where(bad, np.frexp(mag)[1], 0)
    return np.ldexp(x, -exp[..., None]).astype(x.dtype, copy=False)


def unit_rows(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rows scaled to unit L2 norm (zero rows stay zero: cosine 0 with everything).

    Args:
        x: ``(N, D)`` rows, already through :func:`rescale_rows`.

    Returns:
        ``(unit (N, D), norm (N,))`` in ``x``'s dtype; a NaN / inf row shows in its norm.
    """
    norm = torch.linalg.vector_norm(x, dim=1)
    inv = torch.where(norm > 0, 1.0 / torch.where(norm > 0, norm, 1.0), torch.zeros_like(norm))
    return x * inv[:, None], norm


# ---- padded landmark sets ----------------------------------------------------------------
@dataclass
class Side:
    """Padded landmark sets of one side: ``N`` images zero padded to ``K = max K_i`` landmarks."""

    name: str  # "query", "reference", "a", "b": used in messages
    raw: torch.Tensor  # (N*K, D) descriptors as given (float32/float64, rescaled), zero padded
    d32: torch.Tensor  # (N*K, D) unit rows, matmul dtype
    mask: torch.Tensor  # (N, K) bool valid landmark
    count: torch.Tensor  # (N,) float64 number of landmarks
    wh: torch.Tensor  # (N, K, 2) float64 box sizes
    xy: torch.Tensor  # (N, K, 2) float64 box centres in units of the image's landmark extent
    boxes: list[np.ndarray]
    n: int
    k: int
    dim: int
    padded: bool

    _norm64: torch.Tensor | None = None
    _unit64: torch.Tensor | None = None

    def images(self, sel: Selection) -> torch.Tensor:
        """``(n * K, D)`` unit matmul-dtype descriptors of the images ``sel`` (a slice: a view)."""
        if isinstance(sel, slice):
            return self.d32[sel.start * self.k : sel.stop * self.k]
        return self.d32.view(self.n, self.k, -1).index_select(0, sel).view(-1, self.dim)

    def unit_images64(self, sel: Selection) -> torch.Tensor:
        """``(n * K, D)`` float64 unit descriptors of the images ``sel`` (cache built once)."""
        if self._unit64 is None:
            self._unit64 = self.raw.double() / self.norm64()[:, None]
        if isinstance(sel, slice):
            return self._unit64[sel.start * self.k : sel.stop * self.k]
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


def check_same_dim(named: Iterable[tuple[str, int]]) -> int:
    """The one descriptor dimension ``D`` of ``(name, D)`` pairs (0 when there are none); two
    different ones are refused, naming both (the rule of every matching and shortlist input)."""
    named = list(named)
    for name, dim in named[1:]:
        if dim != named[0][1]:
            raise ValueError(
                f"descriptor dimensions differ: {named[0][0]} D={named[0][1]}, {name} D={dim}; "
                "describe every image with the same encoder"
            )
    return named[0][1] if named else 0


def _as_list(x: LandmarkSets, name: str, kind: str) -> list[np.ndarray]:
    """One array per image from a sequence or a stacked ``(N, K, kind)`` array."""
    if isinstance(x, (np.ndarray, torch.Tensor)):
        arr = np.asarray(x.detach().cpu() if isinstance(x, torch.Tensor) else x)
        return list(check_shape(arr, f"N K {kind}", name))
    try:
        return [np.asarray(v) for v in x]
    except TypeError as e:
        raise ValueError(f"{name} must be a sequence of arrays or one (N, K, ...) array") from e


def _check_counts(n: int, n_boxes: int, dname: str, bname: str) -> None:
    """One boxes array per image, and at least one image."""
    if n_boxes != n:
        raise ValueError(f"{dname} has {n} images but {bname} has {n_boxes}")
    if n == 0:
        raise ValueError(f"{dname} is empty")


def landmark_lists(
    desc: LandmarkSets, boxes: LandmarkSets, side: str
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """One side's descriptors and boxes as one array per image, as many of each, at least one
    (``side``: ``"query"`` / ``"reference"``, named in messages); the arrays are not checked."""
    dname, bname = f"{side}_desc", f"{side}_boxes"
    dl, bl = _as_list(desc, dname, "D"), _as_list(boxes, bname, "4")
    _check_counts(len(dl), len(bl), dname, bname)
    return dl, bl


def prepare_side(
    desc: LandmarkSets,
    boxes: LandmarkSets | None,
    side: str,
    mm_dtype: torch.dtype,
    device: torch.device,
) -> Side:
    """Parse and check one side's landmark sets (the boundary check), pad and normalise them.

    Args:
        desc: sequence of ``(K_i, D)`` arrays or one ``(N, K, D)`` array.
        boxes: sequence of ``(K_i, 4)`` ``(x, y, w, h)`` arrays or ``(N, K, 4)``; None: no boxes
            (sizes 0, for the reciprocal matches alone).
        side: ``"query"`` / ``"reference"`` (messages name ``query_desc[i]``), or ``"a"`` / ``"b"``
            for one image (``desc_a``, ``boxes_a``).
        mm_dtype: dtype of the unit descriptors used in the matmul.
        device: torch device of every tensor.
    """
    one = side in ("a", "b")
    dname, bname = (f"desc_{side}", f"boxes_{side}") if one else (f"{side}_desc", f"{side}_boxes")

    def item(name: str, i: int) -> str:
        return name if one else f"{name}[{i}]"

    if isinstance(desc, (np.ndarray, torch.Tensor)) and np.ndim(desc) == 3:
        stacked = np.asarray(desc.detach().cpu() if isinstance(desc, torch.Tensor) else desc)
        if stacked.dtype not in (np.float32, np.float64):
            stacked = stacked.astype(np.float64)
        n, k, dim = stacked.shape
        counts = [k] * n
    else:
        dl = _as_list(desc, dname, "D")
        n = len(dl)
        dl = [np.zeros((0, 0)) if d.ndim == 1 and d.size == 0 else d for d in dl]
        for i, d in enumerate(dl):
            check_shape(d, "K D", item(dname, i))
        dim = check_same_dim([(item(dname, i), d.shape[1]) for i, d in enumerate(dl) if len(d)])
        counts = [d.shape[0] for d in dl]
        k = max(counts + [1])
        dtype = np.float32 if all(d.dtype == np.float32 for d in dl) else np.float64
        stacked = np.zeros((n, k, dim), dtype=dtype)
        for i, d in enumerate(dl):
            if d.shape[0]:
                stacked[i, : d.shape[0]] = d
    bl = [np.zeros((c, 4)) for c in counts] if boxes is None else _as_list(boxes, bname, "4")
    _check_counts(n, len(bl), dname, bname)
    stacked = rescale_rows(stacked)
    raw = torch.from_numpy(np.ascontiguousarray(stacked)).to(device).reshape(n * k, dim)
    d32, norm = unit_rows(raw.to(mm_dtype))
    norms = norm.cpu().numpy()  # NaN / inf anywhere shows in its row's norm
    check_finite(norms if one else norms.reshape(n, k), dname)  # row: landmark, else image
    wh = np.zeros((n, k, 2), dtype=np.float64)
    xy = np.zeros((n, k, 2), dtype=np.float64)
    mask = np.zeros((n, k), dtype=bool)
    bs = []
    for i, (c, b) in enumerate(zip(counts, bl, strict=True)):
        b = check_boxes(b, item(bname, i), c)
        bs.append(b)
        wh[i, :c] = b[:, 2:]
        xy[i, :c] = normalised_centres(b)
        mask[i, :c] = True
    return Side(
        name=dname,
        raw=raw,
        d32=d32.contiguous(),
        mask=torch.from_numpy(mask).to(device),
        count=torch.tensor(counts, dtype=torch.float64, device=device),
        wh=torch.from_numpy(wh).to(device),
        xy=torch.from_numpy(xy).to(device),
        boxes=bs,
        n=n,
        k=k,
        dim=dim,
        padded=bool(min(counts) != k),
    )


def normalised_centres(boxes: np.ndarray) -> np.ndarray:
    """Box centres in units of the extent of all the image's boxes (not in the paper).

    Args:
        boxes: ``(K, 4)`` float64 ``(x, y, w, h)`` boxes of one image.

    Returns:
        ``(K, 2)`` ``((cx - x0) / W, (cy - y0) / H)``: ``x0``, ``W`` the left edge and width of
        the boxes' union bounding box (``W = 1`` when it is 0), likewise ``y0``, ``H``.
    """
    if boxes.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.float64)
    lo = boxes[:, :2].min(axis=0)
    ext = (boxes[:, :2] + boxes[:, 2:]).max(axis=0) - lo
    ext = np.where(ext > 0, ext, 1.0)
    return (boxes[:, :2] + 0.5 * boxes[:, 2:] - lo) / ext
