"""Peer results from VPR-Bench (Zaffar et al. IJCV 2021): precomputed similarity matrices.

VPR-Bench ships, per dataset and technique (NetVLAD, HybridNet, AMOSNet, AlexNet_VPR, RegionVLAD,
CoHOG, HOG, CALC, denseVLAD, AP-GeM, ...), a file::

    <VPR-Bench>/precomputed_matches/<dataset>/<technique>/precomputed_data_corrected.npy

a pickled numpy object array (written under Python 2, hence ``encoding="latin1"``) holding, in
order: the query indices ``(Nq,)``, the top-1 reference indices ``(Nq,)``, the top-1 scores
``(Nq,)``, the full similarity matrix ``(Nq, Nr)`` (higher = more similar), the encoding time
and the matching time in seconds, as VPR-Bench stored them (not rescaled here).

:func:`load_vprbench_precomputed` reads one file into a :class:`PeerResult`,
:func:`find_vprbench_peers` every technique of one dataset, and :func:`peer_similarity_for`
checks a peer against a :class:`~vpr_core.datasets.PlaceDataset` and returns its ``(Nq, Nr)``
matrix in the dataset's query order, ready for the same metrics as ours.

The files are pickles: loading one can run code from it, so load only files from a source you
trust (the VPR-Bench release).
"""

from __future__ import annotations

import logging
import os
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "PRECOMPUTED_FILE",
    "VPR_BENCH_ROOT_ENV",
    "PeerResult",
    "find_vprbench_peers",
    "load_vprbench_precomputed",
    "peer_similarity_for",
]

log = logging.getLogger("vpr_core")

PRECOMPUTED_FILE = "precomputed_data_corrected.npy"
VPR_BENCH_ROOT_ENV = "VPR_BENCH_ROOT"
_ITEMS = ("query indices", "top-1 reference indices", "top-1 scores", "similarity matrix",
          "encode seconds", "match seconds")


@dataclass(frozen=True)
class PeerResult:
    """One VPR-Bench technique's precomputed result on one dataset.

    Attributes:
        name: Technique (its folder name, e.g. ``"NetVLAD"``).
        dataset: VPR-Bench dataset (its folder name, e.g. ``"GardensPointWalking"``).
        similarity: ``float64 (Nq, Nr)``; row ``k`` belongs to query ``query_indices[k]``.
        encode_seconds: Encoding time as stored by VPR-Bench.
        match_seconds: Matching time as stored by VPR-Bench.
        source: The file it was read from.
        query_indices: ``int64 (Nq,)`` query index of each row.
        top1_reference: ``int64 (Nq,)`` VPR-Bench's best reference per row.
        top1_score: ``float64 (Nq,)`` its score.
    """

    name: str
    dataset: str
    similarity: np.ndarray = field(repr=False)
    encode_seconds: float
    match_seconds: float
    source: Path
    query_indices: np.ndarray = field(repr=False)
    top1_reference: np.ndarray = field(repr=False)
    top1_score: np.ndarray = field(repr=False)

    @property
    def shape(self) -> tuple[int, int]:
        """``(Nq, Nr)`` of the similarity matrix."""
        return tuple(self.similarity.shape)  # type: ignore[return-value]


def _bad(path: Path, what: str) -> ValueError:
    return ValueError(
        f"{path} is not a VPR-Bench precomputed_data_corrected.npy: {what}. Expected 6 items: "
        f"{', '.join(_ITEMS)}."
    )


def _items(path: Path) -> list:
    try:
        data = np.load(path, allow_pickle=True, encoding="latin1")
    except (OSError, ValueError, EOFError, pickle.UnpicklingError) as exc:
        raise _bad(path, f"unreadable ({type(exc).__name__}: {exc}); download it again") from None
    if isinstance(data, np.ndarray) and data.dtype == object and data.ndim == 0:
        data = data.item()
    if isinstance(data, np.ndarray) and (data.dtype != object or data.ndim != 1):
        raise _bad(path, f"found a {data.dtype} array of shape {data.shape}")
    if not isinstance(data, (np.ndarray, list, tuple)):
        raise _bad(path, f"found a {type(data).__name__}")
    if len(data) != len(_ITEMS):
        raise _bad(path, f"found {len(data)} items")
    return list(data)


def _vector(path: Path, value: Any, k: int, n: int | None, integral: bool) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise _bad(path, f"item {k} ({_ITEMS[k]}) is not numeric") from None
    if n is not None and arr.size != n:
        raise _bad(path, f"item {k} ({_ITEMS[k]}) has {arr.size} values, the similarity matrix "
                         f"{n} rows")
    if not np.all(np.isfinite(arr)):
        raise _bad(path, f"item {k} ({_ITEMS[k]}) holds NaN or inf")
    if integral:
        if not np.all(arr == np.round(arr)):
            raise _bad(path, f"item {k} ({_ITEMS[k]}) is not integral")
        return arr.astype(np.int64)
    return arr


def _seconds(path: Path, value: Any, k: int) -> float:
    arr = _vector(path, value, k, None, integral=False)
    if arr.size != 1 or arr[0] < 0:
        raise _bad(path, f"item {k} ({_ITEMS[k]}) must be one number >= 0, got {value!r}")
    return float(arr[0])


def _matrix(path: Path, value: Any) -> np.ndarray:
    try:
        sim = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise _bad(path, "item 3 (similarity matrix) is not a numeric (Nq, Nr) matrix "
                         "(ragged rows?)") from None
    if sim.ndim != 2 or 0 in sim.shape:
        raise _bad(path, f"item 3 (similarity matrix) has shape {sim.shape}, not (Nq, Nr)")
    if not np.all(np.isfinite(sim)):
        raise _bad(path, "item 3 (similarity matrix) holds NaN or inf")
    return sim


