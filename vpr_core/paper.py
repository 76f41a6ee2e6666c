"""The paper's constants, written once: every other module imports them from here. Section,
table, equation and algorithm numbers are the paper's; docs/PAPER_MAP.md maps them to code."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pandas as pd

__all__ = [
    "ALEXNET_CONV3_DIM",
    "ALEXNET_INPUT",
    "DENSE_PER_SCALE",
    "DENSE_SCALES",
    "FIG7_NMS_THRESHOLDS",
    "FIG7_SOFT_NMS_THRESHOLDS",
    "MIN_SCALE_INDEX",
    "NMS_IOU",
    "N_CANDIDATES",
    "N_LANDMARKS",
    "N_SCALES",
    "PROJECTION_DIM",
    "SCALE_EDGES",
    "SCALE_LABELS",
    "SCALE_PRIORITY_ORDER",
    "SCALE_RANGES",
    "SCALE_RANGE_LABELS",
    "SOFT_NMS_IOU",
    "SOFT_NMS_SIGMA",
    "TABLE2",
    "TABLE3",
    "TABLE4",
    "dense_set_label",
    "dense_settings",
    "table1",
]

# ---- landmark counts (Sec. 2.1, 3.2) ----------------------------------------------------------
#: Landmarks per image in every scheme.
N_LANDMARKS: int = 100
#: Edge Box candidates per image that the selection / overlap schemes choose from.
N_CANDIDATES: int = 1000

# ---- Table 1 and Eq. (3): nine scales of the normalised scale (box area / image area) ---------
#: Inner bin edges of Table 1; lower edge inclusive.
SCALE_EDGES: tuple[float, ...] = (0.02, 0.05, 0.09, 0.14, 0.23, 0.34, 0.5, 0.72)
#: Number of Table-1 scales (indices 1..9).
N_SCALES: int = len(SCALE_EDGES) + 1
#: ``(low, high)`` of Scale i at ``SCALE_RANGES[i - 1]``.
SCALE_RANGES: tuple[tuple[float, float], ...] = tuple(
    zip((0.0,) + SCALE_EDGES, SCALE_EDGES + (1.0,), strict=False)
)
#: ``"Scale 1"`` .. ``"Scale 9"`` (``SCALE_LABELS[i - 1]`` for Scale i).
SCALE_LABELS: tuple[str, ...] = tuple(f"Scale {i}" for i in range(1, N_SCALES + 1))
#: Table 1's range labels, e.g. ``"0.02~0.05"`` (``SCALE_RANGE_LABELS[i - 1]`` for Scale i).
SCALE_RANGE_LABELS: tuple[str, ...] = tuple(f"{lo:g}~{hi:g}" for lo, hi in SCALE_RANGES)

# ---- Algorithms 1-4 ---------------------------------------------------------------------------
#: Algorithm 1 (selection Scheme 1): keep candidates whose scale index is >= this ("> Scale 3").
MIN_SCALE_INDEX: int = 4
#: Algorithm 2 (selection Scheme 2): scale priority.
SCALE_PRIORITY_ORDER: tuple[int, ...] = (5, 6, 7, 8, 9, 4)
#: Algorithm 3 (overlap Scheme 1, NMS): default IoU threshold.
NMS_IOU: float = 0.5
#: Algorithm 4 (overlap Scheme 2, soft-NMS on matched pairs): default overlap threshold.
SOFT_NMS_IOU: float = 0.5
#: Algorithm 4: Gaussian decay ``exp(-IoU^2 / sigma)``.
SOFT_NMS_SIGMA: float = 0.5
#: Fig. 7a: NMS thresholds swept.
FIG7_NMS_THRESHOLDS: tuple[float, ...] = (0.4, 0.5, 0.6, 0.7)
#: Fig. 7b: soft-NMS thresholds swept.
FIG7_SOFT_NMS_THRESHOLDS: tuple[float, ...] = (0.3, 0.4, 0.5, 0.6, 0.7)

# ---- Sec. 4: dense multi-scale sampling -------------------------------------------------------
#: The proposed dense landmarks: four normalised scales ...
DENSE_SCALES: tuple[float, ...] = (0.16, 0.25, 0.36, 0.49)
#: ... with 25 landmarks (a 5 x 5 grid) at each.
DENSE_PER_SCALE: int = 25

#: Table 2: number of scale levels (setting -> (scales, per_scale)).
TABLE2: dict[str, tuple[tuple[float, ...], int]] = {
    "Set 1": ((0.25,), 100),
    "Set 2": ((0.49,), 100),
    "Set 3": ((0.25, 0.49), 49),
    "Set 4": ((0.16, 0.36), 49),
    "Set 5": (DENSE_SCALES, DENSE_PER_SCALE),
    "Set 6": ((0.09, 0.18, 0.25, 0.33, 0.41, 0.49), 16),
}
#: Table 3: landmarks per scale at the dense scales.
TABLE3: dict[str, tuple[tuple[float, ...], tuple[int, ...]]] = {
    "Set 1": (DENSE_SCALES, (25, 25, 25, 25)),
    "Set 2": (DENSE_SCALES, (36, 25, 25, 16)),
    "Set 3": (DENSE_SCALES, (36, 36, 16, 16)),
    "Set 4": (DENSE_SCALES, (49, 25, 16, 9)),
    "Set 5": (DENSE_SCALES, (49, 36, 9, 9)),
}
#: Table 4: normalised scales with 25 landmarks per scale.
TABLE4: dict[str, tuple[tuple[float, ...], int]] = {
    "Set 1": (DENSE_SCALES, DENSE_PER_SCALE),
    "Set 2": ((0.18, 0.27, 0.38, 0.51), 25),
    "Set 3": ((0.09, 0.20, 0.32, 0.44), 25),
    "Set 4": ((0.20, 0.32, 0.44, 0.54), 25),
}

# ---- Sec. 2.1: the landmark descriptor --------------------------------------------------------
#: Random-projection output dimension.
PROJECTION_DIM: int = 1024
#: AlexNet input size for a landmark crop.
ALEXNET_INPUT: int = 227
#: AlexNet conv3 descriptor length (13 x 13 x 384).
ALEXNET_CONV3_DIM: int = 13 * 13 * 384


# ---- the tables as a reader sees them -----------------------------------------------------------
def table1() -> pd.DataFrame:
    """Table 1: ``(9, 3)`` DataFrame of each scale's range label, lower (incl.) and upper edge."""
    return pd.DataFrame(
        {
            "scale index": list(SCALE_LABELS),
            "normalized scale": list(SCALE_RANGE_LABELS),
            "lower (incl.)": [lo for lo, _ in SCALE_RANGES],
            "upper": [hi for _, hi in SCALE_RANGES],
        }
    ).set_index("scale index")


def dense_settings(table: dict[str, Any]) -> pd.DataFrame:
    """:data:`TABLE2`, :data:`TABLE3` or :data:`TABLE4` as a DataFrame, one row per setting."""
    rows = []
    for name, (scales, per_scale) in table.items():
        counts = per_scale if isinstance(per_scale, tuple) else (per_scale,) * len(scales)
        rows.append(
            {
                "setting": name,
                "normalized scales": scales,
                "landmarks per scale": counts,
                "total": int(sum(counts)),
            }
        )
    return pd.DataFrame(rows).set_index("setting")


def dense_set_label(name: str, scales: Sequence[float], per_scale: int | tuple[int, ...]) -> str:
    """Legend label of a dense setting, e.g. ``"Set 3: 0.25/0.49 x 49"``."""
    n = "/".join(map(str, per_scale)) if isinstance(per_scale, tuple) else str(per_scale)
    return f"{name}: {'/'.join(f'{s:g}' for s in scales)} x {n}"
