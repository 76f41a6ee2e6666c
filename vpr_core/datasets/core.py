"""Place-recognition datasets: one loader per dataset, a registry, and the synthetic generator.

Every dataset is a :class:`PlaceDataset`: two lists of image files (query and reference
traverses) and a boolean ground-truth matrix ``(Nq, Nr)`` with the tolerance already applied.

Loaders (looked up by name in :data:`DATASETS`, called through :func:`load_dataset`):

``synthetic``
    The embedded default. Generated from a seed, written as PNG files into
    ``cache_dir("datasets", "synthetic-<hash>")``; no downloads. See :func:`load_synthetic`.
``gardens_point``
    Gardens Point Walking (Glover 2014): ``<root>/day_left|day_right|night_right/ImageNNN.jpg``.
``mapillary_berlin``
    Mapillary Berlin (Sunderhauf et al. RSS 2015): ``query/``, ``reference/`` and a
    correspondence list ``ground_truth.csv``.
``freiburg_across_seasons``
    Freiburg Across Seasons (Naseer et al. AAAI 2014): ``summer2015/``, ``winter2012/`` and
    ``ground_truth.csv`` (layout documented by us, unverified).
``folder``
    Any ``<root>/query/`` + ``<root>/reference/`` pair, ground truth from a file or frame-aligned.

Ground-truth files accepted by the file-based loaders:

* ``*.npy``: a ``(Nq, Nr)`` matrix of bools or 0/1 numbers.
* ``*.csv``: rows ``query,reference`` (an optional header row ``query,reference``; ``#``
  comments allowed). Each cell is a 0-based index into the naturally sorted image list
  (when it is all digits) or an image file name (``12.jpg``), a stem (``12`` is read as an
  index, so use the file name for numeric stems) or a path relative to the traverse folder.
  Several rows per query (one-to-many) and several queries per reference (many-to-one) are
  allowed; queries without a row have no ground truth (the evaluation drops them).

Tolerance: on frame-aligned traverses ``ground_truth[q, r] = |q - r| <= tolerance``; on a
correspondence file the listed matches are widened along the reference sequence by
``tolerance`` frames (``0``: exactly the listed pairs).
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import urllib.request
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..utils import file_fingerprint, logger

__all__ = [
    "DOWNLOADS",
    "IMAGE_EXTENSIONS",
    "PlaceDataset",
    "download_dataset",
    "list_images",
    "load_folder",
    "load_freiburg_across_seasons",
    "load_gardens_point",
    "load_mapillary_berlin",
    "read_ground_truth",
    "read_image",
]

SIDES = ("query", "reference")
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".ppm")


# ----------------------------------------------------------------------------------------------
# PlaceDataset
# ----------------------------------------------------------------------------------------------


@dataclass
class PlaceDataset:
    """Two traverses of image files and their ground truth.

    Attributes:
        name: Dataset name (``"synthetic"``, ``"gardens_point"``, ...).
        query_paths: ``Nq`` query image files, in traverse order.
        reference_paths: ``Nr`` reference image files, in traverse order.
        ground_truth: ``bool (Nq, Nr)``; ``ground_truth[q, r]`` is True when reference ``r``
            shows the place of query ``q`` (tolerance already applied).
        tolerance: Frame tolerance used to build ``ground_truth`` (None when not applicable).
        root: Folder the dataset was read from (or generated into).
        homographies: ``float64 (Nq, 3, 3)`` or None. ``homographies[i]`` maps query-``i``
            pixel coordinates ``(x, y, 1)`` to reference-``i`` pixel coordinates (known on
            ``synthetic`` only; None on real data).
        meta: Free-form details (layout, traverse names, generator parameters, ...).
    """

    name: str
    query_paths: list[Path]
    reference_paths: list[Path]
    ground_truth: np.ndarray
    tolerance: int | None
    root: Path | None = None
    homographies: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    _keys: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _sizes: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.query_paths = [Path(p) for p in self.query_paths]
        self.reference_paths = [Path(p) for p in self.reference_paths]
        if self.root is not None:
            self.root = Path(self.root)
        nq, nr = len(self.query_paths), len(self.reference_paths)
        gt = self.ground_truth
        if not isinstance(gt, np.ndarray):
            raise TypeError(
                f"PlaceDataset {self.name!r}: ground_truth must be a numpy bool array of shape "
                f"({nq}, {nr}), got {type(gt).__name__}; pass np.asarray(gt, dtype=bool)."
            )
        if gt.dtype != np.bool_:
            raise TypeError(
                f"PlaceDataset {self.name!r}: ground_truth must have dtype bool, got {gt.dtype}; "
                "convert it with `gt.astype(bool)` (after checking it only holds 0/1)."
            )
        if gt.shape != (nq, nr):
            raise ValueError(
                f"PlaceDataset {self.name!r}: ground_truth has shape {gt.shape} but there are "
                f"{nq} query and {nr} reference images, so it must be ({nq}, {nr}); "
                "fix the ground-truth file or the image folders so they agree."
            )
        if self.homographies is not None:
            h = np.asarray(self.homographies, dtype=np.float64)
            if h.shape != (nq, 3, 3):
                raise ValueError(
                    f"PlaceDataset {self.name!r}: homographies must have shape ({nq}, 3, 3), "
                    f"got {h.shape}; give one 3x3 query->reference mapping per query or None."
                )
            self.homographies = h

    # -- access ---------------------------------------------------------------------------------

    def paths(self, side: str) -> list[Path]:
        """The image files of one side (``"query"`` or ``"reference"``)."""
        if side == "query":
            return self.query_paths
        if side == "reference":
            return self.reference_paths
        raise ValueError(f"side must be 'query' or 'reference', got {side!r}.")

    def _path(self, side: str, i: int) -> Path:
        paths = self.paths(side)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"image index must be an int, got {type(i).__name__} ({i!r}).")
        if not 0 <= int(i) < len(paths):
            raise IndexError(
                f"{side} index {int(i)} out of range: dataset {self.name!r} has {len(paths)} "
                f"{side} images (valid indices 0..{len(paths) - 1})."
            )
        return paths[int(i)]

    def load_image(self, side: str, i: int) -> np.ndarray:
        """Read one image.

        Args:
            side: ``"query"`` or ``"reference"``.
            i: Index into that side's list, ``0 <= i < N``.

        Returns:
            ``uint8 (H, W, 3)`` RGB image.

        Raises:
            ValueError: bad side, or the file is not a readable image.
            IndexError: ``i`` out of range.
            FileNotFoundError: the file is gone.
        """
        path = self._path(side, i)
        img = read_image(path)
        self._sizes[(side, int(i))] = img.shape[:2]
        return img

    def image_size(self, side: str, i: int) -> tuple[int, int]:
        """``(H, W)`` of one image (read once, then memoised)."""
        key = (side, int(i)) if isinstance(i, (int, np.integer)) else None
        if key is not None and key in self._sizes and side in SIDES:
            return tuple(self._sizes[key])  # type: ignore[return-value]
        h, w = self.load_image(side, i).shape[:2]
        return int(h), int(w)

    def image_key(self, side: str, i: int) -> str:
        """Stable content key of one image for caches (sha1 of the file bytes, memoised)."""
        path = self._path(side, i)
        key = (side, int(i))
        if key not in self._keys:
            self._keys[key] = file_fingerprint(path)
        return self._keys[key]

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

    def __len__(self) -> int:
        return len(self.query_paths)

    def __repr__(self) -> str:
        return (
            f"PlaceDataset(name={self.name!r}, n_query={self.n_query}, "
            f"n_reference={self.n_reference}, gt_pairs={int(self.ground_truth.sum())}, "
            f"tolerance={self.tolerance}, root={str(self.root) if self.root else None!r}, "
            f"homographies={'yes' if self.homographies is not None else 'no'})"
        )


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as ``uint8 (H, W, 3)`` RGB (grey images are expanded to 3 channels).

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: OpenCV cannot decode it (not an image, truncated, or an unsupported format).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"image file not found: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError(
            f"{path} is not a readable image (OpenCV could not decode it; the file may be "
            "corrupt, truncated or in an unsupported format): replace or remove the file."
        )
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


# ----------------------------------------------------------------------------------------------
# Listing images and reading ground truth
# ----------------------------------------------------------------------------------------------


def _natural_key(name: str) -> list:
    return [(0, int(t), t) if t.isdigit() else (1, 0, t.lower()) for t in re.split(r"(\d+)", name)]


def list_images(folder: str | os.PathLike, what: str = "image folder") -> list[Path]:
    """Image files directly inside ``folder``, naturally sorted (``2.jpg`` before ``10.jpg``).

    Extensions (case-insensitive): jpg, jpeg, png, bmp, tif, tiff, ppm. Hidden files are skipped.

    Raises:
        FileNotFoundError: ``folder`` does not exist or is not a folder.
        ValueError: it holds no image file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(
            f"{what} not found: {folder} does not exist or is not a folder; create it and put "
            "the images there, or point `root` at the folder that contains it."
        )
    files = [
        p for p in folder.iterdir()
        if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in IMAGE_EXTENSIONS
    ]
    if not files:
        raise ValueError(
            f"{what} {folder} contains no images (looked for {', '.join(IMAGE_EXTENSIONS)}, "
            "any case); copy the images there or point `root` at the right folder."
        )
    return sorted(files, key=lambda p: _natural_key(p.name))


