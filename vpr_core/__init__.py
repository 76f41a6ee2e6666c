"""vpr_core: the pipeline of Yang et al., "Towards A Deep Insight into Landmark-based Visual Place
Recognition", by stage; this flat face is what callers use (``from vpr_core import ...``): the run,
its values and results, each stage's public functions, the shared modules (docs/ARCHITECTURE.md)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: Each module whose names the face holds, and those names ("": the module itself is handed
#: out). A name is imported on first use, so ``import vpr_core.settings`` (``vpr-study --help``)
#: loads no torch.
_MODULES: dict[str, tuple[str, ...]] = {
    "": ("checks", "paper", "paths", "settings", "utils"),
    # a run: its three values, the run itself, the result
    "run": ("run_method",),
    "methods": ("Method", "available_methods", "get_method", "step_between"),
    "features.encoder": ("Encoder", "LandmarkEncoder"),
    "backbones": ("available_backbones",),
    "evaluation.spec": ("Evaluation", "PROTOCOLS"),
    "matching.spec": ("Matching", "SPATIAL_OPTIONS"),
    "result": ("MethodResult", "normalise_result", "result_from_matrix"),
    "cost": ("cost_table",),
    # datasets
    "datasets": ("DATASETS", "load_dataset"),
    "datasets.safe_pickle": ("read_npy",),
    "datasets.base": ("PlaceDataset",),
    "datasets.ground_truth": ("ground_truth_references",),
    "cache": ("dataset_fingerprint",),
    # landmarks (Table 1, Algorithms 1-3, the schemes)
    "landmarks.schemes": (
        "Dense",
        "EdgeBoxesTop",
        "MinScale",
        "ReduceOverlap",
        "ScalePriority",
        "WholeImage",
    ),
    "landmarks.dense": ("dense_sampling",),
    "landmarks.edge_boxes": ("edge_boxes",),
    "landmarks.scales": ("normalized_scale", "scale_distribution", "scale_index"),
    "landmarks.selection": ("reduce_overlap", "select_min_scale", "select_scale_priority"),
    "landmarks.coverage": ("landmark_coverage",),
    "boxes": ("box_iou",),
    # matching: Eq. (1)-(2), Algorithm 4; the rooms of the steps not in the paper
    "matching.similarity": (
        "cosine_distance",
        "image_similarity",
        "match_landmarks",
        "reciprocal_matches",
        "shape_penalty",
        "similarity_matrix",
        "similarity_pairs",
    ),
    "matching.weighting": ("WEIGHTINGS", "Weighting"),
    "matching.blocks": ("plan_blocks",),
    "matching.normalise": ("NORMALISATIONS", "Normalisation"),
    # evaluation: curves, intervals, the comparison table, the per-query view
    "evaluation.curves": ("auc_pr", "pr_curve", "recall_at_k"),
    "evaluation.bootstrap": (
        "ON_PAR_MARGIN",
        "VERDICT_WORDS",
        "bootstrap_metrics",
        "claim_verdict",
        "paired_bootstrap",
    ),
    "evaluation.chance": ("chance",),
    "evaluation.compare": ("compact", "compare", "compare_pairs", "identical_to"),
    "evaluation.queries": ("per_query",),
    "evaluation.steps": ("carried_landmarks", "step_changes"),
    "evaluation.whitening": ("whitening_changes",),
    # Sec. 3.1: labelled matches and the scale statistics
    "labels": ("append_labels", "label_matches", "pair_matches"),
    "statistics": ("cmr_difference", "scale_statistics"),
    # process-wide settings a notebook makes where the reader sees them; notices
    "utils": ("configure_logging", "tune_allocator"),
    "notices": ("VPRWarning", "notice"),
}

_FACE = {name: module for module, names in _MODULES.items() for name in names}

#: The face, by name (tests/test_public_face.py: the same names as :data:`_MODULES`).
__all__ = [
    "__version__",
    "append_labels",
    "auc_pr",
    "available_backbones",
    "available_methods",
    "bootstrap_metrics",
    "box_iou",
    "carried_landmarks",
    "chance",
    "checks",
    "claim_verdict",
    "cmr_difference",
    "compact",
    "compare",
    "compare_pairs",
    "configure_logging",
    "cosine_distance",
    "cost_table",
    "dataset_fingerprint",
    "DATASETS",
    "Dense",
    "dense_sampling",
    "edge_boxes",
    "EdgeBoxesTop",
    "Encoder",
    "Evaluation",
    "get_method",
    "ground_truth_references",
    "identical_to",
    "image_similarity",
    "label_matches",
    "landmark_coverage",
    "LandmarkEncoder",
    "load_dataset",
    "match_landmarks",
    "Matching",
    "Method",
    "MethodResult",
    "MinScale",
    "Normalisation",
    "NORMALISATIONS",
    "normalise_result",
    "normalized_scale",
    "notice",
    "ON_PAR_MARGIN",
    "pair_matches",
    "paired_bootstrap",
    "paper",
    "paths",
    "per_query",
    "PlaceDataset",
    "plan_blocks",
    "pr_curve",
    "PROTOCOLS",
    "read_npy",
    "recall_at_k",
    "reciprocal_matches",
    "reduce_overlap",
    "ReduceOverlap",
    "result_from_matrix",
    "run_method",
    "scale_distribution",
    "scale_index",
    "scale_statistics",
    "ScalePriority",
    "select_min_scale",
    "select_scale_priority",
    "settings",
    "shape_penalty",
    "similarity_matrix",
    "similarity_pairs",
    "SPATIAL_OPTIONS",
    "step_between",
    "step_changes",
    "tune_allocator",
    "utils",
    "VERDICT_WORDS",
    "VPRWarning",
    "Weighting",
    "WEIGHTINGS",
    "whitening_changes",
    "WholeImage",
]


def __getattr__(name: str) -> Any:
    if name not in _FACE:
        raise AttributeError(f"module 'vpr_core' has no attribute {name!r}")
    module = importlib.import_module(f".{_FACE[name] or name}", __name__)
    value = getattr(module, name) if _FACE[name] else module
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_FACE))


if TYPE_CHECKING:
    from . import checks, paper, paths, settings, utils
    from .backbones import available_backbones
    from .boxes import box_iou
    from .cache import dataset_fingerprint
    from .cost import cost_table
    from .datasets import DATASETS, load_dataset
    from .datasets.base import PlaceDataset
    from .datasets.ground_truth import ground_truth_references
    from .datasets.safe_pickle import read_npy
    from .evaluation.bootstrap import (
        ON_PAR_MARGIN,
        VERDICT_WORDS,
        bootstrap_metrics,
        claim_verdict,
        paired_bootstrap,
    )
    from .evaluation.chance import chance
    from .evaluation.compare import compact, compare, compare_pairs, identical_to
    from .evaluation.curves import auc_pr, pr_curve, recall_at_k
    from .evaluation.queries import per_query
    from .evaluation.spec import PROTOCOLS, Evaluation
    from .evaluation.steps import carried_landmarks, step_changes
    from .evaluation.whitening import whitening_changes
    from .features.encoder import Encoder, LandmarkEncoder
    from .labels import append_labels, label_matches, pair_matches
    from .landmarks.coverage import landmark_coverage
    from .landmarks.dense import dense_sampling
    from .landmarks.edge_boxes import edge_boxes
    from .landmarks.scales import normalized_scale, scale_distribution, scale_index
    from .landmarks.schemes import (
        Dense,
        EdgeBoxesTop,
        MinScale,
        ReduceOverlap,
        ScalePriority,
        WholeImage,
    )
    from .landmarks.selection import reduce_overlap, select_min_scale, select_scale_priority
    from .matching.blocks import plan_blocks
    from .matching.normalise import NORMALISATIONS, Normalisation
    from .matching.similarity import (
        cosine_distance,
        image_similarity,
        match_landmarks,
        reciprocal_matches,
        shape_penalty,
        similarity_matrix,
        similarity_pairs,
    )
    from .matching.spec import SPATIAL_OPTIONS, Matching
    from .matching.weighting import WEIGHTINGS, Weighting
    from .methods import Method, available_methods, get_method, step_between
    from .notices import VPRWarning, notice
    from .result import MethodResult, normalise_result, result_from_matrix
    from .run import run_method
    from .statistics import cmr_difference, scale_statistics
    from .utils import configure_logging, tune_allocator
