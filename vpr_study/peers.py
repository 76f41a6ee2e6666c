"""Peers: VPR-Bench's precomputed similarity matrices (Zaffar et al. IJCV 2021, read with the
restricted unpickler) and a user's own method as a matrix or global descriptors (``.npy`` files
read with ``allow_pickle=False``), checked against a dataset by :func:`peer_similarity_for`."""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vpr_core import Evaluation, MethodResult, checks, read_npy, result_from_matrix, settings

log = logging.getLogger("vpr_core")

__all__ = [
    "PRECOMPUTED_FILE",
    "PeerResult",
    "find_vprbench_peers",
    "load_vprbench_precomputed",
    "peer_from_descriptors",
    "peer_from_matrix",
    "peer_result",
    "peer_similarity_for",
]

PRECOMPUTED_FILE = "precomputed_data_corrected.npy"
#: The items of a VPR-Bench precomputed file, in order (similarity: higher = more similar; the
#: times as VPR-Bench stored them; written under Python 2, hence ``encoding="latin1"``).
_ITEMS = (
    "query indices",
    "top-1 reference indices",
    "top-1 scores",
    "similarity matrix",
    "encode seconds",
    "match seconds",
)


@dataclass(frozen=True)
class PeerResult:
    """One peer's result on one dataset: a VPR-Bench technique (``name`` and ``dataset`` its
    folder names, times as VPR-Bench stored them) or a user's method (``dataset`` ``""``, times
    NaN). ``similarity`` is ``float64 (Nq, Nr)``, row ``k`` of query ``query_indices[k]``;
    ``top1_reference`` the stored best reference per row; ``source`` None for an array."""

    name: str
    dataset: str
    similarity: np.ndarray = field(repr=False)
    encode_seconds: float
    match_seconds: float
    source: Path | None
    query_indices: np.ndarray = field(repr=False)
    top1_reference: np.ndarray = field(repr=False)


def _bad(path: Path, what: str) -> ValueError:
    return ValueError(
        f"{path} is not a VPR-Bench precomputed_data_corrected.npy: {what}. Expected 6 items: "
        f"{', '.join(_ITEMS)}."
    )


def _items(path: Path) -> list:
    data = read_npy(
        path, f"a VPR-Bench {PRECOMPUTED_FILE} (6 items: {', '.join(_ITEMS)}); download it again"
    )
    if isinstance(data, np.ndarray) and data.dtype == object and data.ndim == 0:
        data = data.item()
    if isinstance(data, np.ndarray) and (data.dtype != object or data.ndim != 1):
        raise _bad(path, f"found a {data.dtype} array of shape {data.shape}")
    if not isinstance(data, (np.ndarray, list, tuple)):
        raise _bad(path, f"found a {type(data).__name__}")
    if len(data) != len(_ITEMS):
        raise _bad(path, f"found {len(data)} items")
    return list(data)


def _as_real(value: Any) -> np.ndarray:
    """``value`` as a float64 array; TypeError for complex, dates, strings and other non-reals
    (``np.asarray(..., float64)`` would drop an imaginary part or parse dates)."""
    raw = np.asarray(value)
    if raw.dtype.kind not in "biufO":
        raise TypeError(f"dtype {raw.dtype} is not real numbers")
    return raw.astype(np.float64)


def _item(path: Path, items: list, k: int, rows: int | None = None) -> np.ndarray:
    """Item ``k`` checked: a finite real ``(Nq, Nr)`` matrix (k = 3), a ``(rows,)`` vector
    (integral for the indices, k < 2) or one number ``>= 0`` (the times, k > 3)."""
    what = f"item {k} ({_ITEMS[k]})"
    try:
        arr = _as_real(items[k])
    except (TypeError, ValueError):
        kind = "(Nq, Nr) matrix (ragged rows?)" if k == 3 else "array"
        raise _bad(path, f"{what} is not a numeric {kind}") from None
    flat = arr.ravel()
    if k == 3 and (arr.ndim != 2 or 0 in arr.shape):
        wrong = f"has shape {arr.shape}, not (Nq, Nr)"
    elif k < 3 and flat.size != rows:
        wrong = f"has {flat.size} values, the similarity matrix {rows} rows"
    elif k > 3 and (flat.size != 1 or flat[0] < 0):
        wrong = f"must be one number >= 0, got {items[k]!r}"
    elif not np.isfinite(flat).all():
        wrong = "holds NaN or inf"
    elif k < 2 and (flat != np.round(flat)).any():
        wrong = "is not integral"
    else:
        return arr if k == 3 else flat
    raise _bad(path, f"{what} {wrong}")


