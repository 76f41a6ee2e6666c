"""The study's figures: each one the notebooks write (:data:`FIGURES`), the notebook that writes
it and the paper item it reproduces."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FIGURES", "NOTEBOOKS", "expected_figures", "FigureSpec"]


@dataclass(frozen=True)
class FigureSpec:
    """One expected figure ``figures/<label>/<stem>.png``, the notebook that writes it and the
    paper item it reproduces (``"Fig. 5"``), or what it shows when the paper has no such figure."""

    stem: str
    notebook: str
    paper: str


#: The study notebooks (file stems), in order.
NOTEBOOKS = (
    "01_pipeline_tour",
    "02_scale_statistics",
    "03_landmark_selection",
    "04_overlap",
    "05_dense_sampling_parameters",
    "06_comparison",
    "07_places_alike",
)
_NB1, _NB2, _NB3, _NB4, _NB5, _NB6, _NB7 = NOTEBOOKS

#: Every figure the notebooks write, in notebook order.
FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("examples", _NB1, "Sec. 5.2: example reference/query pairs"),
    FigureSpec("tour1_edge_boxes", _NB1, "Sec. 2.1: edge_boxes on one pair"),
    FigureSpec("tour1_dense_sampling", _NB1, "Sec. 4: dense_sampling on one pair"),
    FigureSpec("tour2_descriptors", _NB1, "Sec. 2.1: LandmarkEncoder.encode, descriptors"),
    FigureSpec("tour3_reciprocal_matches", _NB1, "Sec. 2.1: reciprocal_matches"),
    FigureSpec("tour4_image_similarity", _NB1, "Eq. 1-2: image_similarity, per-pair terms"),
    FigureSpec("fig03_classical_pipeline", _NB1, "Fig. 3"),
    FigureSpec("fig08_dense_pipeline", _NB1, "Fig. 8"),
    FigureSpec("fig09_dense_scales", _NB1, "Fig. 9"),
    FigureSpec("fig01_labelled_matches", _NB2, "Fig. 1"),
    FigureSpec("fig02_irrelevant_matches", _NB2, "Fig. 2"),
    FigureSpec("fig04a_cmr", _NB2, "Fig. 4a"),
    FigureSpec("fig04b_cls", _NB2, "Fig. 4b"),
    FigureSpec("fig04c_asl", _NB2, "Fig. 4c"),
    FigureSpec("fig04_scale_statistics", _NB2, "Fig. 4"),
    FigureSpec("fig05_selection", _NB3, "Fig. 5"),
    FigureSpec("fig06a_scheme1_scales", _NB3, "Fig. 6a"),
    FigureSpec("fig06b_scheme2_scales", _NB3, "Fig. 6b"),
    FigureSpec("fig07a_overlap_nms", _NB4, "Fig. 7a"),
    FigureSpec("fig07b_overlap_soft_nms", _NB4, "Fig. 7b"),
    FigureSpec("fig10_scale_levels", _NB5, "Fig. 10 / Table 2"),
    FigureSpec("fig11_landmarks_per_scale", _NB5, "Fig. 11 / Table 3"),
    FigureSpec("fig12_normalized_scales", _NB5, "Fig. 12 / Table 4"),
    FigureSpec("own_scheme_and_backbone", _NB5, "not in the paper: a user scheme and backbone"),
    FigureSpec("fig13_comparison", _NB6, "Fig. 13"),
    FigureSpec("disagreements_dense_classical", _NB6, "not in the paper: per-query view"),
    FigureSpec("geometry_dense", _NB6, "not in the paper: geometry-aware score"),
    FigureSpec("geometry_classical", _NB6, "not in the paper: geometry-aware score"),
    FigureSpec("fig14_coverage_comparison", _NB6, "Fig. 14"),
    FigureSpec("weighting_dense", _NB6, "not in the paper: database weighting"),
    FigureSpec("weighting_classical", _NB6, "not in the paper: database weighting"),
    FigureSpec("places_alike_pr", _NB7, "beyond the paper: each method with each weighting"),
    FigureSpec("places_alike_carried", _NB7, "beyond the paper: landmarks that carried a top-1"),
    FigureSpec("places_alike_steps", _NB7, "beyond the paper: each method with each step"),
    FigureSpec("places_alike_vs_contrast", _NB7, "beyond the paper: each step against contrast"),
    FigureSpec("places_alike_changes", _NB7, "beyond the paper: what each step changed"),
    FigureSpec("places_alike_whitening", _NB7, "beyond the paper: what whitening does"),
)


def expected_figures() -> dict[str, list[str]]:
    """``{notebook stem: [figure stems]}`` in notebook order."""
    out: dict[str, list[str]] = {}
    for spec in FIGURES:
        out.setdefault(spec.notebook, []).append(spec.stem)
    return out
