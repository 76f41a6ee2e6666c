"""The study's figures, listed once: file stem -> notebook, paper item and plot title.

The runner checks after each notebook that its figures exist; the tests and
``docs/PAPER_MAP.md`` use the same list. A figure method of :class:`~vpr_core.study.Study`
saves under the stem given here.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FIGURES", "FigureSpec", "expected_figures", "figure_spec"]


@dataclass(frozen=True)
class FigureSpec:
    """One expected figure file.

    Attributes:
        stem: file stem under ``figures/<label>/`` (``.png``).
        notebook: the notebook (stem) that writes it.
        paper: the paper item it reproduces (``"Fig. 5"``), or what it shows when the paper has
            no such figure.
        title: the plot title of PR-curve figures (None: the figure method builds its own).
    """

    stem: str
    notebook: str
    paper: str
    title: str | None = None


_NB1, _NB2, _NB3 = "01_pipeline_tour", "02_scale_statistics", "03_landmark_selection"
_NB4, _NB5, _NB6 = "04_overlap", "05_dense_sampling_parameters", "06_comparison"

#: Every figure the notebooks write, in notebook order.
FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("examples", _NB1, "Sec. 5.2: example reference/query pairs"),
    FigureSpec("tour1_dense_sampling", _NB1, "Sec. 4: dense_sampling on one pair"),
    FigureSpec("tour2_descriptors", _NB1, "Sec. 2.1: LandmarkEncoder.encode, descriptors"),
    FigureSpec("tour3_reciprocal_matches", _NB1, "Sec. 2.1: reciprocal_matches"),
    FigureSpec("tour4_image_similarity", _NB1, "Eq. 1-2: image_similarity, per-pair terms"),
    FigureSpec("fig03_classical_pipeline", _NB1, "Fig. 3"),
    FigureSpec("fig08_dense_pipeline", _NB1, "Fig. 8"),
    FigureSpec("fig09_dense_scales", _NB1, "Fig. 9"),
    FigureSpec("fig14_coverage", _NB1, "Fig. 14"),
    FigureSpec("fig01_labelled_matches", _NB2, "Fig. 1"),
    FigureSpec("fig02_irrelevant_matches", _NB2, "Fig. 2"),
    FigureSpec("fig04a_cmr", _NB2, "Fig. 4a"),
    FigureSpec("fig04b_cls", _NB2, "Fig. 4b"),
    FigureSpec("fig04c_asl", _NB2, "Fig. 4c"),
    FigureSpec("fig04_scale_statistics", _NB2, "Fig. 4"),
    FigureSpec("fig05_selection", _NB3, "Fig. 5", "Fig. 5: landmark selection schemes"),
    FigureSpec("fig06a_scheme1_scales", _NB3, "Fig. 6a"),
    FigureSpec("fig06b_scheme2_scales", _NB3, "Fig. 6b"),
    FigureSpec("fig07a_overlap_nms", _NB4, "Fig. 7a", "Fig. 7a: NMS on landmarks (Alg. 3)"),
    FigureSpec("fig07b_overlap_soft_nms", _NB4, "Fig. 7b",
               "Fig. 7b: soft-NMS on matches (Alg. 4)"),
    FigureSpec("fig10_scale_levels", _NB5, "Fig. 10 / Table 2"),
    FigureSpec("fig11_landmarks_per_scale", _NB5, "Fig. 11 / Table 3"),
    FigureSpec("fig12_normalized_scales", _NB5, "Fig. 12 / Table 4"),
    FigureSpec("fig13_comparison", _NB6, "Fig. 13", "Fig. 13: dense vs selection vs classical"),
    FigureSpec("fig14_coverage_comparison", _NB6, "Fig. 14"),
)


def figure_spec(stem: str) -> FigureSpec:
    """The registry entry of a figure stem.

    Raises:
        KeyError: unknown stem (the message lists the valid ones).
    """
    for spec in FIGURES:
        if spec.stem == stem:
            return spec
    raise KeyError(f"Unknown figure {stem!r}; registered: {', '.join(s.stem for s in FIGURES)}.")


def expected_figures() -> dict[str, list[str]]:
    """``{notebook stem: [figure stems]}`` in notebook order."""
    out: dict[str, list[str]] = {}
    for spec in FIGURES:
        out.setdefault(spec.notebook, []).append(spec.stem)
    return out