def _frame_aligned(nq: int, nr: int, tolerance: int) -> np.ndarray:
    q = np.arange(nq)[:, None]
    r = np.arange(nr)[None, :]
    return np.abs(q - r) <= tolerance


def _widen(gt: np.ndarray, tolerance: int) -> np.ndarray:
    """Widen a ``bool (Nq, Nr)`` match matrix by ``tolerance`` frames along the reference axis."""
    out = gt.copy()
    for t in range(1, min(int(tolerance), gt.shape[1]) + 1):
        out[:, t:] |= gt[:, :-t]
        out[:, :-t] |= gt[:, t:]
    return out


def _check_tolerance(tolerance: Any) -> int:
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, np.integer)) or tolerance < 0:
        raise ValueError(f"tolerance must be an int >= 0 (frames), got {tolerance!r}.")
    return int(tolerance)


def _name_index(paths: Sequence[Path], base: Path | None) -> dict[str, int]:
    index: dict[str, int] = {}
    stems: dict[str, list[int]] = {}
    for i, p in enumerate(paths):
        index[p.name] = i
        stems.setdefault(p.stem, []).append(i)
        if base is not None:
            try:
                index[p.relative_to(base).as_posix()] = i
            except ValueError:
                pass
    for stem, idx in stems.items():
        if len(idx) == 1:
            index.setdefault(stem, idx[0])
    return index


