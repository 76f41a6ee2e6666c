"""(Not in the paper.) Whitening of the landmark descriptors on the reference database,
``whiten=k``: the fit (reference landmarks only, kept in memory by content) and the transform of
both sides before Eq. (1); definitions in docs/DEFINITIONS.md, "(not in the paper) whitening"."""

from __future__ import annotations

import dataclasses
import hashlib
import threading
from collections import OrderedDict
from collections.abc import Iterator, Sequence

import numpy as np

from ..checks import check_int
from ..notices import notice
from .spec import Matching

__all__ = [
    "DESCRIPTOR_STEPS",
    "WHITEN_BLOCK_ROWS",
    "WHITEN_CACHE_SIZE",
    "WHITEN_FLOOR",
    "WHITEN_K",
    "Whitening",
    "clear_whitening_cache",
    "fit_whitening",
    "refuse_whiten",
    "score_sign_notice",
    "whiten_descriptors",
    "whiten_landmarks",
    "whitening_cache_keys",
    "whitening_key",
]

#: (Not in the paper.) The components of the recipe (issue 62), fixed before any result; the
#: CLI's ``--whiten both`` compares it with no whitening.
WHITEN_K = 256
#: (Not in the paper.) A component is kept only when its eigenvalue is above this share of the
#: largest one (docs/DEFINITIONS.md).
WHITEN_FLOOR = 1e-6
#: Databases whose fit is kept in memory (keyed by content, least recently used dropped first).
WHITEN_CACHE_SIZE = 4
#: Landmarks per block of the fit and the transform: a block's float64 copy is ~64 MB at 1,024-d.
WHITEN_BLOCK_ROWS = 8192

_CACHE: OrderedDict[str, Whitening] = OrderedDict()
_CACHE_LOCK = threading.Lock()


@dataclasses.dataclass(frozen=True, eq=False)
class Whitening:
    """A fit on one reference database: ``x -> L2((L2(x) - mean) @ projection)``.

    Attributes:
        mean: ``(D,)`` float64, the mean of the L2-normalised reference landmarks.
        projection: ``(D, k')`` float64, ``U_k' diag(lambda_k'^-1/2)``.
        eigenvalues: ``(k',)`` float64, descending: the kept components' variances.
        k: the components asked for; ``k' = projection.shape[1] <= k``.
        landmarks: the reference landmarks fitted (``n``).
        key: the content key (:func:`whitening_key`).
    """

    mean: np.ndarray
    projection: np.ndarray
    eigenvalues: np.ndarray
    k: int
    landmarks: int
    key: str

    @property
    def kept(self) -> int:
        """``k'``: the components kept (above :data:`WHITEN_FLOOR`, at most ``k`` and ``D``)."""
        return int(self.projection.shape[1])

    def shortfall(self) -> str | None:
        """The sentence a run carries when fewer than ``k`` components were kept, else None."""
        if self.kept >= self.k:
            return None
        dim = self.mean.shape[0]
        return (
            f"whiten={self.k} kept {self.kept} components ({self.landmarks} reference "
            f"landmarks, {dim}-d descriptors, eigenvalues above {WHITEN_FLOOR:g} of the "
            f"largest): the descriptors were whitened in {self.kept} dimensions, not {self.k} "
            "(docs/DEFINITIONS.md, whitening)"
        )


def _unit(x: np.ndarray) -> np.ndarray:
    """``(n, D)`` rows as float64 unit vectors; a zero row stays 0."""
    x = np.asarray(x, dtype=np.float64)
    norm = np.linalg.norm(x, axis=1, keepdims=True)
    return np.divide(x, norm, out=np.zeros_like(x), where=norm > 0)


def _blocks(desc: Sequence[np.ndarray], rows: int) -> Iterator[tuple[int, int, np.ndarray | None]]:
    """``(first image, end image, (m, D) rows or None)``: consecutive images' landmarks, about
    ``rows`` at a time (one image is never split; None: those images have no landmark)."""
    i, n = 0, len(desc)
    while i < n:
        j, m = i, 0
        while j < n and (m == 0 or m + len(desc[j]) <= rows):
            m += len(desc[j])
            j += 1
        parts = [np.asarray(d) for d in desc[i:j] if len(d)]
        yield i, j, np.concatenate(parts) if parts else None
        i = j


