"""The dataset model: :class:`PlaceDataset` (two traverses of image files and their ground
truth). Image files are read and listed by :mod:`vpr_core.datasets.images`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..checks import check_choice, check_int, check_shape
from ..utils import file_fingerprint
from .ground_truth import (
    check_ground_truth,
    check_tolerance,
    frame_aligned,
    ground_truth_coverage,
    ground_truth_text,
)
from .images import read_image

__all__ = ["SIDES", "PlaceDataset"]

#: The two traverses of a dataset, as methods name them.
SIDES = ("query", "reference")


@dataclass
class PlaceDataset:
    """Two traverses of image files and their ground truth.

    Attributes:
        name: Dataset name: ``"synthetic"``, or a file-based dataset's data folder
            (``"gardens_point_mini"``; see :func:`~vpr_core.datasets._layout.data_name`).
        query_paths: ``Nq`` query image files, in traverse order.
        reference_paths: ``Nr`` reference image files, in traverse order.
        ground_truth: ``bool (Nq, Nr)``; ``ground_truth[q, r]`` is True when reference ``r``
            shows the place of query ``q`` (tolerance already applied).
        tolerance: Tolerance used to build ``ground_truth``: frames (int), a distance such as
            ``"25 m"`` (``utm``), or None when not applicable.
        root: Folder the dataset was read from (or generated into).
        homographies: ``float64 (Nq, 3, 3)`` or None. ``homographies[i]`` maps query-``i``
            pixel coordinates ``(x, y, 1)`` to reference-``i`` pixel coordinates (known on
            ``synthetic`` only; None on real data).
        meta: Free-form details (layout, traverse names, generator parameters, ...);
            ``meta["frame_aligned"]``: True when ``ground_truth`` is ``|q - r| <= tolerance``
            (the loaders that say so; :meth:`with_tolerance` needs it).
        ground_truth_soft: ``bool (Nq, Nr)`` or None: VPR_Tutorial's GTsoft, a superset of
            ``ground_truth`` (GThard). Pairs that are soft but not hard positives are neither right
            nor wrong: an evaluation ignores them, e.g. with :meth:`ignore_soft`.
    """

    name: str
    query_paths: list[Path]
    reference_paths: list[Path]
    ground_truth: np.ndarray
    tolerance: int | str | None
    root: Path | None = None
    homographies: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    ground_truth_soft: np.ndarray | None = field(default=None, repr=False)
    _keys: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _sizes: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.query_paths = [Path(p) for p in self.query_paths]
        self.reference_paths = [Path(p) for p in self.reference_paths]
        if self.root is not None:
            self.root = Path(self.root)
        nq, nr = len(self.query_paths), len(self.reference_paths)
        where = f"of PlaceDataset {self.name!r}"
        self.ground_truth = gt = check_ground_truth(self.ground_truth, (nq, nr), where)
        if self.ground_truth_soft is not None:
            soft = check_ground_truth(self.ground_truth_soft, (nq, nr), f"(soft) {where}")
            if (gt & ~soft).any():
                raise ValueError(
                    f"PlaceDataset {self.name!r}: ground_truth_soft must hold every ground_truth "
                    "pair (GTsoft is a superset of GThard), or be None."
                )
            self.ground_truth_soft = soft
        if self.homographies is not None:  # one 3x3 query->reference mapping per query
            self.homographies = check_shape(
                self.homographies, f"{nq} 3 3", f"PlaceDataset {self.name!r}: homographies", float
            )

    @property
    def title(self) -> str:
        """The name as figures print it: ``"nordland_64x32, every 50th place"`` for a loader's
        ``step`` subset, else :attr:`name`."""
        step = self.meta.get("step", 1)
        if not isinstance(step, int) or step <= 1:
            return self.name
        suffix = (
            "th" if step % 100 in (11, 12, 13) else {1: "st", 2: "nd", 3: "rd"}.get(step % 10, "th")
        )
        return f"{self.name}, every {step}{suffix} place"

    @property
    def truth_text(self) -> str:
        """How its ground truth was made, as tables and titles print it (``"tolerance 2"``, or
        the file's correct references per query)."""
        from_file = bool(self.meta.get("ground_truth_file"))
        return ground_truth_text(self.ground_truth, self.tolerance, from_file)

    @property
    def queries_with_gt(self) -> tuple[int, int]:
        """``(queries with at least one correct reference, all queries)``."""
        return ground_truth_coverage(self.ground_truth)

    # -- access ---------------------------------------------------------------------------------

    def paths(self, side: str) -> list[Path]:
        """The image files of one side (``"query"`` or ``"reference"``)."""
        check_choice(side, "side", SIDES)
        return self.query_paths if side == "query" else self.reference_paths

    def _path(self, side: str, i: int) -> Path:
        paths = self.paths(side)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < len(paths):
            raise IndexError(
                f"{side} index {i!r} out of range: dataset {self.name!r} has {len(paths)} "
                f"{side} images (valid indices 0..{len(paths) - 1})."
            )
        return paths[int(i)]

    def load_image(self, side: str, i: int) -> np.ndarray:
        """Read image ``i`` of ``side`` (``"query"`` or ``"reference"``): ``uint8 (H, W, 3)`` RGB.

        Raises ValueError (bad side, unreadable, truncated or tiny file), IndexError,
        FileNotFoundError.
        """
        path = self._path(side, i)
        img = read_image(path)
        self._sizes[(side, int(i))] = img.shape[:2]
        return img

    def image_size(self, side: str, i: int) -> tuple[int, int]:
        """``(H, W)`` of one image (read once, then memoised)."""
        if (side, i) not in self._sizes:
            self.load_image(side, i)
        h, w = self._sizes[(side, i)]
        return int(h), int(w)

    def image_key(self, side: str, i: int) -> str:
        """Stable content key of one image for caches (sha1 of the file bytes, memoised)."""
        path = self._path(side, i)
        key = (side, int(i))
        if key not in self._keys:
            self._keys[key] = file_fingerprint(path)
        return self._keys[key]

    @property
    def soft_only(self) -> np.ndarray | None:
        """``(Nq, Nr)`` bool: the pairs in ``ground_truth_soft`` but not in ``ground_truth``
        (neither right nor wrong); None without soft ground truth."""
        if self.ground_truth_soft is None:
            return None
        return self.ground_truth_soft & ~self.ground_truth

    def ignore_soft(self, similarity: np.ndarray) -> np.ndarray:
        """``similarity (Nq, Nr)`` with soft-only pairs set to its minimum (VPR_Tutorial's rule).

        A pair in ``ground_truth_soft`` but not in ``ground_truth`` is neither a true nor a false
        match; lowering its score to the minimum keeps it from being anyone's best match. Returns
        a copy (the input itself when there is no soft ground truth).
        """
        if self.ground_truth_soft is None:
            return similarity
        out = np.array(similarity, dtype=np.float64)
        if not np.isnan(out).all():  # NaN (unranked) pairs stay NaN
            out[self.soft_only] = np.nanmin(out)
        return out

    def subset(self, n: int) -> PlaceDataset:
        """The first ``n`` queries and references (quick runs); the ground truth is cut to match."""
        n = check_int(n, "subset(n): n", minimum=1)
        nq, nr = min(n, self.n_query), min(n, self.n_reference)
        soft = None if self.ground_truth_soft is None else self.ground_truth_soft[:nq, :nr].copy()
        homs = None if self.homographies is None else self.homographies[:nq].copy()
        return PlaceDataset(
            name=self.name,
            query_paths=self.query_paths[:nq],
            reference_paths=self.reference_paths[:nr],
            ground_truth=self.ground_truth[:nq, :nr].copy(),
            tolerance=self.tolerance,
            root=self.root,
            homographies=homs,
            meta={**self.meta, "subset": (nq, nr)},
            ground_truth_soft=soft,
        )

    def with_tolerance(self, tolerance: int) -> PlaceDataset:
        """This dataset with its frame-aligned ground truth at ``tolerance`` frames
        (``|q - r| <= tolerance``), as loading it with ``tolerance=`` gives; the images are the
        same, so a run reuses every cached landmark, descriptor and Eq. (1) matrix.

        Refused, naming the fix, for ground truth that is not frame-aligned (a file's, widened
        when it was loaded; a distance rule; soft): load the dataset again with ``tolerance=``.
        """
        if not self.meta.get("frame_aligned") or self.ground_truth_soft is not None:
            rule = self.meta.get("ground_truth_rule", "not frame-aligned")
            raise ValueError(
                f"{self.name!r}.with_tolerance({tolerance!r}): its ground truth is {rule}, not "
                "frame-aligned (|q - r| <= tolerance), so it cannot be rebuilt here; load the "
                f"dataset again with tolerance={tolerance!r} (load_dataset(name, root, "
                f"tolerance={tolerance!r})): the Eq. (1) matrices are reused from the cache"
            )
        t = check_tolerance(tolerance)
        meta = dict(self.meta)
        if "ground_truth_rule" in meta:
            meta["ground_truth_rule"] = re.sub(r"<=\d+", f"<={t}", meta["ground_truth_rule"])
        out = replace(
            self,
            ground_truth=frame_aligned(self.n_query, self.n_reference, t),
            tolerance=t,
            meta=meta,
        )
        out._keys.update(self._keys)  # same files: their content keys and sizes carry over
        out._sizes.update(self._sizes)
        return out

    def gt_pairs(self) -> list[tuple[int, int]]:
        """All ``(q, r)`` with ``ground_truth[q, r]`` True, row-major order."""
        return [(int(q), int(r)) for q, r in np.argwhere(self.ground_truth)]

    @property
    def n_query(self) -> int:
        """Number of query images ``Nq``."""
        return len(self.query_paths)

    @property
    def n_reference(self) -> int:
        """Number of reference images ``Nr``."""
        return len(self.reference_paths)

    @property
    def queries_with_ground_truth(self) -> int:
        """Number of queries with at least one true reference (the others are dropped from
        every metric); print it as "queries with ground truth: N of M"."""
        return int(self.ground_truth.any(axis=1).sum())

    def __len__(self) -> int:
        return len(self.query_paths)

    def __repr__(self) -> str:
        return (
            f"PlaceDataset(name={self.name!r}, n_query={self.n_query}, "
            f"n_reference={self.n_reference}, gt_pairs={int(self.ground_truth.sum())}, "
            f"tolerance={self.tolerance}, root={str(self.root) if self.root else None!r}, "
            f"homographies={'yes' if self.homographies is not None else 'no'})"
        )
