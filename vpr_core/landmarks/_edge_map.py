"""The gradient edge map Edge Boxes groups when no structured-edge model is given: Scharr
magnitude of the blurred grayscale image, robustly normalised and thinned, filtered in float64
by NumPy so that every CPU gives the same bits (docs/SYNTHETIC.md)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

__all__ = ["gradient_edges"]


def _edge_nms(mag: np.ndarray, orient: np.ndarray) -> np.ndarray:
    """Zero every pixel of ``mag (H, W)`` that is not a maximum along its edge normal."""
    q = np.rint(orient / (np.pi / 4)).astype(np.int64) % 4
    H, W = mag.shape
    pad = np.pad(mag, 1)

    def shifted(dy: int, dx: int) -> np.ndarray:
        return pad[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W]

    # neighbours along the edge normal for angle bins 0, 45, 90, 135 degrees
    neighbours = (((0, 1), (0, -1)), ((1, 1), (-1, -1)), ((1, 0), (-1, 0)), ((1, -1), (-1, 1)))
    keep = np.zeros(mag.shape, dtype=bool)
    for k, (a, b) in enumerate(neighbours):
        keep |= (q == k) & (mag >= shifted(*a)) & (mag >= shifted(*b))
    return np.where(keep, mag, 0.0)


#: Scharr's derivative and smoothing taps (``cv2.Scharr``'s kernel, separated).
SCHARR_DIFF = (-1.0, 0.0, 1.0)
SCHARR_SMOOTH = (3.0, 10.0, 3.0)


def _gaussian_taps(sigma: float) -> tuple[float, ...]:
    """Normalised Gaussian taps, ``cv2.GaussianBlur``'s size for float images (8 sigma + 1,
    odd), from scalar ``math.exp`` (no SIMD variant)."""
    half = int(round(sigma * 4 * 2 + 1)) // 2
    w = [math.exp(-0.5 * (i / sigma) ** 2) for i in range(-half, half + 1)]
    total = math.fsum(w)
    return tuple(x / total for x in w)


def _correlate(a: np.ndarray, taps: Sequence[float], axis: int) -> np.ndarray:
    """``a`` (float64) correlated with ``taps`` along ``axis``, OpenCV's default border
    (reflect-101), summed tap by tap in a fixed order: the same bits on every CPU, where
    OpenCV's float filters differ in the last bit between its SIMD paths (and so did the
    Edge Boxes proposals from one machine to another)."""
    half = len(taps) // 2
    widths = [(0, 0), (0, 0)]
    widths[axis] = (half, half)
    pad = np.pad(a, widths, mode="reflect")
    n = a.shape[axis]
    out = np.zeros_like(a)
    for k, w in enumerate(taps):
        if w:
            out += w * (pad[k : k + n] if axis == 0 else pad[:, k : k + n])
    return out


def gradient_edges(
    image: np.ndarray, blur_sigma: float = 2.0, nms: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Gradient edge map in ``[0, 1]`` and edge orientation map, both ``(H, W)`` float32.

    Scharr gradient magnitude of the lightly blurred grayscale image (float64, filtered by
    :func:`_correlate`: identical on every CPU), divided by a robust
    maximum (99th percentile of the non-flat pixels) and clipped to ``[0, 1]``; optionally thinned
    by non-maximum suppression across the edge. The orientation is the gradient (edge-normal)
    direction modulo pi, the convention of ``StructuredEdgeDetection.computeOrientation``.
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    g: np.ndarray = gray.astype(np.float64) / 255.0
    if blur_sigma and blur_sigma > 0:
        taps = _gaussian_taps(float(blur_sigma))
        g = _correlate(_correlate(g, taps, 1), taps, 0)
    gx = _correlate(_correlate(g, SCHARR_DIFF, 1), SCHARR_SMOOTH, 0)
    gy = _correlate(_correlate(g, SCHARR_SMOOTH, 1), SCHARR_DIFF, 0)
    mag = np.sqrt(gx * gx + gy * gy)
    peak = float(mag.max())
    if peak <= 0:
        flat = np.zeros(mag.shape, dtype=np.float32)
        return flat, flat.copy()
    active = mag[mag > 0.01 * peak]
    scale = float(np.percentile(active, 99)) if active.size else peak
    mag = np.clip(mag / max(scale, 1e-12), 0.0, 1.0)
    orient = np.mod(np.arctan2(gy, gx), np.pi).astype(np.float32)
    if nms:
        mag = _edge_nms(mag, orient)
    return mag.astype(np.float32), orient