def load_vprbench_precomputed(path: str | os.PathLike) -> PeerResult:
    """Read ``.../precomputed_matches/<dataset>/<technique>/precomputed_data_corrected.npy``
    (technique and dataset named by the two parent folders)."""
    path = Path(path).expanduser()
    if not checks.check_file(path, "VPR-Bench precomputed file"):
        raise FileNotFoundError(
            f"VPR-Bench precomputed file not found: {path}; expected "
            f"precomputed_matches/<dataset>/<technique>/{PRECOMPUTED_FILE}."
        )
    items = _items(path)
    sim = _item(path, items, 3)
    nq, nr = sim.shape
    queries, top1, _ = (_item(path, items, k, nq) for k in (0, 1, 2))
    queries, top1 = queries.astype(np.int64), top1.astype(np.int64)
    if np.any((top1 < 0) | (top1 >= nr)):
        raise _bad(path, f"item 1 (top-1 reference indices) outside 0..{nr - 1}")
    agree = float(np.mean(np.argmax(sim, axis=1) == top1))
    if agree < 0.9:
        log.warning(
            "%s: the stored top-1 references agree with the similarity matrix's row "
            "maxima for only %.0f%% of the queries; check that the matrix is a similarity "
            "(higher = better), not a distance",
            path,
            100 * agree,
        )
    return PeerResult(
        name=path.parent.name,
        dataset=path.parent.parent.name,
        similarity=sim,
        encode_seconds=float(_item(path, items, 4)[0]),
        match_seconds=float(_item(path, items, 5)[0]),
        source=path,
        query_indices=queries,
        top1_reference=top1,
    )