def read_ground_truth(
    path: str | os.PathLike,
    query_paths: Sequence[Path],
    reference_paths: Sequence[Path],
) -> np.ndarray:
    """Read a ground-truth file (``.npy`` matrix or ``.csv`` correspondence list).

    Args:
        path: ``*.npy`` with a ``(Nq, Nr)`` bool or 0/1 matrix, or ``*.csv`` with
            ``query,reference`` rows (indices or file names, see the module docstring).
        query_paths: The ``Nq`` query files (names resolve CSV cells).
        reference_paths: The ``Nr`` reference files.

    Returns:
        ``bool (Nq, Nr)`` match matrix (no tolerance applied).

    Raises:
        FileNotFoundError: no such file.
        ValueError: unknown format, a shape that does not fit the images, bad values or rows.
    """
    path = Path(path)
    nq, nr = len(query_paths), len(reference_paths)
    if not path.is_file():
        raise FileNotFoundError(
            f"ground-truth file not found: {path}; create it (a .npy (Nq, Nr) matrix or a .csv "
            "with query,reference rows) or pass ground_truth=<path> to the loader."
        )
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (OSError, ValueError, EOFError) as exc:  # what np.load raises on bad files
            raise ValueError(
                f"ground-truth file {path} is not a readable .npy array ({exc}); "
                "save it with np.save(path, matrix)."
            ) from None
        if arr.shape != (nq, nr):
            raise ValueError(
                f"ground truth {path} has shape {arr.shape} but the dataset has {nq} query and "
                f"{nr} reference images, so it must be ({nq}, {nr}); fix the matrix or the image "
                "folders so they agree."
            )
        if arr.dtype != np.bool_ and (
            not np.issubdtype(arr.dtype, np.number) or not np.isin(arr, (0, 1)).all()
        ):
            raise ValueError(
                f"ground truth {path} must hold bools or 0/1 numbers, got dtype {arr.dtype} "
                "with other values; save a bool matrix (gt.astype(bool))."
            )
        return arr.astype(bool)
    if suffix != ".csv":
        raise ValueError(
            f"unsupported ground-truth file {path}: use a .npy (Nq, Nr) matrix or a .csv with "
            "query,reference rows."
        )
    qnames = _name_index(query_paths, query_paths[0].parent if nq else None)
    rnames = _name_index(reference_paths, reference_paths[0].parent if nr else None)
    gt = np.zeros((nq, nr), dtype=bool)

    def resolve(cell: str, names: dict[str, int], n: int, side: str, line: int) -> int:
        if cell.isdigit():
            j = int(cell)
            if j >= n:
                raise ValueError(
                    f"{path}, line {line}: {side} index {j} out of range (the dataset has {n} "
                    f"{side} images, indices 0..{n - 1}); fix the file or the image folder."
                )
            return j
        if cell in names:
            return names[cell]
        raise ValueError(
            f"{path}, line {line}: {side} image {cell!r} is not in the {side} folder; use a file "
            f"name from that folder or a 0-based index."
        )

    n_rows = 0
    with open(path, newline="", encoding="utf-8") as f:
        for line, row in enumerate(csv.reader(f), start=1):
            cells = [c.strip() for c in row]
            if not cells or all(not c for c in cells) or cells[0].startswith("#"):
                continue
            if n_rows == 0 and [c.lower() for c in cells] == ["query", "reference"]:
                continue
            if len(cells) != 2:
                raise ValueError(
                    f"{path}, line {line}: expected 2 columns 'query,reference', got {len(cells)} "
                    f"({row!r}); write one query,reference pair per row."
                )
            q = resolve(cells[0], qnames, nq, "query", line)
            r = resolve(cells[1], rnames, nr, "reference", line)
            gt[q, r] = True
            n_rows += 1
    if n_rows == 0:
        raise ValueError(
            f"ground-truth file {path} has no query,reference rows; add one row per matching pair."
        )
    return gt


