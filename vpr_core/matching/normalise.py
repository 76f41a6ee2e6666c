"""(Not in the paper.) The room of the normalisations of a whole similarity matrix after Eq. (1),
``normalise=``: :data:`NORMALISATIONS` (``query_batch``: needs the batch of queries;
``database``: CSLS-like, a single live query; docs/DEFINITIONS.md) and :func:`normalise_matrix`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..checks import check_choice, check_int, check_shape

__all__ = [
    "NORMALISATIONS",
    "NORMALISE_K",
    "NORMALISE_SIGMA_MIN",
    "Normalisation",
    "database_normalise",
    "database_offsets",
    "needs_query_batch",
    "normalise_matrix",
    "query_batch_normalise",
    "refuse_normalise",
    "zscore",
]

#: (Not in the paper.) ``database``: the nearest database neighbours whose mean similarity is
#: subtracted (CSLS's published default, fixed before any result; docs/DEFINITIONS.md).
NORMALISE_K = 10
#: (Not in the paper.) A standard deviation at or below this makes its z-score term 0.
NORMALISE_SIGMA_MIN = 1e-12
#: The magnitudes :func:`zscore` takes as they are; a line whose largest value lies outside
#: is divided by it first (a z-score does not change with a positive scale; 1e300 squared
#: overflows, and a sd below :data:`NORMALISE_SIGMA_MIN` would read as constant).
_SAFE_MAX, _SAFE_MIN = 1e6, 1e-6


def zscore(s: np.ndarray, axis: int) -> np.ndarray:
    """``(s - mean) / std`` along ``axis`` over ranked (finite) entries, population std; 0 where
    the std is <= :data:`NORMALISE_SIGMA_MIN` or no entry is ranked; NaN stays NaN; a line of
    values far from 1 in magnitude is rescaled first (the same z-scores at any positive scale)."""
    ok = np.isfinite(s)
    n = ok.sum(axis, keepdims=True)
    x = np.where(ok, s, 0.0)
    big = np.abs(x).max(axis, keepdims=True) if x.shape[axis] else np.zeros_like(n, float)
    if ((big > _SAFE_MAX) | ((big > 0) & (big < _SAFE_MIN))).any():
        # a scale far from 1: each line divided by its largest |value| first (a z-score does
        # not change with a positive scale; the matrices of every method take the direct path)
        scale = np.where(big > 0, big, 1.0)
        s, x = s / scale, x / scale
    mean = x.sum(axis, keepdims=True) / np.maximum(n, 1)
    var = (np.where(ok, s - mean, 0.0) ** 2).sum(axis, keepdims=True) / np.maximum(n, 1)
    sd = np.sqrt(var)
    good = (n > 0) & (sd > NORMALISE_SIGMA_MIN)
    z = (s - mean) / np.where(good, sd, 1.0)
    return np.where(good, z, np.where(ok, 0.0, np.nan))


def query_batch_normalise(similarity: np.ndarray) -> np.ndarray:
    """``z_row + z_col`` of ``(Nq, Nr)`` (before the final ``exp``): each entry z-normalised
    over its query's references plus over the batch of queries (**needs the query batch**)."""
    s = np.asarray(similarity, dtype=np.float64)
    return zscore(s, 1) + zscore(s, 0)


def database_offsets(database: np.ndarray, k: int = NORMALISE_K) -> np.ndarray:
    """``(Nr,)`` ``rho_r``: the mean of reference ``r``'s ``k`` largest similarities to the other
    references (the diagonal and NaN entries left out; fewer when fewer are ranked, 0 when none).

    Args:
        database: ``(Nr, Nr)`` similarities of the references to each other by the same method.
        k: neighbours (:data:`NORMALISE_K`).
    """
    db = np.array(database, dtype=np.float64)
    k = check_int(k, "k (nearest database neighbours)", 1)
    if db.ndim != 2 or db.shape[0] != db.shape[1]:
        raise ValueError(f"database must be a square (Nr, Nr) matrix, got shape {db.shape}")
    np.fill_diagonal(db, np.nan)
    ranked = np.isfinite(db)
    srt = -np.sort(-np.where(ranked, db, -np.inf), axis=1)  # descending, unranked last
    kk = np.minimum(k, ranked.sum(1))  # (Nr,)
    take = np.arange(db.shape[1])[None, :] < kk[:, None]
    total = np.where(take, srt, 0.0).sum(1)
    return np.where(kk > 0, total / np.maximum(kk, 1), 0.0)


