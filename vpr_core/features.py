"""Landmark descriptors: batched crops -> CNN (or handcrafted) features -> random projection.

``LandmarkEncoder(backbone, dim, seed)`` turns an image and its landmark boxes into one
descriptor per box, as in the paper's Section 2.1 (AlexNet conv3, 64,896-d, Gaussian random
projection to 1,024-d, cosine distance downstream):

1. **Crop** every box with ``kornia.geometry.transform.crop_and_resize`` (box -> 4 corner points
   clipped to the image, bilinear, ``align_corners=True``) to the backbone's square input size.
   Boxes much larger than the input are cropped from a 2x/4x/... average-pooled copy of the image
   (an image pyramid) so that the final bilinear resize never shrinks by 2x or more (anti-aliasing,
   like MATLAB/Caffe ``imresize`` in the original pipeline); ``antialias=False`` turns this off.
2. **Normalise** with the backbone's mean/std (ImageNet for the CNNs), applied to the whole image
   once (it commutes with bilinear sampling).
3. **Backbone** in batches of ``batch_size`` under ``torch.inference_mode()`` -> ``(K, raw_dim)``.
4. **Project** with a Gaussian random matrix ``P (raw_dim, dim)``, entries ``N(0, 1/dim)``, drawn
   from ``numpy.random.default_rng(seed)``: deterministic across runs, identical for equal seeds.
   With ``dim=None`` or ``dim >= raw_dim`` there is no projection and descriptors are raw
   features (``.dim == raw_dim``). Descriptors are not normalised (cosine distance is used
   downstream); they are float32.

Backbones are looked up by name in :mod:`vpr_core.backbones` (``available_backbones()``).
"""

from __future__ import annotations

import math
import os
from functools import lru_cache
from typing import Any

import numpy as np
import torch
from kornia.geometry.transform import crop_and_resize

from .backbones import DEFAULT_INPUT_SIZE, available_backbones, build_backbone
from .utils import logger

__all__ = ["LandmarkEncoder", "available_backbones", "boxes_to_corners", "random_projection"]

#: Bumped when the descriptor computation changes in a way that invalidates caches.
DESCRIPTOR_VERSION = 2  # 2: fixed batch shape (grouping-invariant descriptors)


@lru_cache(maxsize=2)
def _projection_cached(raw_dim: int, dim: int, seed: int) -> torch.Tensor:
    rng = np.random.default_rng(seed)
    mat = rng.standard_normal((raw_dim, dim), dtype=np.float32)
    mat *= np.float32(1.0 / math.sqrt(dim))
    return torch.from_numpy(mat)


def random_projection(raw_dim: int, dim: int, seed: int = 0) -> torch.Tensor:
    """Gaussian random projection matrix.

    Args:
        raw_dim: input dimension.
        dim: output dimension.
        seed: seed of ``numpy.random.default_rng`` (PCG64).

    Returns:
        ``(raw_dim, dim)`` float32 tensor with i.i.d. ``N(0, 1/dim)`` entries (read-only: shared
        between encoders with the same arguments).
    """
    if raw_dim < 1 or dim < 1:
        raise ValueError(f"raw_dim and dim must be positive, got {raw_dim}, {dim}")
    return _projection_cached(int(raw_dim), int(dim), int(seed))


def _check_image(image: Any) -> np.ndarray:
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image must be a numpy array (H, W, 3) uint8, got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must have shape (H, W, 3) (RGB), got {image.shape}")
    if image.dtype != np.uint8:
        raise ValueError(f"image must be uint8 RGB, got dtype {image.dtype}")
    if image.shape[0] < 1 or image.shape[1] < 1:
        raise ValueError(f"image is empty: shape {image.shape}")
    return image


def _check_boxes(boxes: Any) -> np.ndarray:
    arr = np.asarray(boxes, dtype=np.float64)
    if arr.size == 0:
        return arr.reshape(0, 4)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"boxes must have shape (K, 4) as (x, y, w, h), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("boxes contain NaN or inf")
    if (arr[:, 2] <= 0).any() or (arr[:, 3] <= 0).any():
        bad = np.flatnonzero((arr[:, 2] <= 0) | (arr[:, 3] <= 0))
        raise ValueError(f"boxes must have positive width and height; bad rows: {bad[:10]}")
    return arr