def _check_root(root: str | os.PathLike | None, name: str, layout: str) -> Path:
    if root is None:
        raise ValueError(
            f"dataset {name!r} needs root=<folder>: call load_dataset({name!r}, root='/path/to/"
            f"{name}'). Expected layout: {layout}"
        )
    root = Path(root).expanduser()
    if not root.exists():
        hint = f" or fetch it with download_dataset({name!r}, root)" if name in DOWNLOADS else ""
        raise FileNotFoundError(
            f"dataset root {root} does not exist: pass the folder that holds {name!r}{hint}. "
            f"Expected layout: {layout}"
        )
    if not root.is_dir():
        raise FileNotFoundError(f"dataset root {root} is not a folder. Expected layout: {layout}")
    return root


def _traverse_dir(base: Path, sub: str, name: str, layout: str) -> Path:
    d = base / sub
    if not d.is_dir():
        found = sorted(p.name for p in base.iterdir() if p.is_dir())
        raise FileNotFoundError(
            f"{name}: traverse folder {d} not found (subfolders present: {found or 'none'}). "
            f"Expected layout: {layout}; or pass the traverse names as options."
        )
    return d


def _correspondence_dataset(
    name: str,
    base: Path,
    query_dir: Path,
    reference_dir: Path,
    gt_file: Path,
    tolerance: int,
    meta: dict,
) -> PlaceDataset:
    qp = list_images(query_dir, f"{name} query folder")
    rp = list_images(reference_dir, f"{name} reference folder")
    gt = _widen(read_ground_truth(gt_file, qp, rp), tolerance)
    meta = dict(meta, ground_truth_file=str(gt_file), ground_truth_rule="correspondence file")
    return PlaceDataset(name, qp, rp, gt, tolerance, root=base, meta=meta)


