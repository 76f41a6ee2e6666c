"""CPU-independent image arithmetic for the generator (the same pixels on every machine): only
correctly rounded elementwise float64 ops, exact integer sums, pure-Python homographies and
grid-rounded transcendentals; no OpenCV resize, warp or blur (why: docs/SYNTHETIC.md)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "GRID_BITS",
    "Matrix3",
    "gaussian_blur",
    "mat3_mul",
    "normal",
    "normalise_h",
    "resize_area",
    "resize_bilinear",
    "solve_homography",
    "to_grid",
    "to_uint8",
    "warp_perspective",
]

Matrix3 = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]

#: Grid of :func:`to_grid` (``2**-GRID_BITS``).
GRID_BITS = 24


def to_grid(x, bits: int = GRID_BITS):
    """Round a float (or float64 array) to the binary grid ``2**-bits`` (exact, elementwise)."""
    s = float(2**bits)
    if isinstance(x, np.ndarray):
        return np.round(x * s) / s
    return round(float(x) * s) / s


def normal(rng: np.random.Generator, loc=0.0, scale=1.0, size=None):
    """``loc + scale * z``, standard normals ``z`` rounded to the grid (float or float64 array)."""
    z = to_grid(rng.standard_normal(size))
    if size is None:
        return float(loc + scale * z)
    return np.asarray(loc, np.float64) + np.asarray(scale, np.float64) * z


def _reflect101(idx: np.ndarray, n: int) -> np.ndarray:
    """Indices reflected into ``[0, n)`` without repeating the edge (OpenCV's BORDER_REFLECT101)."""
    if n == 1:
        return np.zeros_like(idx)
    period = 2 * (n - 1)
    idx = np.abs(idx) % period
    return np.where(idx >= n, period - idx, idx)


def _sample_bilinear(src: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``src (H, W[, C])`` at float64 coordinates ``(h, w)`` (_reflect101)."""
    hs, ws = src.shape[:2]
    x0, y0 = np.floor(xs), np.floor(ys)
    fx, fy = xs - x0, ys - y0
    x0i, y0i = x0.astype(np.int64), y0.astype(np.int64)
    xa, xb = _reflect101(x0i, ws), _reflect101(x0i + 1, ws)
    ya, yb = _reflect101(y0i, hs), _reflect101(y0i + 1, hs)
    if src.ndim == 3:
        fx, fy = fx[..., None], fy[..., None]
    p00 = src[ya, xa].astype(np.float64)
    p01 = src[ya, xb].astype(np.float64)
    p10 = src[yb, xa].astype(np.float64)
    p11 = src[yb, xb].astype(np.float64)
    top = p00 + (p01 - p00) * fx
    bot = p10 + (p11 - p10) * fx
    return top + (bot - top) * fy


def warp_perspective(src: np.ndarray, dst_to_src: Matrix3, size: tuple[int, int]) -> np.ndarray:
    """Inverse-mapped perspective warp with bilinear interpolation and _reflect101 borders.

    Args:
        src: ``(Hs, Ws)`` or ``(Hs, Ws, C)`` image (any real dtype).
        dst_to_src: Homography taking output pixel ``(x, y, 1)`` to source coordinates (pixel
            centres at integers, as in OpenCV).
        size: ``(H, W)`` of the output.

    Returns:
        ``float64 (H, W[, C])``.
    """
    h, w = size
    (a, b, c), (d, e, f), (g, k, m) = dst_to_src
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    den = g * xs + k * ys + m
    return _sample_bilinear(src, (a * xs + b * ys + c) / den, (d * xs + e * ys + f) / den)


def resize_bilinear(src: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Bilinear resize with half-pixel centres (edge-clamped): ``float64 (H, W[, C])``."""
    h, w = size
    hs, ws = src.shape[:2]
    ys = np.clip((np.arange(h, dtype=np.float64) + 0.5) * (hs / h) - 0.5, 0, hs - 1)
    xs = np.clip((np.arange(w, dtype=np.float64) + 0.5) * (ws / w) - 0.5, 0, ws - 1)
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    return _sample_bilinear(src, xx, yy)


def resize_area(src: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Box-average resize of an integer image (integer sums: exact): ``float64 (H, W[, C])``.

    Output pixel ``j`` averages source pixels ``floor(j * s) .. floor((j + 1) * s) - 1`` with
    ``s = source / output`` size (at least one pixel: nearest-neighbour when enlarging).
    """
    assert np.issubdtype(src.dtype, np.integer), f"resize_area needs an integer image: {src.dtype}"
    h, w = size
    hs, ws = src.shape[:2]

    def bounds(n_out: int, n_src: int) -> tuple[np.ndarray, np.ndarray]:
        j = np.arange(n_out + 1, dtype=np.int64)
        edges = (j * n_src) // n_out
        lo, hi = edges[:-1], np.maximum(edges[1:], edges[:-1] + 1)
        return np.minimum(lo, n_src - 1), np.minimum(hi, n_src)

    y0, y1 = bounds(h, hs)
    x0, x1 = bounds(w, ws)
    ii = np.zeros((hs + 1, ws + 1) + src.shape[2:], np.int64)
    ii[1:, 1:] = src.astype(np.int64).cumsum(0).cumsum(1)
    s = ii[y1][:, x1] - ii[y0][:, x1] - ii[y1][:, x0] + ii[y0][:, x0]
    count = ((y1 - y0)[:, None] * (x1 - x0)[None, :]).astype(np.float64)
    if src.ndim == 3:
        count = count[..., None]
    return s.astype(np.float64) / count


def _gaussian_kernel(sigma: float) -> list[float]:
    """Half of a normalised 1-D Gaussian (taps ``0..r``, ``r = ceil(3 sigma)``), grid-rounded."""
    r = max(1, math.ceil(3.0 * sigma))
    raw = [to_grid(math.exp(-0.5 * (k / sigma) ** 2)) for k in range(r + 1)]
    total = raw[0] + 2.0 * sum(raw[1:])  # Python floats, fixed order
    return [v / total for v in raw]


def gaussian_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur in float64 with _reflect101 borders: same shape, ``float64``."""
    if sigma <= 0:
        return img.astype(np.float64)
    kern = _gaussian_kernel(float(sigma))
    out = img.astype(np.float64)
    for axis in (0, 1):
        n = out.shape[axis]
        r = len(kern) - 1
        idx = _reflect101(np.arange(-r, n + r), n)
        pad = np.take(out, idx, axis=axis)

        def tap(o: int, pad=pad, axis=axis, n=n) -> np.ndarray:
            return np.take(pad, np.arange(o, o + n), axis=axis)

        acc = kern[0] * tap(r)
        for k in range(1, r + 1):
            acc = acc + kern[k] * (tap(r - k) + tap(r + k))
        out = acc
    return out


def to_uint8(a: np.ndarray) -> np.ndarray:
    """``[0, 1]`` float64 -> ``uint8`` by ``floor(255 a + 0.5)`` after clipping (exact)."""
    return np.floor(np.clip(a, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


# ------------------------------------------------------------------------------------------
# 3x3 homographies in pure Python floats
# ------------------------------------------------------------------------------------------


def solve_homography(src: Sequence[Sequence[float]], dst: Sequence[Sequence[float]]) -> Matrix3:
    """Homography ``H`` (``H[2][2] = 1``) with ``H @ [src_i, 1] ~ [dst_i, 1]`` for 4 point pairs.

    Gauss-Jordan elimination with partial pivoting on the 8x8 system, in Python floats.
    """
    rows: list[list[float]] = []
    for (x, y), (u, v) in zip(src, dst, strict=False):
        x, y, u, v = float(x), float(y), float(u), float(v)
        rows.append([x, y, 1.0, 0.0, 0.0, 0.0, -x * u, -y * u, u])
        rows.append([0.0, 0.0, 0.0, x, y, 1.0, -x * v, -y * v, v])
    n = 8
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(rows[r][col]))
        assert abs(rows[piv][col]) >= 1e-12, "degenerate point configuration: no homography"
        rows[col], rows[piv] = rows[piv], rows[col]
        p = rows[col][col]
        rows[col] = [v / p for v in rows[col]]
        for r in range(n):
            if r != col and rows[r][col] != 0.0:
                f = rows[r][col]
                rows[r] = [a - f * b for a, b in zip(rows[r], rows[col], strict=False)]
    h = [rows[r][8] for r in range(n)]
    return ((h[0], h[1], h[2]), (h[3], h[4], h[5]), (h[6], h[7], 1.0))


def mat3_mul(a: Matrix3, b: Matrix3) -> Matrix3:
    """``a @ b`` in Python floats (fixed summation order)."""
    return tuple(
        tuple(a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] for j in range(3))
        for i in range(3)
    )  # type: ignore[return-value]


def normalise_h(m: Matrix3) -> np.ndarray:
    """``m / m[2][2]`` as ``float64 (3, 3)``."""
    s = m[2][2]
    return np.array([[v / s for v in row] for row in m], np.float64)