def whitening_key(reference_desc: Sequence[np.ndarray], k: int) -> str:
    """Content key of a fit: sha256 of every reference's descriptors (dtype, shape, bytes, in
    order), ``k`` and :data:`WHITEN_FLOOR`."""
    h = hashlib.sha256(f"whiten k={k} floor={WHITEN_FLOOR!r}|".encode())
    for d in reference_desc:
        a = np.ascontiguousarray(d)
        h.update(f"{a.dtype.str}{a.shape}|".encode())
        h.update(a.reshape(-1).view(np.uint8).data)
    return h.hexdigest()


def _fit(reference_desc: Sequence[np.ndarray], k: int, key: str) -> Whitening:
    """The fit of docs/DEFINITIONS.md: two passes over blocks of reference landmarks."""
    n, total = 0, None
    for _, _, x in _blocks(reference_desc, WHITEN_BLOCK_ROWS):
        if x is None:
            continue
        u = _unit(x)
        total = u.sum(0) if total is None else total + u.sum(0)
        n += u.shape[0]
    if total is None or n < 2:
        raise ValueError(
            f"whiten={k}: the reference database has {n} landmark(s); whitening needs at least "
            "two distinct reference landmarks (docs/DEFINITIONS.md)"
        )
    mean = total / n
    gram = np.zeros((mean.shape[0], mean.shape[0]), dtype=np.float64)
    for _, _, x in _blocks(reference_desc, WHITEN_BLOCK_ROWS):
        if x is None:
            continue
        c = _unit(x) - mean
        gram += c.T @ c
    lam, vec = np.linalg.eigh(gram / n)  # ascending
    lam, vec = lam[::-1], vec[:, ::-1]
    keep = int(np.count_nonzero(lam[:k] > WHITEN_FLOOR * lam[0])) if lam[0] > 0 else 0
    if keep == 0:
        raise ValueError(
            f"whiten={k}: the reference landmarks' covariance has no component above "
            f"{WHITEN_FLOOR:g} of its largest eigenvalue (all {n} reference landmarks alike): "
            "nothing to whiten on (docs/DEFINITIONS.md)"
        )
    lam_k = lam[:keep].copy()
    proj = np.ascontiguousarray(vec[:, :keep] / np.sqrt(lam_k)[None, :])
    return Whitening(mean, proj, lam_k, k, n, key)


def fit_whitening(reference_desc: Sequence[np.ndarray], k: int = WHITEN_K) -> Whitening:
    """The whitening fit on the reference database (docs/DEFINITIONS.md): mean and population
    covariance (float64) of the L2-normalised reference landmarks, the components above
    :data:`WHITEN_FLOOR` among the top ``k``; computed once per content (:func:`whitening_key`,
    :data:`WHITEN_CACHE_SIZE` kept in memory). Queries never enter it.

    Args:
        reference_desc: sequence of ``(K_r, D)`` arrays, one per reference image (``K_r`` may
            be 0).
        k: the components asked for (>= 1).

    Raises:
        ValueError: ``k`` not an int >= 1; fewer than two reference landmarks, or none of their
            components above the floor.
    """
    k = check_int(k, "whiten (components kept)", 1)
    key = whitening_key(reference_desc, k)
    with _CACHE_LOCK:
        hit = _CACHE.get(key)
        if hit is not None:
            _CACHE.move_to_end(key)
            return hit
    fit = _fit(reference_desc, k, key)
    with _CACHE_LOCK:
        _CACHE[key] = fit
        while len(_CACHE) > WHITEN_CACHE_SIZE:
            _CACHE.popitem(last=False)
    return fit


def whiten_descriptors(desc: Sequence[np.ndarray], fit: Whitening) -> list[np.ndarray]:
    """Each image's landmarks ``(K_i, D)`` -> ``(K_i, k')`` float32 ``L2((L2(x) - mean) P)``
    (float64 inside, in blocks of :data:`WHITEN_BLOCK_ROWS` landmarks; a zero result stays 0)."""
    dim = fit.mean.shape[0]
    out: list[np.ndarray] = []
    for i, j, x in _blocks(desc, WHITEN_BLOCK_ROWS):
        if x is None:
            out += [np.zeros((0, fit.kept), dtype=np.float32) for _ in range(i, j)]
            continue
        if x.ndim != 2 or x.shape[1] != dim:
            raise ValueError(
                f"whiten: descriptors of shape {x.shape[1:]} but the fit is {dim}-d; whiten "
                "descriptors of the same encoder as the reference database"
            )
        w = _unit((_unit(x) - fit.mean) @ fit.projection).astype(np.float32)
        out += np.split(w, np.cumsum([len(d) for d in desc[i:j]])[:-1])
    return out