# ----------------------------------------------------------------------------------------------
# Real-data loaders
# ----------------------------------------------------------------------------------------------

GARDENS_POINT_LAYOUT = (
    "<root>/day_left/Image000.jpg..Image199.jpg, <root>/day_right/..., <root>/night_right/... "
    "(frame i of one traverse is frame i of the others)"
)
GARDENS_POINT_TRAVERSES = ("day_left", "day_right", "night_right")


def load_gardens_point(
    root: str | os.PathLike | None = None,
    query: str = "day_left",
    reference: str = "night_right",
    tolerance: int = 2,
) -> PlaceDataset:
    """Gardens Point Walking (Glover 2014; Zenodo doi 10.5281/zenodo.4590133).

    Layout (the published one)::

        <root>/day_left/Image000.jpg ... Image199.jpg
        <root>/day_right/Image000.jpg ...
        <root>/night_right/Image000.jpg ...

    A root that holds a single ``GardensPointWalking/`` folder with that layout (as extracted
    from the archive) is accepted too. The traverses are frame-aligned: ground truth is
    ``|q - r| <= tolerance``. Tolerances in use differ (0, +-2 in VPR-Bench, +-3 in IROS-2015
    reproductions): always report the tolerance beside a number.

    Args:
        root: Dataset folder.
        query: Query traverse (``day_left``, ``day_right`` or ``night_right``).
        reference: Reference traverse.
        tolerance: Frames of slack in the frame-aligned ground truth.

    Returns:
        PlaceDataset with ``Nq = Nr = 200`` on the full dataset.
    """
    tolerance = _check_tolerance(tolerance)
    root = _check_root(root, "gardens_point", GARDENS_POINT_LAYOUT)
    for t in (query, reference):
        if t not in GARDENS_POINT_TRAVERSES:
            raise ValueError(
                f"gardens_point: unknown traverse {t!r}; valid: {', '.join(GARDENS_POINT_TRAVERSES)}."
            )
    base = root
    if not (root / query).is_dir() and (root / "GardensPointWalking" / query).is_dir():
        base = root / "GardensPointWalking"
        logger.info("gardens_point: using %s (the archive's top folder)", base)
    qp = list_images(_traverse_dir(base, query, "gardens_point", GARDENS_POINT_LAYOUT),
                     f"gardens_point {query} folder")
    rp = list_images(_traverse_dir(base, reference, "gardens_point", GARDENS_POINT_LAYOUT),
                     f"gardens_point {reference} folder")
    if len(qp) != len(rp):
        raise ValueError(
            f"gardens_point: {query} has {len(qp)} images but {reference} has {len(rp)}; the "
            "traverses are frame-aligned and must have the same count (re-extract the dataset)."
        )
    gt = _frame_aligned(len(qp), len(rp), tolerance)
    meta = {"query_traverse": query, "reference_traverse": reference,
            "ground_truth_rule": f"frame-aligned |q-r|<={tolerance}", "layout": GARDENS_POINT_LAYOUT}
    return PlaceDataset("gardens_point", qp, rp, gt, tolerance, root=base, meta=meta)


MAPILLARY_BERLIN_LAYOUT = (
    "<root>[/<sequence>]/query/*.jpg, <root>[/<sequence>]/reference/*.jpg, "
    "<root>[/<sequence>]/ground_truth.csv with rows query,reference"
)