def _user_array(value: Any, name: str, what: str, ndim: int) -> tuple[np.ndarray, Path | None]:
    """A finite float64 array of ``ndim`` dims from an array or a ``.npy`` path (no pickles)."""
    source = None
    if isinstance(value, (str, os.PathLike)):
        source = Path(value).expanduser()
        if not checks.check_file(source, f"peer {name!r}: {what}"):
            raise FileNotFoundError(f"peer {name!r}: {what} file not found: {source}.")
        try:  # the header's shape is checked against the file before anything is allocated
            value = read_npy(
                source, f"the {what} saved with np.save(path, array)", allow_pickle=False
            )
        except ValueError as exc:
            raise ValueError(f"peer {name!r}: {exc}") from None
    where = source or "the array"
    try:
        arr = _as_real(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(
            f"peer {name!r}: the {what} in {where} is not real numbers ({exc}: complex, dates, "
            "strings and objects are refused); save a float array."
        ) from None
    if arr.ndim != ndim or 0 in arr.shape:
        shape = "(Nq, Nr)" if what.endswith("matrix") else "(N, D)"
        raise ValueError(
            f"peer {name!r}: the {what} in {where} has shape {arr.shape}; it must be a "
            f"non-empty {ndim}-d {shape} array."
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(
            f"peer {name!r}: the {what} in {where} holds "
            f"{int(np.sum(~np.isfinite(arr)))} NaN or inf values; fix the method's "
            "output (every entry must be a finite number)."
        )
    return arr, source


#: Smallest rescaled distance used by :func:`_distance_similarity` (a distance of 0 maps here).
_MIN_SCALED_DISTANCE = 1e-300


def _distance_similarity(dist: np.ndarray, name: str, where: object) -> np.ndarray:
    """Similarity ``c / d`` of finite distances, so that the ratio test's ``S2 / S1`` is the
    ``d1 / d2`` of Sunderhauf et al. (docs/DEFINITIONS.md); rankings kept. ``c = max(d)``, or
    the geometric middle of the positive distances when they span more than 300 decades (both
    ends stay finite, no tie from underflow); a distance of 0 maps above every other."""
    if (dist < 0).any():
        raise ValueError(
            f"peer {name!r}: the distance matrix in {where} holds {int((dist < 0).sum())} "
            "negative values; distances must be >= 0 (pass a similarity matrix without "
            "--peer-distance / distance=False if higher means more similar)."
        )
    top = float(dist.max())
    if top == 0.0:
        return np.ones_like(dist)
    low = float(dist[dist > 0].min())
    if top / low < 1 / _MIN_SCALED_DISTANCE:
        return 1.0 / np.maximum(dist / top, _MIN_SCALED_DISTANCE)
    biggest = np.finfo(np.float64).max
    with np.errstate(over="ignore", divide="ignore"):
        sim = np.minimum((np.sqrt(top) * np.sqrt(low)) / dist, biggest / 2)
    return np.where(dist == 0, biggest, sim)


def _check_name(name: Any) -> str:
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"a peer needs a non-empty name, got {name!r}.")
    return name


def _user_peer(name: str, sim: np.ndarray, source: Path | None) -> PeerResult:
    top1 = np.argmax(sim, axis=1)
    return PeerResult(
        name=name,
        dataset="",
        similarity=sim,
        encode_seconds=float("nan"),
        match_seconds=float("nan"),
        source=source,
        query_indices=np.arange(sim.shape[0]),
        top1_reference=top1,
    )


def peer_from_matrix(
    matrix_or_path: np.ndarray | str | os.PathLike, name: str, distance: bool = False
) -> PeerResult:
    """A user's method as a peer, from its ``(Nq, Nr)`` matrix (array or ``.npy`` file; row
    ``q`` = query ``q`` in the dataset's order, higher = more similar). ``distance=True``: the
    matrix holds distances ``>= 0``, scored as ``1 / d`` (the ratio protocol then sees ``d1 / d2``).
    """
    _check_name(name)
    sim, source = _user_array(
        matrix_or_path, name, "distance matrix" if distance else "similarity matrix", 2
    )
    if distance:
        sim = _distance_similarity(sim, name, source or "the array")
    return _user_peer(name, sim, source)


def peer_from_descriptors(
    query_path_or_array: np.ndarray | str | os.PathLike,
    database_path_or_array: np.ndarray | str | os.PathLike,
    name: str,
    metric: str = "cosine",
) -> PeerResult:
    """A user's method as a peer, from ``(Nq, D)`` query and ``(Nr, D)`` database descriptors
    (arrays or ``.npy`` files, e.g. VPR-methods-evaluation's ``queries_descriptors.npy``).
    ``metric``: ``"cosine"`` or ``"l2"`` (similarity ``1 / d`` as :func:`peer_from_matrix`).
    """
    _check_name(name)
    metric = checks.check_choice(str(metric).lower(), "metric", ("cosine", "l2"))
    q, q_src = _user_array(query_path_or_array, name, "query descriptors", 2)
    r, _ = _user_array(database_path_or_array, name, "database descriptors", 2)
    if q.shape[1] != r.shape[1]:
        raise ValueError(
            f"peer {name!r}: query descriptors are {q.shape[1]}-d but database "
            f"descriptors {r.shape[1]}-d; give both files of the same method run."
        )
    if metric == "l2":
        # one common scale keeps the squares finite; 1 / d depends only on distance ratios
        scale = max(float(np.abs(q).max()), float(np.abs(r).max())) or 1.0
        q, r = q / scale, r / scale
        sq = (q * q).sum(1)[:, None] + (r * r).sum(1)[None, :] - 2 * q @ r.T
        dist = np.sqrt(np.maximum(sq, 0.0))
        return _user_peer(name, _distance_similarity(dist, name, q_src or "the array"), q_src)
    # each row scaled by its largest entry first: cosine is scale-free, the norm cannot overflow
    q = q / np.maximum(np.abs(q).max(axis=1, keepdims=True), np.finfo(np.float64).tiny)
    r = r / np.maximum(np.abs(r).max(axis=1, keepdims=True), np.finfo(np.float64).tiny)
    nq, nr = np.linalg.norm(q, axis=1), np.linalg.norm(r, axis=1)
    if not (nq > 0).all() or not (nr > 0).all():
        raise ValueError(
            f"peer {name!r}: some descriptors are all zero, so their cosine is "
            "undefined; use metric='l2' or fix the descriptors."
        )
    return _user_peer(name, (q / nq[:, None]) @ (r / nr[:, None]).T, q_src)


def _precomputed_dir(root: str | os.PathLike | None) -> Path:
    if root is None:
        root = settings.bench_root()
        if not root:
            raise ValueError(
                f"no VPR-Bench folder given: pass root=<VPR-Bench checkout> or set "
                f"{settings.BENCH_ROOT_ENV}."
            )
    root = Path(root).expanduser()
    for cand in (root / "precomputed_matches", root):
        if cand.is_dir() and cand.name == "precomputed_matches":
            return cand
    raise FileNotFoundError(
        f"{root} is neither a VPR-Bench checkout (with precomputed_matches/) "
        "nor its precomputed_matches folder."
    )


def find_vprbench_peers(root: str | os.PathLike | None, dataset: str) -> list[PeerResult]:
    """Every technique's precomputed result for one VPR-Bench dataset, sorted by name.

    ``root``: a VPR-Bench checkout or its ``precomputed_matches`` folder (None: ``VPR_BENCH_ROOT``);
    ``dataset``: a folder name under it, exact or unique up to case (``"GardensPointWalking"``).
    """
    base = _precomputed_dir(root)
    found = sorted(p.name for p in base.iterdir() if p.is_dir())
    match = [n for n in found if n == dataset] or [n for n in found if n.lower() == dataset.lower()]
    if len(match) != 1:
        raise FileNotFoundError(
            f"VPR-Bench dataset {dataset!r} not found in {base}; datasets "
            f"there: {', '.join(found) or 'none'}."
        )
    folder = base / match[0]
    files = sorted(
        (p / PRECOMPUTED_FILE for p in folder.iterdir() if (p / PRECOMPUTED_FILE).is_file()),
        key=lambda p: p.parent.name.lower(),
    )
    if not files:
        raise FileNotFoundError(f"no <technique>/{PRECOMPUTED_FILE} under {folder}.")
    return [load_vprbench_precomputed(f) for f in files]


def peer_similarity_for(dataset: Any, peer: PeerResult) -> np.ndarray:
    """A peer's ``float64 (Nq, Nr)`` similarity checked against a dataset, rows in the dataset's
    query order."""
    nq, nr = dataset.ground_truth.shape
    if peer.similarity.shape != (nq, nr):
        pq, pr = peer.similarity.shape
        raise ValueError(
            f"peer {peer.name!r} ({peer.source or 'array'}): the peer has {pq} x {pr} (queries x "
            f"references) but the dataset {dataset.name!r} has {nq} x {nr}: compute the peer on "
            "exactly this dataset's query and reference images, in its order (same subset, "
            "same step), or load the dataset the peer was computed on."
        )
    order = np.argsort(peer.query_indices, kind="stable")
    if not np.array_equal(peer.query_indices[order], np.arange(nq)):
        raise ValueError(
            f"peer {peer.name!r} ({peer.source}): its query indices are not 0..{nq - 1} "
            "each once, so its rows cannot be matched to the dataset's queries."
        )
    return peer.similarity[order].copy()


def peer_result(
    peer, dataset, evaluation: Evaluation | None = None, label: str | None = None, **overrides: Any
) -> MethodResult:
    """A VPR-Bench peer (:class:`~vpr_study.peers.PeerResult`) as a result beside ours.

    Its similarity matrix is checked against ``dataset`` (shape, query order) and evaluated with
    the same metrics and intervals. Costs: ``features s/img`` is VPR-Bench's stored encode time
    and ``matching s/pair`` its stored match time, as VPR-Bench recorded them on its machine
    (not comparable with ours to more than an order of magnitude); landmark columns are NaN.

    Args:
        peer: a loaded peer (:func:`~vpr_study.peers.load_vprbench_precomputed`).
        dataset: the :class:`~vpr_core.datasets.PlaceDataset` it was computed on.
        evaluation: protocol and bootstrap resamples (as
            :func:`~vpr_core.run_method`; its fields given as keywords change it). The
            ground truth is ``dataset``'s as loaded (``tolerance=`` here is refused, naming the
            fix).
        label: its name in tables and legends (default ``"<name> (VPR-Bench)"``).
    """
    evaluation = (evaluation or Evaluation()).with_options(overrides, "peer_result")
    nq, nr = np.shape(dataset.ground_truth)
    timings = {
        "landmarks_s_per_image": float("nan"),
        "landmarks_per_image": float("nan"),
        "features_s_per_image": float(peer.encode_seconds),
        "matching_s_per_pair": float(peer.match_seconds),
        "pairs": float(nq * nr),
    }
    source = None if peer.source is None else str(peer.source)
    sim = peer_similarity_for(dataset, peer)
    made = MethodResult(
        method=f"peer:{peer.name}",
        label=label or f"{peer.name} (VPR-Bench)",
        config={"name": f"peer:{peer.name}", "source": source},
        encoder={},
        similarity=sim,
        boxes={"query": [], "reference": []},
        metrics={},
        timings=timings,
        **MethodResult.fields_of(dataset),
    )
    return result_from_matrix(sim, made, evaluation)
