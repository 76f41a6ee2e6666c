"""The ``crop`` pooling mode: each box cropped and resized to the backbone's square input (kornia
``crop_and_resize``, bilinear, ``align_corners=True``); large boxes come from a 2x/4x/... average-
pooled pyramid so the resize never shrinks by 2x or more (anti-aliasing; ``antialias=False``)."""

from __future__ import annotations

import numpy as np
import torch
from kornia.geometry.transform import crop_and_resize

__all__ = ["crop_boxes", "pyramid_levels"]


def _boxes_to_corners(boxes: np.ndarray, image_size: tuple[int, int], level: int = 0) -> np.ndarray:
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
        [
            np.stack([x1, y1], 1),
            np.stack([x2, y1], 1),
            np.stack([x2, y2], 1),
            np.stack([x1, y2], 1),
        ],
        axis=1,
    )
    return pts.astype(np.float32)


def pyramid_levels(
    boxes: np.ndarray,
    input_size: int,
    image_size: tuple[int, int] | None = None,
    antialias: bool = True,
) -> np.ndarray:
    """Pyramid level per box: largest l with sqrt(w*h) / 2**l >= input_size (0 if off).

    Args:
        boxes: ``(K, 4)`` boxes.
        input_size: the crop side.
        image_size: ``(H, W)``; when given, ``w, h`` are measured after clipping to the image.
        antialias: False -> every box at level 0.

    Returns:
        ``(K,)`` int levels.
    """
    if not antialias:
        return np.zeros(len(boxes), dtype=int)
    w, h = boxes[:, 2], boxes[:, 3]
    if image_size is not None:
        w = np.clip(boxes[:, 0] + w, 0, image_size[1]) - np.clip(boxes[:, 0], 0, image_size[1])
        h = np.clip(boxes[:, 1] + h, 0, image_size[0]) - np.clip(boxes[:, 1], 0, image_size[0])
    side = np.sqrt(np.maximum(w, 1.0) * np.maximum(h, 1.0))
    ratio = np.maximum(side / input_size, 1.0)
    return np.floor(np.log2(ratio)).astype(int)


def crop_boxes(
    image: torch.Tensor, boxes: np.ndarray, size: int, batch_size: int, antialias: bool = True
) -> torch.Tensor:
    """Crop and resize every box of a normalised image.

    Args:
        image: ``(1, 3, H, W)`` float32 normalised image (on the encoder's device).
        boxes: ``(K, 4)`` float64 ``(x, y, w, h)`` pixels (validated).
        size: square output side.
        batch_size: crops per ``crop_and_resize`` call.
        antialias: crop large boxes from the average-pooled pyramid.

    Returns:
        ``(K, 3, size, size)`` float32 on ``image.device``.
    """
    device = image.device
    out = torch.empty((len(boxes), 3, size, size), dtype=torch.float32, device=device)
    if len(boxes) == 0:
        return out
    levels = pyramid_levels(boxes, size, (int(image.shape[-2]), int(image.shape[-1])), antialias)
    pyramid = [image]
    for lvl in np.unique(levels):
        while len(pyramid) <= lvl and min(pyramid[-1].shape[-2:]) >= 2:
            pyramid.append(torch.nn.functional.avg_pool2d(pyramid[-1], 2))
        lvl_eff = min(int(lvl), len(pyramid) - 1)
        img = pyramid[lvl_eff]
        idx = np.flatnonzero(levels == lvl)
        corners = torch.from_numpy(
            _boxes_to_corners(boxes[idx], (int(img.shape[-2]), int(img.shape[-1])), lvl_eff)
        ).to(device)
        for start in range(0, len(idx), batch_size):
            sl = slice(start, start + batch_size)
            c = corners[sl]
            out[torch.from_numpy(idx[sl]).to(device)] = crop_and_resize(
                img.expand(len(c), -1, -1, -1), c, (size, size), mode="bilinear", align_corners=True
            )
    return out
