"""The two values every matching call receives: :class:`Matching` (what Eq. (1) computes) and
:class:`Compute` (how its blocks run); each checks its fields once, in its constructor."""

from __future__ import annotations

import dataclasses

from ..checks import check_choice, check_device, check_int, is_number
from ..paper import SOFT_NMS_SIGMA
from .normalise import NORMALISATIONS
from .weighting import WEIGHTINGS

__all__ = [
    "SPATIAL_OPTIONS",
    "Compute",
    "Matching",
    "as_matching",
]

#: (Not in the paper.) Names of the geometry-aware re-scorings of ``spatial=``
#: (docs/DEFINITIONS.md, "(not in the paper) geometry-aware score").
SPATIAL_OPTIONS = ("consistency",)


def _bad(obj: object, key: str, expected: str) -> ValueError:
    value = getattr(obj, key)
    return ValueError(
        f"{type(obj).__name__}: option {key}={value!r} is not valid; expected {expected}"
    )


def _names(options: tuple[str, ...]) -> str:
    return ", ".join(map(repr, options))


@dataclasses.dataclass(frozen=True)
class Matching:
    """How two images' landmarks are scored: Eq. (1), with Algorithm 4 (soft-NMS on the match
    scores) at IoU ``soft_nms_iou`` and Gaussian ``sigma`` when ``soft_nms_iou`` is set, and
    (not in the paper) a geometry-aware re-scoring of the matches when ``spatial`` is set
    (:data:`SPATIAL_OPTIONS`) and a database weighting of the terms when ``weighting`` is set
    (a name of :data:`~.weighting.WEIGHTINGS`), a normalisation of the whole matrix after
    Eq. (1) when ``normalise`` is set (a name of :data:`~.normalise.NORMALISATIONS`: a step on
    the matrix, applied once to a result; docs/DEFINITIONS.md), and the landmark descriptors
    whitened on the reference database before Eq. (1) when ``whiten`` (the components kept, an
    int >= 1) is set (a step on the descriptors, :data:`~.whiten.DESCRIPTOR_STEPS`, applied by
    ``run_method``; docs/DEFINITIONS.md)."""

    soft_nms_iou: float | None = None
    sigma: float = SOFT_NMS_SIGMA
    spatial: str | None = None
    weighting: str | None = None
    normalise: str | None = None
    whiten: int | None = None

    def __post_init__(self) -> None:
        iou, sigma = self.soft_nms_iou, self.sigma
        if iou is not None:
            if not (is_number(iou) and 0 <= iou <= 1):
                raise _bad(self, "soft_nms_iou", "a number in [0, 1] or None (off)")
            object.__setattr__(self, "soft_nms_iou", float(iou))
        if not (is_number(sigma) and sigma > 0):
            raise _bad(self, "sigma", "a positive number")
        object.__setattr__(self, "sigma", float(sigma))
        if self.spatial is not None and self.spatial not in SPATIAL_OPTIONS:
            raise _bad(
                self,
                "spatial",
                f"None or one of {_names(SPATIAL_OPTIONS)} (geometry-aware "
                "score, not in the paper)",
            )
        if self.weighting is not None and self.weighting not in WEIGHTINGS:
            raise _bad(
                self,
                "weighting",
                f"None or one of {_names(tuple(WEIGHTINGS))} (database "
                "weighting, not in the paper)",
            )
        if self.normalise is not None and self.normalise not in NORMALISATIONS:
            raise _bad(
                self,
                "normalise",
                f"None or one of {_names(tuple(NORMALISATIONS))} (matrix normalisation, not "
                "in the paper)",
            )
        if self.whiten is not None:
            try:
                object.__setattr__(self, "whiten", check_int(self.whiten, "whiten", 1))
            except ValueError:
                raise _bad(
                    self,
                    "whiten",
                    "None or an integer >= 1 (the components kept by the whitening of the "
                    "landmark descriptors, e.g. 256; not in the paper)",
                ) from None

    def options(self) -> tuple[str, ...]:
        """The options that change a result: ``spatial``, ``weighting``, ``normalise`` and
        ``whiten`` always, the soft-NMS pair with it on."""
        nms = ("soft_nms_iou", "sigma") if self.soft_nms_iou is not None else ()
        return (*nms, "spatial", "weighting", "normalise", "whiten")

    def note(self) -> str:
        """Its legend text: soft-NMS IoU, whitening, geometry, weighting and normalisation;
        empty at the paper's Eq. (1)."""
        parts = [] if self.soft_nms_iou is None else [f"IoU {self.soft_nms_iou:g}"]
        if self.whiten is not None:
            parts.append(f"whitened: {self.whiten}")
        if self.spatial is not None:
            parts.append(f"geometry: {self.spatial}")
        if self.weighting is not None:
            parts.append(f"weighting: {self.weighting}")
        if self.normalise is not None:
            parts.append(f"normalised: {self.normalise}")
        if self.normalise is not None and NORMALISATIONS[self.normalise].needs_query_batch:
            parts.append("needs the query batch")
        return ", ".join(parts)


def as_matching(soft_nms_iou: float | None, sigma: float, matching: Matching | None) -> Matching:
    """The :class:`Matching` of a public call: ``matching``, or the paper's soft-NMS pair."""
    if matching is None:
        return Matching(soft_nms_iou, sigma)
    if not isinstance(matching, Matching):
        raise TypeError(f"matching must be a vpr_core.matching.Matching, got {matching!r}")
    if soft_nms_iou is not None or sigma != SOFT_NMS_SIGMA:
        raise ValueError(
            "soft-NMS is given twice: set it on matching=Matching(soft_nms_iou=..., sigma=...) "
            "or pass soft_nms_iou/sigma, not both"
        )
    return matching


@dataclasses.dataclass(frozen=True)
class Compute:
    """How the blocks of a matching call run; it changes the time, not the matches (float32
    similarities agree with ``matmul_dtype="float64"`` to ~1e-6). ``batch_size``: queries per
    block (None: 8); ``ref_batch_size``: references per block (None: ~8 MB of cosines);
    ``show_progress``: a progress bar over blocks (``TQDM_DISABLE=1`` silences it). ``device``:
    a torch device this machine has (checked here, once)."""

    device: str = "cpu"
    batch_size: int | None = None
    ref_batch_size: int | None = None
    matmul_dtype: str = "float32"
    show_progress: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "device", str(check_device(self.device)))
        for key in ("batch_size", "ref_batch_size"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, check_int(getattr(self, key), key, 1))
        check_choice(self.matmul_dtype, "matmul_dtype", ("float32", "float64"))