def boxes_to_corners(boxes: np.ndarray, image_size: tuple[int, int], level: int = 0) -> np.ndarray:
    """``(x, y, w, h)`` boxes -> kornia corner points, clipped to the image.

    A box covers the continuous region ``[x, x + w) x [y, y + h)``; its corner *pixel centres*
    (``x .. x + w - 1`` at level 0) are what ``crop_and_resize`` (``align_corners=True``) maps
    onto the output's corner pixels. At pyramid level ``l`` (image average-pooled by ``2**l``) the
    same region is ``[x / 2**l, (x + w) / 2**l)``.

    Args:
        boxes: ``(K, 4)`` float, pixels of the full-resolution image.
        image_size: ``(H, W)`` of the image at this level.
        level: pyramid level.

    Returns:
        ``(K, 4, 2)`` float32 ``(x, y)`` points: top-left, top-right, bottom-right, bottom-left.
    """
    h_img, w_img = image_size
    f = float(2**level)
    x1 = boxes[:, 0] / f
    y1 = boxes[:, 1] / f
    x2 = (boxes[:, 0] + boxes[:, 2]) / f - 1.0
    y2 = (boxes[:, 1] + boxes[:, 3]) / f - 1.0
    x1 = np.clip(x1, 0, w_img - 1)
    y1 = np.clip(y1, 0, h_img - 1)
    x2 = np.clip(np.maximum(x2, x1), 0, w_img - 1)
    y2 = np.clip(np.maximum(y2, y1), 0, h_img - 1)
    pts = np.stack(
        [np.stack([x1, y1], 1), np.stack([x2, y1], 1), np.stack([x2, y2], 1),
         np.stack([x1, y2], 1)],
        axis=1,
    )
    return pts.astype(np.float32)