def load_vprbench_precomputed(path: str | os.PathLike) -> PeerResult:
    """Read one VPR-Bench ``precomputed_data_corrected.npy``.

    Args:
        path: ``.../precomputed_matches/<dataset>/<technique>/precomputed_data_corrected.npy``;
            the technique and dataset names are taken from the two parent folders.

    Returns:
        A :class:`PeerResult` with ``similarity`` ``float64 (Nq, Nr)``.

    Raises:
        FileNotFoundError: no such file.
        ValueError: not 6 items, or an item of the wrong shape or type (the message names the
            file and what was found).
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"VPR-Bench precomputed file not found: {path}; expected "
                                f"precomputed_matches/<dataset>/<technique>/{PRECOMPUTED_FILE}.")
    items = _items(path)
    sim = _matrix(path, items[3])
    nq, nr = sim.shape
    queries = _vector(path, items[0], 0, nq, integral=True)
    top1 = _vector(path, items[1], 1, nq, integral=True)
    scores = _vector(path, items[2], 2, nq, integral=False)
    if np.any((top1 < 0) | (top1 >= nr)):
        raise _bad(path, f"item 1 (top-1 reference indices) outside 0..{nr - 1}")
    agree = float(np.mean(np.argmax(sim, axis=1) == top1))
    if agree < 0.9:
        log.warning("%s: the stored top-1 references agree with the similarity matrix's row "
                    "maxima for only %.0f%% of the queries; check that the matrix is a similarity "
                    "(higher = better), not a distance", path, 100 * agree)
    return PeerResult(name=path.parent.name, dataset=path.parent.parent.name, similarity=sim,
                      encode_seconds=_seconds(path, items[4], 4),
                      match_seconds=_seconds(path, items[5], 5), source=path,
                      query_indices=queries, top1_reference=top1, top1_score=scores)


def _precomputed_dir(root: str | os.PathLike | None) -> Path:
    if root is None:
        root = os.environ.get(VPR_BENCH_ROOT_ENV)
        if not root:
            raise ValueError(f"no VPR-Bench folder given: pass root=<VPR-Bench checkout> or set "
                             f"{VPR_BENCH_ROOT_ENV}.")
    root = Path(root).expanduser()
    for cand in (root / "precomputed_matches", root):
        if cand.is_dir() and cand.name == "precomputed_matches":
            return cand
    raise FileNotFoundError(f"{root} is neither a VPR-Bench checkout (with precomputed_matches/) "
                            "nor its precomputed_matches folder.")


def find_vprbench_peers(root: str | os.PathLike | None, dataset: str) -> list[PeerResult]:
    """Every technique's precomputed result for one VPR-Bench dataset, sorted by name.

    Args:
        root: A VPR-Bench checkout or its ``precomputed_matches`` folder; None: the environment
            variable ``VPR_BENCH_ROOT``.
        dataset: The dataset's folder name under ``precomputed_matches`` (exact, or unique up to
            case, e.g. ``"GardensPointWalking"``).

    Returns:
        One :class:`PeerResult` per technique folder holding ``precomputed_data_corrected.npy``.

    Raises:
        ValueError: no root given and ``VPR_BENCH_ROOT`` unset.
        FileNotFoundError: no such folder or dataset (the message lists those found), or no
            technique file in it.
    """
    base = _precomputed_dir(root)
    found = sorted(p.name for p in base.iterdir() if p.is_dir())
    match = [n for n in found if n == dataset] or [n for n in found if n.lower() == dataset.lower()]
    if len(match) != 1:
        raise FileNotFoundError(f"VPR-Bench dataset {dataset!r} not found in {base}; datasets "
                                f"there: {', '.join(found) or 'none'}.")
    folder = base / match[0]
    files = sorted((p / PRECOMPUTED_FILE for p in folder.iterdir()
                    if (p / PRECOMPUTED_FILE).is_file()), key=lambda p: p.parent.name.lower())
    if not files:
        raise FileNotFoundError(f"no <technique>/{PRECOMPUTED_FILE} under {folder}.")
    return [load_vprbench_precomputed(f) for f in files]


def peer_similarity_for(dataset: Any, peer: PeerResult) -> np.ndarray:
    """A peer's similarity matrix checked against a dataset, rows in the dataset's query order.

    Args:
        dataset: A :class:`~vpr_core.datasets.PlaceDataset` (``Nq`` queries, ``Nr`` references).
        peer: A :class:`PeerResult` on the same images.

    Returns:
        ``float64 (Nq, Nr)``: row ``q`` is the peer's similarity of query ``q``.

    Raises:
        ValueError: the shapes differ, or the peer's query indices are not ``0..Nq-1`` each once.
    """
    nq, nr = dataset.ground_truth.shape
    if peer.similarity.shape != (nq, nr):
        raise ValueError(
            f"peer {peer.name!r} ({peer.source}) has a {peer.similarity.shape} similarity matrix "
            f"but dataset {dataset.name!r} has {nq} queries and {nr} references: it belongs to "
            "another dataset or another subset of it."
        )
    order = np.argsort(peer.query_indices, kind="stable")
    if not np.array_equal(peer.query_indices[order], np.arange(nq)):
        raise ValueError(f"peer {peer.name!r} ({peer.source}): its query indices are not 0..{nq - 1} "
                         "each once, so its rows cannot be matched to the dataset's queries.")
    return peer.similarity[order].copy()