def whiten_landmarks(
    query_desc: Sequence[np.ndarray], reference_desc: Sequence[np.ndarray], k: int
) -> tuple[list[np.ndarray], list[np.ndarray], Whitening]:
    """(Not in the paper.) Both sides' landmark descriptors whitened on the reference database,
    the one step ``whiten=k`` adds before Eq. (1) (docs/DEFINITIONS.md).

    Args:
        query_desc: ``[(K_q, D)]`` per query image; transformed only, never fitted.
        reference_desc: ``[(K_r, D)]`` per reference image; the fit's data.
        k: the components asked for (:data:`WHITEN_K` is the recipe's).

    Returns:
        ``(query [(K_q, k')], reference [(K_r, k')], fit)`` float32; when ``k' < k`` a
        :class:`~vpr_core.notices.VPRWarning` says so (it changes what the numbers mean).
    """
    fit = fit_whitening(reference_desc, k)
    short = fit.shortfall()
    if short is not None:
        notice(short)
    return whiten_descriptors(query_desc, fit), whiten_descriptors(reference_desc, fit), fit


#: (Not in the paper.) The room's table: each step on the landmark descriptors, by the
#: :class:`~.spec.Matching` field that sets it, as ``(query_desc, reference_desc, value) ->
#: (query, reference, info)``; ``run_method`` applies the set ones in this order after the
#: features (fit on the references only), and the matcher never sees the field.
DESCRIPTOR_STEPS = {"whiten": whiten_landmarks}


def score_sign_notice(
    similarity: np.ndarray, ground_truth: np.ndarray, protocol: str
) -> str | None:
    """Say (and return; None: nothing to say), under the ``ratio`` protocol, how many queries'
    best score is ``<= 0`` (whitened cosines are centred on 0, so Eq. (1) can be negative;
    docs/DEFINITIONS.md, whitening).

    Args:
        similarity: ``(Nq, Nr)`` the run's matrix (NaN: not ranked); ground_truth: ``(Nq, Nr)``
            bool; protocol: the run's PR protocol.
    """
    if protocol != "ratio":
        return None
    s = np.asarray(similarity, dtype=np.float64)
    rows = np.isfinite(s).any(1) & np.asarray(ground_truth, dtype=bool).any(1)
    best = np.where(np.isfinite(s[rows]), s[rows], -np.inf).max(1, initial=-np.inf)
    n = int(np.count_nonzero(best <= 0))
    if not n:
        return None
    return notice(
        f"whitening: {n} of {int(rows.sum())} queries have a best score <= 0 (whitened "
        "cosines are centred on 0, so a weak match's Eq. (1) term 1 - d*s is negative): the "
        "ratio protocol gives them r = 1, rejected at every threshold but the last, which "
        "lowers AUC and R@100P (R@K is unaffected); normalise='query_batch' (positive "
        "scores) does not have it (docs/DEFINITIONS.md, whitening)"
    )


def clear_whitening_cache() -> int:
    """Empty the in-memory whitening fits; returns the entries dropped."""
    with _CACHE_LOCK:
        n = len(_CACHE)
        _CACHE.clear()
    return n


def whitening_cache_keys() -> list[str]:
    """The content keys of the fits in memory (oldest first)."""
    with _CACHE_LOCK:
        return list(_CACHE)


def refuse_whiten(matching: Matching, caller: str) -> None:
    """Refuse ``whiten`` where the reference database is not known (a batch of descriptors)."""
    whiten = getattr(matching, "whiten", None)
    if whiten is not None:
        raise ValueError(
            f"{caller}: whiten={whiten!r} is a step on the landmark descriptors that needs the "
            f"whole reference database: call run_method(..., whiten={whiten}), or whiten the "
            "descriptors first with vpr_core.matching.whiten_landmarks(query_desc, "
            f"reference_desc, {whiten}) and pass a Matching without whiten"
        )