class LandmarkEncoder:
    """Describe landmark boxes with a CNN (or handcrafted) backbone + Gaussian random projection.

    Args:
        backbone: name in :func:`available_backbones` (default ``"efficientnet_lite0"``).
        dim: output dimension of the random projection (1024 in the paper); None or
            ``>= raw_dim``: no projection, raw features.
        seed: seed of the projection matrix (and of ``weights="random"`` initialisations).
        device: torch device for the backbone and projection.
        weights: backbone weights: a path to a state dict, ``"random"`` (AlexNet only, flagged),
            or None for the backbone's default lookup (see :mod:`vpr_core.backbones`).
        input_size: square crop side; None -> the backbone's default
            (``efficientnet_lite0``: 128, ``alexnet_conv3``: 227, ``hog``: 64).
        batch_size: crops per forward pass.
        antialias: crop large boxes from an average-pooled image pyramid (see module doc).

    Attributes:
        raw_dim: backbone feature length before projection.
        dim: descriptor length actually produced.
        config: dict describing everything that determines the descriptors (cache key).

    Raises:
        ValueError: unknown backbone (lists valid names) or bad arguments.
        FileNotFoundError: required weights are missing (message says how to get them).
    """

    def __init__(
        self,
        backbone: str = "efficientnet_lite0",
        dim: int | None = 1024,
        seed: int = 0,
        device: str | torch.device = "cpu",
        weights: str | os.PathLike | None = None,
        input_size: int | None = None,
        batch_size: int = 50,
        antialias: bool = True,
    ) -> None:
        if backbone not in available_backbones():
            raise ValueError(
                f"unknown backbone {backbone!r}; valid names: {', '.join(available_backbones())}"
            )
        if dim is not None and int(dim) < 1:
            raise ValueError(f"dim must be a positive integer or None, got {dim}")
        if int(batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        self.backbone_name = backbone
        self.seed = int(seed)
        self.device = torch.device(device)
        self.batch_size = int(batch_size)
        self.antialias = bool(antialias)
        self.model = build_backbone(backbone, input_size=input_size, weights=weights,
                                    seed=self.seed).to(self.device)
        self.input_size = int(self.model.input_size)
        self.raw_dim = int(self.model.raw_dim)
        self.weights_source = str(self.model.weights_source)
        self._mean = torch.tensor(self.model.mean, dtype=torch.float32, device=self.device)
        self._std = torch.tensor(self.model.std, dtype=torch.float32, device=self.device)
        self.dim_requested = None if dim is None else int(dim)
        if self.dim_requested is None or self.dim_requested >= self.raw_dim:
            self.projection: torch.Tensor | None = None
            self.dim = self.raw_dim
        else:
            self.projection = random_projection(self.raw_dim, self.dim_requested, self.seed).to(
                self.device)
            self.dim = self.dim_requested
        self.config: dict[str, Any] = {
            "backbone": backbone,
            "input_size": self.input_size,
            "raw_dim": self.raw_dim,
            "feature_shape": list(getattr(self.model, "feature_shape", (self.raw_dim,))),
            "dim": self.dim,
            "projection": ("none" if self.projection is None
                           else "gaussian N(0, 1/dim), numpy default_rng(seed)"),
            "seed": self.seed,
            "weights": self.weights_source,
            "normalisation": {"mean": list(self.model.mean), "std": list(self.model.std)},
            "antialias": self.antialias,
            "version": DESCRIPTOR_VERSION,
        }
        if hasattr(self.model, "stage"):
            self.config["stage"] = int(self.model.stage)
        logger.debug("LandmarkEncoder %s", self.config)

    # ------------------------------------------------------------------ description
    def describe(self) -> dict[str, Any]:
        """A copy of :attr:`config` (backbone, input size, raw/output dim, seed, weights, ...)."""
        return dict(self.config)

    def __repr__(self) -> str:
        c = self.config
        return (f"LandmarkEncoder(backbone={c['backbone']!r}, input_size={c['input_size']}, "
                f"raw_dim={c['raw_dim']}, dim={c['dim']}, seed={c['seed']}, "
                f"weights={c['weights']!r})")

    # ------------------------------------------------------------------ crops
    def _levels(self, boxes: np.ndarray, image_size: tuple[int, int] | None = None) -> np.ndarray:
        """Pyramid level per box: largest l with sqrt(w*h) / 2**l >= input_size (0 if off).

        ``w, h`` are measured after clipping the box to ``image_size`` ``(H, W)`` when given.
        """
        if not self.antialias:
            return np.zeros(len(boxes), dtype=int)
        w, h = boxes[:, 2], boxes[:, 3]
        if image_size is not None:
            w = np.clip(boxes[:, 0] + w, 0, image_size[1]) - np.clip(boxes[:, 0], 0, image_size[1])
            h = np.clip(boxes[:, 1] + h, 0, image_size[0]) - np.clip(boxes[:, 1], 0, image_size[0])
        side = np.sqrt(np.maximum(w, 1.0) * np.maximum(h, 1.0))
        ratio = np.maximum(side / self.input_size, 1.0)
        return np.floor(np.log2(ratio)).astype(int)

    def _image_tensor(self, image: np.ndarray) -> torch.Tensor:
        x = torch.from_numpy(np.ascontiguousarray(image)).to(self.device)
        x = x.permute(2, 0, 1).unsqueeze(0).float().div_(255.0)
        return (x - self._mean[:, None, None]) / self._std[:, None, None]

    def crops(self, image: np.ndarray, boxes: np.ndarray) -> torch.Tensor:
        """Normalised crops of ``boxes``.

        Args:
            image: ``(H, W, 3)`` uint8 RGB.
            boxes: ``(K, 4)`` float ``(x, y, w, h)`` pixels.

        Returns:
            ``(K, 3, s, s)`` float32 tensor, ``s = input_size``, normalised by the backbone's
            mean/std.
        """
        image = _check_image(image)
        boxes = _check_boxes(boxes)
        s = self.input_size
        out = torch.empty((len(boxes), 3, s, s), dtype=torch.float32, device=self.device)
        if len(boxes) == 0:
            return out
        levels = self._levels(boxes, image.shape[:2])
        pyramid = [self._image_tensor(image)]
        for lvl in np.unique(levels):
            while len(pyramid) <= lvl and min(pyramid[-1].shape[-2:]) >= 2:
                pyramid.append(torch.nn.functional.avg_pool2d(pyramid[-1], 2))
            lvl_eff = min(int(lvl), len(pyramid) - 1)
            img = pyramid[lvl_eff]
            idx = np.flatnonzero(levels == lvl)
            corners = torch.from_numpy(
                boxes_to_corners(boxes[idx], tuple(img.shape[-2:]), lvl_eff)).to(self.device)
            for start in range(0, len(idx), self.batch_size):
                sl = slice(start, start + self.batch_size)
                c = corners[sl]
                out[torch.from_numpy(idx[sl]).to(self.device)] = crop_and_resize(
                    img.expand(len(c), -1, -1, -1), c, (s, s), mode="bilinear",
                    align_corners=True)
        return out

    # ------------------------------------------------------------------ encode
    def encode(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """Describe each landmark box.

        Args:
            image: ``(H, W, 3)`` uint8 RGB.
            boxes: ``(K, 4)`` float ``(x, y, w, h)`` pixels (clipped to the image when cropping).

        Returns:
            ``(K, dim)`` float32 descriptors (``(0, dim)`` for no boxes); row k describes box k
            independently of the other boxes.

        Raises:
            TypeError / ValueError: wrong image type/shape/dtype or boxes shape.
        """
        image = _check_image(image)
        boxes = _check_boxes(boxes)
        if len(boxes) == 0:
            return np.zeros((0, self.dim), dtype=np.float32)
        outs = []
        with torch.inference_mode():
            crops = self.crops(image, boxes)
            for start in range(0, len(boxes), self.batch_size):
                chunk = crops[start:start + self.batch_size]
                feats = self._forward_fixed(chunk, keep_padding=True)
                if self.projection is not None:
                    feats = feats @ self.projection
                outs.append(feats[:len(chunk)].cpu())
        return torch.cat(outs).numpy().astype(np.float32, copy=False)

    def _forward_fixed(self, batch: torch.Tensor, keep_padding: bool = False) -> torch.Tensor:
        """Backbone on a batch padded to ``batch_size`` rows (repeating the last crop).

        CPU kernels (convolutions, and the projection matmul, which becomes a matrix-vector
        product for one row) are chosen by shape, and some shapes give results that differ in
        the 4th decimal; a fixed batch shape makes every descriptor independent of how the
        boxes were grouped (cached resumes, subsets), so the same command gives the same
        numbers. ``(B, C, S, S)`` -> ``(B, raw_dim)`` float32 (``(batch_size, raw_dim)`` with
        ``keep_padding``, the padding rows last).
        """
        n = batch.shape[0]
        if n < self.batch_size:
            pad = batch[-1:].expand(self.batch_size - n, *batch.shape[1:])
            batch = torch.cat([batch, pad])
        out = self.model(batch).float()
        return out if keep_padding else out[:n]

    def encode_raw(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """Backbone features before projection: ``(K, raw_dim)`` float32."""
        image = _check_image(image)
        boxes = _check_boxes(boxes)
        if len(boxes) == 0:
            return np.zeros((0, self.raw_dim), dtype=np.float32)
        with torch.inference_mode():
            crops = self.crops(image, boxes)
            feats = [self._forward_fixed(crops[i:i + self.batch_size]).cpu()
                     for i in range(0, len(boxes), self.batch_size)]
        return torch.cat(feats).numpy()


def default_input_size(backbone: str) -> int:
    """Default crop side of ``backbone``."""
    if backbone not in DEFAULT_INPUT_SIZE:
        raise ValueError(
            f"unknown backbone {backbone!r}; valid names: {', '.join(available_backbones())}"
        )
    return DEFAULT_INPUT_SIZE[backbone]