def database_normalise(
    similarity: np.ndarray, database: np.ndarray, k: int = NORMALISE_K
) -> np.ndarray:
    """``S[q, r] - rho_r`` (before the final ``exp``): the database-only variant, for a single
    live query (:func:`database_offsets`)."""
    s = np.asarray(similarity, dtype=np.float64)
    rho = database_offsets(database, k)
    if rho.shape[0] != s.shape[1]:
        raise ValueError(
            f"database is ({rho.shape[0]}, {rho.shape[0]}) but the matrix has {s.shape[1]} "
            "references: score the same references against each other"
        )
    return s - rho[None, :]


@dataclass(frozen=True)
class Normalisation:
    """(Not in the paper.) One normalisation of a whole matrix: an entry of
    :data:`NORMALISATIONS`, whose key is its ``normalise=`` name.

    Attributes:
        function: ``function(similarity, database)``: ``(Nq, Nr)`` float64 (NaN: not ranked) ->
            ``(Nq, Nr)``; ``database`` is the ``(Nr, Nr)`` references against each other when
            ``needs_database``, else None.
        needs_query_batch: its rows change when the other queries change (every table that
            shows it says so).
        needs_database: it reads the references scored against each other by the same method.
    """

    function: Callable[[np.ndarray, np.ndarray | None], np.ndarray]
    needs_query_batch: bool = False
    needs_database: bool = False


def _query_batch(similarity: np.ndarray, database: np.ndarray | None) -> np.ndarray:
    return np.exp(query_batch_normalise(similarity))


def _database(similarity: np.ndarray, database: np.ndarray | None) -> np.ndarray:
    assert database is not None
    return np.exp(database_normalise(similarity, database))


#: (Not in the paper.) The normalisations by ``normalise=`` name (docs/DEFINITIONS.md). A new
#: normalisation is one function and one entry here.
NORMALISATIONS: dict[str, Normalisation] = {
    "query_batch": Normalisation(_query_batch, needs_query_batch=True),
    "database": Normalisation(_database, needs_database=True),
}


def needs_query_batch(normalise: str | None) -> bool:
    """True when the normalisation ``normalise`` uses the other queries of the batch."""
    return normalise is not None and NORMALISATIONS[normalise].needs_query_batch


def normalise_matrix(
    similarity: np.ndarray, how: str | None, database: np.ndarray | None = None
) -> np.ndarray:
    """A similarity matrix normalised by the :data:`NORMALISATIONS` entry ``how`` (None:
    unchanged); the one place a whole-matrix step runs.

    Args:
        similarity: ``(Nq, Nr)`` any method's or a peer's similarities (NaN: not ranked).
        how: None or a name of :data:`NORMALISATIONS`; ``"query_batch"`` needs the batch of
            queries (its rows change when the other queries change).
        database: ``(Nr, Nr)`` the references scored against each other by the same method
            (a normalisation that ``needs_database`` only).

    Returns:
        ``(Nq, Nr)`` float64 (``query_batch``, ``database``: positive where ranked, each row's
        ranking kept for ``database``).
    """
    s = check_shape(similarity, "Nq Nr", "similarity", dtype=np.float64)
    if how is None:
        return s
    if np.isinf(s).any():
        q, r = np.argwhere(np.isinf(s))[0]
        raise ValueError(
            f"similarity[{q}, {r}] is {s[q, r]}: normalise={how!r} needs finite scores (NaN "
            "marks a pair not ranked); replace the infinite entries (a peer's matrix file) or "
            "leave the matrix unnormalised"
        )
    entry = NORMALISATIONS[check_choice(how, "normalise", NORMALISATIONS)]
    if entry.needs_database and database is None:
        raise ValueError(
            f"normalise={how!r} needs the references scored against each other (database=, "
            "an (Nr, Nr) matrix by the same method)"
        )
    return np.asarray(entry.function(s, database if entry.needs_database else None))


def refuse_normalise(matching: object, caller: str) -> None:
    """Refuse ``normalise`` where there is no whole matrix (one pair, listed pairs, a block)."""
    how = getattr(matching, "normalise", None)
    if how is not None:
        raise ValueError(
            f"{caller}: normalise={how!r} is a step on a whole (Nq, Nr) matrix, applied once "
            f"to a result: run_method(..., normalise={how!r}) or normalise_result(result, "
            f"{how!r}) (valid names: {', '.join(NORMALISATIONS)})"
        )