def load_mapillary_berlin(
    root: str | os.PathLike | None = None,
    sequence: str | None = None,
    query: str = "query",
    reference: str = "reference",
    ground_truth: str | os.PathLike = "ground_truth.csv",
    tolerance: int = 0,
) -> PlaceDataset:
    """Mapillary Berlin (Sunderhauf et al. RSS 2015); layout documented by us.

    The paper's set has 157 query and 67 reference images from one Berlin street; the source
    has the sequences Halenseestrasse, Kudamm and A100, each with two traverses ``_1``/``_2``.
    The ground truth is a correspondence list (many queries may share one reference), not a
    frame alignment, so a file is required. Layout::

        <root>/query/*.jpg
        <root>/reference/*.jpg
        <root>/ground_truth.csv          # rows "query,reference" (file names or 0-based indices)

    With ``sequence="Kudamm"`` the same layout is read from ``<root>/Kudamm/``. To use the raw
    traverses directly, pass ``query="Kudamm_1", reference="Kudamm_2"`` (folder names).

    Args:
        root: Dataset folder.
        sequence: Optional sub-folder holding one sequence in the layout above.
        query: Query folder name (under the base folder).
        reference: Reference folder name.
        ground_truth: Correspondence file (``.csv`` or ``.npy``), relative to the base folder
            or absolute.
        tolerance: Frames by which listed matches are widened along the reference sequence.
    """
    tolerance = _check_tolerance(tolerance)
    root = _check_root(root, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
    base = _traverse_dir(root, sequence, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT) \
        if sequence else root
    qd = _traverse_dir(base, query, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
    rd = _traverse_dir(base, reference, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
    gt_file = Path(ground_truth) if Path(ground_truth).is_absolute() else base / ground_truth
    meta = {"sequence": sequence, "query_traverse": query, "reference_traverse": reference,
            "layout": MAPILLARY_BERLIN_LAYOUT}
    return _correspondence_dataset("mapillary_berlin", base, qd, rd, gt_file, tolerance, meta)


FREIBURG_LAYOUT = (
    "<root>/summer2015/*.jpg, <root>/winter2012/*.jpg, <root>/ground_truth.csv with rows "
    "query,reference (layout documented by vpr-landmarks, not verified against the release)"
)


def load_freiburg_across_seasons(
    root: str | os.PathLike | None = None,
    query: str = "summer2015",
    reference: str = "winter2012",
    ground_truth: str | os.PathLike = "ground_truth.csv",
    tolerance: int = 0,
) -> PlaceDataset:
    """Freiburg Across Seasons (Naseer et al. AAAI 2014), Summer 2015 vs Winter 2012.

    The layout below is UNVERIFIED: it is documented by this project (the original release
    keeps several images per place; the paper keeps one per place and matches them with a
    correspondence file). Prepare the data as::

        <root>/summer2015/*.jpg          # one image per place
        <root>/winter2012/*.jpg
        <root>/ground_truth.csv          # rows "query,reference" (file names or 0-based indices)

    Args:
        root: Dataset folder.
        query: Query traverse folder (default ``summer2015``).
        reference: Reference traverse folder (default ``winter2012``).
        ground_truth: Correspondence file (``.csv`` or ``.npy``), relative to root or absolute.
        tolerance: Frames by which listed matches are widened along the reference sequence.
    """
    tolerance = _check_tolerance(tolerance)
    root = _check_root(root, "freiburg_across_seasons", FREIBURG_LAYOUT)
    qd = _traverse_dir(root, query, "freiburg_across_seasons", FREIBURG_LAYOUT)
    rd = _traverse_dir(root, reference, "freiburg_across_seasons", FREIBURG_LAYOUT)
    gt_file = Path(ground_truth) if Path(ground_truth).is_absolute() else root / ground_truth
    meta = {"query_traverse": query, "reference_traverse": reference, "layout": FREIBURG_LAYOUT,
            "layout_verified": False}
    return _correspondence_dataset("freiburg_across_seasons", root, qd, rd, gt_file, tolerance,
                                   meta)


FOLDER_LAYOUT = (
    "<root>/query/*, <root>/reference/*, optional <root>/ground_truth.npy ((Nq, Nr) bool) or "
    "<root>/ground_truth.csv (query,reference rows); without one, query i <-> reference i"
)


def load_folder(
    root: str | os.PathLike | None = None,
    ground_truth: str | os.PathLike | None = None,
    tolerance: int = 0,
    query: str = "query",
    reference: str = "reference",
) -> PlaceDataset:
    """Any ``query/`` + ``reference/`` folder pair.

    Layout::

        <root>/query/*.jpg|png|...       # naturally sorted: 2.jpg before 10.jpg
        <root>/reference/*.jpg|png|...
        <root>/ground_truth.npy          # optional (Nq, Nr) bool / 0-1 matrix, or
        <root>/ground_truth.csv          # optional rows "query,reference"

    Ground truth: ``ground_truth=`` (a path) if given, else ``ground_truth.npy`` or
    ``ground_truth.csv`` in root (not both), else frame-aligned ``|q - r| <= tolerance``, which
    needs as many query as reference images.

    Args:
        root: Dataset folder.
        ground_truth: Explicit ground-truth file (relative to root or absolute).
        tolerance: Frames of slack (frame-aligned rule, or widening of a file's matches).
        query: Query folder name.
        reference: Reference folder name.
    """
    tolerance = _check_tolerance(tolerance)
    root = _check_root(root, "folder", FOLDER_LAYOUT)
    qp = list_images(_traverse_dir(root, query, "folder", FOLDER_LAYOUT), "query folder")
    rp = list_images(_traverse_dir(root, reference, "folder", FOLDER_LAYOUT), "reference folder")
    if ground_truth is None:
        found = [root / f for f in ("ground_truth.npy", "ground_truth.csv") if (root / f).is_file()]
        if len(found) > 1:
            raise ValueError(
                f"folder: both {found[0].name} and {found[1].name} exist in {root}; remove one "
                "or choose with ground_truth=<path>."
            )
        gt_file = found[0] if found else None
    else:
        gt_file = Path(ground_truth) if Path(ground_truth).is_absolute() else root / ground_truth
    meta: dict[str, Any] = {"query_traverse": query, "reference_traverse": reference,
                            "layout": FOLDER_LAYOUT}
    if gt_file is not None:
        gt = _widen(read_ground_truth(gt_file, qp, rp), tolerance)
        meta.update(ground_truth_file=str(gt_file), ground_truth_rule="file")
    else:
        if len(qp) != len(rp):
            raise ValueError(
                f"folder: {len(qp)} query but {len(rp)} reference images in {root}, so the "
                "frame-aligned rule (query i <-> reference i) does not apply; supply a ground-"
                "truth file (ground_truth.npy or ground_truth.csv in root, or ground_truth=<path>)."
            )
        gt = _frame_aligned(len(qp), len(rp), tolerance)
        meta["ground_truth_rule"] = f"frame-aligned |q-r|<={tolerance}"
    return PlaceDataset("folder", qp, rp, gt, tolerance, root=root, meta=meta)


# ----------------------------------------------------------------------------------------------
# Downloads
# ----------------------------------------------------------------------------------------------

DOWNLOADS: dict[str, dict[str, str | None]] = {
    "gardens_point": {
        # Zenodo record of Gardens Point Walking (doi 10.5281/zenodo.4590133).
        "url": "https://zenodo.org/records/4590133/files/GardensPointWalking.zip?download=1",
        # SHA-256 not known to us (no network when this was written): the download prints the
        # computed hash; put it here once it has been checked against Zenodo's listed checksum.
        "sha256": None,
    },
}

_MARKER = ".vpr_download.json"


def _safe_extract(zf: zipfile.ZipFile, dest: Path) -> list[str]:
    dest_r = dest.resolve()
    names = zf.namelist()
    for n in names:
        target = (dest / n).resolve()
        if target != dest_r and dest_r not in target.parents:
            raise ValueError(f"refusing to extract {n!r}: it would land outside {dest}.")
    zf.extractall(dest)
    return names


def download_dataset(
    name: str,
    root: str | os.PathLike,
    url: str | None = None,
    sha256: str | None = None,
    overwrite: bool = False,
) -> Path:
    """Download (and unzip) a dataset for users with internet access.

    Streams ``url`` (default: the :data:`DOWNLOADS` entry of ``name``) into ``root`` with a
    progress bar, checks its SHA-256 (``sha256`` or the registry's; when neither is known the
    computed hash is logged so it can be pinned), extracts a ``.zip`` into ``root`` and removes
    the archive. A marker file records a finished download; a second call returns at once
    unless ``overwrite``.

    Args:
        name: Dataset name (a :data:`DOWNLOADS` key unless ``url`` is given).
        root: Folder to download into (created).
        url: Override the download URL (any ``http(s)://`` or ``file://`` URL).
        sha256: Expected SHA-256 hex digest of the downloaded file.
        overwrite: Download again even if a finished download is recorded.

    Returns:
        The folder to pass as ``root=`` to :func:`load_dataset`: ``root`` itself, or its single
        top-level folder when the archive holds exactly one.

    Raises:
        ValueError: unknown name without ``url``, checksum mismatch (the file is removed), or a
            bad archive.
        OSError: network or file-system errors (with the URL in the message).
    """
    entry = DOWNLOADS.get(name)
    if entry is None and url is None:
        raise ValueError(
            f"no download known for {name!r}; downloadable: {', '.join(DOWNLOADS)}. For other "
            "datasets pass url=..., or download them by hand and use the layout in the loader's "
            "docstring."
        )
    url = url or str(entry["url"])  # type: ignore[index]
    expected = (sha256 or (entry or {}).get("sha256") or None)
    expected = expected.lower().strip() if expected else None
    root = Path(root).expanduser()
    root.mkdir(parents=True, exist_ok=True)
    marker = root / _MARKER
    if marker.is_file() and not overwrite:
        info = json.loads(marker.read_text())
        logger.info("%s already downloaded into %s (overwrite=True to fetch again)", name, root)
        return root / info.get("top", "") if info.get("top") else root
    fname = Path(urllib.request.url2pathname(url.split("?")[0].rstrip("/").split("/")[-1])).name
    fname = fname or f"{name}.download"
    part = root / (fname + ".part")
    digest = hashlib.sha256()
    from tqdm.auto import tqdm

    try:
        with urllib.request.urlopen(url, timeout=60) as resp:
            total = int(resp.headers.get("Content-Length") or 0) or None
            with open(part, "wb") as f, tqdm(total=total, unit="B", unit_scale=True,
                                              desc=f"download {name}", leave=False,
                                              disable=bool(os.environ.get("TQDM_DISABLE"))) as bar:
                for chunk in iter(lambda: resp.read(1 << 20), b""):
                    f.write(chunk)
                    digest.update(chunk)
                    bar.update(len(chunk))
    except OSError as exc:
        part.unlink(missing_ok=True)
        raise OSError(f"download of {name!r} from {url} failed: {exc}; check the URL and your "
                      f"connection, or download it by hand into {root}.") from exc
    got = digest.hexdigest()
    if expected is not None and got != expected:
        part.unlink(missing_ok=True)
        raise ValueError(
            f"SHA-256 mismatch for {url}: expected {expected}, got {got}; the file was removed. "
            "Retry (the download may be truncated) or check the URL / the expected hash."
        )
    if expected is None:
        logger.warning("%s: no SHA-256 known for %s; computed sha256=%s (pass sha256=... to "
                       "verify next time)", name, url, got)
    target = root / fname
    os.replace(part, target)
    top = ""
    if zipfile.is_zipfile(target):
        try:
            with zipfile.ZipFile(target) as zf:
                names = _safe_extract(zf, root)
        except zipfile.BadZipFile as exc:
            raise ValueError(f"{target} is not a valid zip archive ({exc}); download it again "
                             "with overwrite=True.") from None
        target.unlink()
        tops = {n.split("/")[0] for n in names if n.strip("/")}
        if len(tops) == 1 and (root / next(iter(tops))).is_dir():
            top = next(iter(tops))
        logger.info("%s: extracted %d entries into %s", name, len(names), root)
    marker.write_text(json.dumps({"name": name, "url": url, "sha256": got, "top": top}))
    return root / top if top else root

