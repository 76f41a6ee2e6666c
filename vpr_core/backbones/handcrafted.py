"""Handcrafted (non-CNN) landmark descriptors: a scikit-image HOG baseline."""

from __future__ import annotations

import numpy as np
import torch
from skimage.feature import hog
from torch import nn

__all__ = ["HOGBackbone"]


class HOGBackbone(nn.Module):
    """Histogram of oriented gradients on grayscale crops (the registry's default 64x64).

    9 orientations, 8x8-pixel cells, 2x2-cell blocks, L2-Hys block normalisation: at 64x64 the
    descriptor is 7*7*2*2*9 = 1,764-d. A cheap, training-free baseline for the CNN descriptors.
    ``weights_sha256``: ``"none"``; ``weights_source``: ``"none (handcrafted)"``.

    ``forward``: ``(B, 3, s, s)`` RGB crops in [0, 1] (``mean=0``, ``std=1``: no normalisation)
    -> ``(B, D)`` float32 on the batch's device (HOG itself runs on the CPU). No
    ``feature_map``: the ``roi`` pooling mode does not apply to it.
    """

    mean = (0.0, 0.0, 0.0)
    std = (1.0, 1.0, 1.0)
    weights_sha256 = "none"
    weights_source = "none (handcrafted)"

    def __init__(
        self, orientations: int = 9, pixels_per_cell: int = 8, cells_per_block: int = 2
    ) -> None:
        super().__init__()
        self.hog_params = {
            "orientations": orientations,
            "pixels_per_cell": (pixels_per_cell, pixels_per_cell),
            "cells_per_block": (cells_per_block, cells_per_block),
            "block_norm": "L2-Hys",
            "feature_vector": True,
        }

    def forward(self, batch: torch.Tensor) -> torch.Tensor:
        w = torch.tensor([0.299, 0.587, 0.114], dtype=batch.dtype, device=batch.device)
        gray = (batch * w[None, :, None, None]).sum(1).cpu().numpy().astype(np.float64)
        feats = np.stack([hog(g, **self.hog_params) for g in gray])
        return torch.from_numpy(feats.astype(np.float32)).to(batch.device)
