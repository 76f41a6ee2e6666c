"""The ``roi`` pooling mode: one backbone pass per image, landmark regions pooled from its map.

1. **Working size.** The normalised image is resized (bilinear, antialiased) so that its long side
   is ``working_size`` pixels (default :data:`DEFAULT_WORKING_SIZE` = 512; aspect kept, short
   side rounded). At 512 a 640x360 frame becomes 512x288 and the stride-16 feature map 32x18
   cells, so a Table-1 Scale-4 landmark (~0.1 of the image area) is about 10x6 cells and the
   smallest dense box (area 0.16) about 13x7: a few cells wide, like the 8x8 cells that ``crop``
   mode gives every box. Every image, whatever its size, is processed at the same working size,
   so the backbone sees the same scale for the same normalised box.
2. **Bilinear RoIAlign** (``torch.nn.functional.grid_sample``, ``align_corners=False``): each box
   gives an ``n x n`` grid, ``n`` = the side of ``crop`` mode's feature map for that backbone and
   crop size (8 for Lite0 stage 5 at 128 px). Sample ``(i, j)`` is placed where cell ``(i, j)`` of
   the crop-mode feature map is centred once the crop is mapped back onto the image (same corner
   clipping and ``align_corners=True`` geometry as ``crop``, and the backbone's
   ``feature_offset``: TF "same" padding centres cell ``i`` at ``stride * i + stride - 0.5``).
   Each output cell averages ``sampling x sampling`` bilinear samples spread over the cell's
   ``stride x stride`` crop pixels (default 4 x 4), as RoIAlign does.
3. The ``(K, C, n, n)`` result is flattened in ``crop`` mode's order and projected with the same
   matrix, so both modes give descriptors of the same dimension in the same space.

Determinism: the feature map depends only on the image; each box's sample points start at a
multiple of 16 in the sampling grid (padded), so a box's descriptor does not depend on which other
boxes are encoded with it.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F

__all__ = ["DEFAULT_ROI_SAMPLING", "DEFAULT_WORKING_SIZE", "roi_pool", "roi_sample_points",
           "working_image"]

#: Long side of the image fed to the backbone in ``roi`` mode, pixels.
DEFAULT_WORKING_SIZE = 512
#: Bilinear samples per output cell and axis (RoIAlign's sampling ratio).
DEFAULT_ROI_SAMPLING = 4
_ALIGN = 16  # sample points per box padded to a multiple of this (vector lanes)


def working_shape(image_size: tuple[int, int], working_size: int) -> tuple[int, int]:
    """``(H, W)`` -> ``(Hw, Ww)`` with ``max(Hw, Ww) == working_size``, aspect kept."""
    h, w = image_size
    f = working_size / max(h, w)
    return max(1, round(h * f)), max(1, round(w * f))


def working_image(image: torch.Tensor, working_size: int) -> torch.Tensor:
    """Resize a ``(1, 3, H, W)`` image to the working size (bilinear, antialiased when shrinking).

    Returns:
        ``(1, 3, Hw, Ww)`` float32, see :func:`working_shape`.
    """
    hw, ww = working_shape(tuple(image.shape[-2:]), working_size)
    if (hw, ww) == tuple(image.shape[-2:]):
        return image
    return F.interpolate(image, size=(hw, ww), mode="bilinear", align_corners=False,
                         antialias=True)


def roi_sample_points(boxes: np.ndarray, image_size: tuple[int, int], crop_size: int,
                      side: int, stride: int, offset: float, sampling: int) -> np.ndarray:
    """Image pixel coordinates (index convention) of every RoIAlign sample of every box.

    Args:
        boxes: ``(K, 4)`` float64 ``(x, y, w, h)`` in image pixels.
        image_size: ``(H, W)`` of the image.
        crop_size: ``crop`` mode's square input side ``s``.
        side: ``n``, the crop-mode feature map side.
        stride: the backbone's output stride.
        offset: the backbone's ``feature_offset`` (continuous coordinate of cell 0's centre).
        sampling: samples per cell and axis ``r``.

    Returns:
        ``(2, K, n*r)`` float64: ``[0]`` x positions along the box width, ``[1]`` y positions
        along its height; entry ``j * r + t`` is sub-sample ``t`` of cell ``j``.
    """
    h_img, w_img = image_size
    x1 = np.clip(boxes[:, 0], 0, w_img - 1)
    y1 = np.clip(boxes[:, 1], 0, h_img - 1)
    x2 = np.clip(np.maximum(boxes[:, 0] + boxes[:, 2] - 1.0, x1), 0, w_img - 1)
    y2 = np.clip(np.maximum(boxes[:, 1] + boxes[:, 3] - 1.0, y1), 0, h_img - 1)
    j = np.arange(side)[:, None]
    t = np.arange(sampling)[None, :]
    # crop-pixel index of each sample: cell centre, spread over the cell's stride pixels
    c = (stride * j + offset - 0.5 + ((t + 0.5) / sampling - 0.5) * stride).reshape(-1)
    scale = 1.0 / max(crop_size - 1, 1)
    xs = x1[:, None] + c[None, :] * ((x2 - x1) * scale)[:, None]
    ys = y1[:, None] + c[None, :] * ((y2 - y1) * scale)[:, None]
    return np.stack([xs, ys])


def roi_pool(fmap: torch.Tensor, boxes: np.ndarray, image_size: tuple[int, int],
             work_size: tuple[int, int], crop_size: int, stride: int, offset: float,
             sampling: int = DEFAULT_ROI_SAMPLING) -> torch.Tensor:
    """Pool every box from a feature map to crop mode's ``(C, n, n)`` layout, flattened.

    Args:
        fmap: ``(1, C, hf, wf)`` backbone feature map of the working-size image.
        boxes: ``(K, 4)`` float64 boxes in pixels of the *original* image.
        image_size: ``(H, W)`` of the original image.
        work_size: ``(Hw, Ww)`` of the working-size image that produced ``fmap``.
        crop_size: crop mode's square input side ``s``; ``n = ceil(s / stride)``.
        stride, offset: the backbone's ``stride`` and ``feature_offset``.
        sampling: bilinear samples per output cell and axis.

    Returns:
        ``(K, C * n * n)`` float32 on ``fmap.device`` (order ``C, y, x`` like ``crop`` mode).
    """
    n = math.ceil(crop_size / stride)
    k, r = len(boxes), int(sampling)
    hf, wf = fmap.shape[-2:]
    pts = roi_sample_points(boxes, image_size, crop_size, n, stride, offset, r)
    # image index -> working-image continuous coordinate -> feature index -> grid_sample [-1, 1]
    fx = work_size[1] / image_size[1]
    fy = work_size[0] / image_size[0]
    qx = ((pts[0] + 0.5) * fx - offset) / stride
    qy = ((pts[1] + 0.5) * fy - offset) / stride
    gx = (2.0 * qx + 1.0) / wf - 1.0  # (K, n*r)
    gy = (2.0 * qy + 1.0) / hf - 1.0
    # grid (1, r*r, K * P, 2): row = sub-sample (ty, tx), column = (box, cell y, cell x)
    gx = gx.reshape(k, 1, n, 1, r)  # box, -, cell x, -, tx
    gy = gy.reshape(k, n, 1, r, 1)  # box, cell y, -, ty, -
    grid = np.stack(np.broadcast_arrays(gx, gy), axis=-1)  # (K, n, n, r, r, 2)
    grid = grid.transpose(3, 4, 0, 1, 2, 5).reshape(r * r, k, n * n, 2)
    pad = -(n * n) % _ALIGN
    if pad:
        grid = np.concatenate([grid, np.zeros((r * r, k, pad, 2))], axis=2)
    p = n * n + pad
    g = torch.from_numpy(grid.reshape(1, r * r, k * p, 2).astype(np.float32)).to(fmap.device)
    samples = F.grid_sample(fmap.float().contiguous(), g, mode="bilinear",
                            padding_mode="border", align_corners=False)[0]  # (C, r*r, K*P)
    acc = samples[:, 0]
    for i in range(1, r * r):  # fixed summation order: grouping-independent
        acc = acc + samples[:, i]
    acc = acc * (1.0 / (r * r))
    c = acc.shape[0]
    out = acc.reshape(c, k, p)[:, :, : n * n].permute(1, 0, 2)  # (K, C, n*n)
    return out.reshape(k, c * n * n).contiguous()
