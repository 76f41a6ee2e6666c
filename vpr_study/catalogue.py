"""The catalogue of what the study writes under ``figures/`` and ``results/``: per output label,
the notebooks run for it (and the ``vpr-study`` commands of the Makefile), hence every figure and
table; anything else in those folders is not the study's (a user's or a test's stray file).

The study's notebooks are the list :data:`vpr_study.figures.NOTEBOOKS` (``notebooks/<stem>.ipynb``:
the runner, the memo, the save hook and the git filter read it; any other notebook in
``notebooks/`` or ``user/`` is the user's, and a label not in :data:`LABEL_NOTEBOOKS` writes under
``user/``). The figures are :data:`vpr_study.figures.FIGURES` (the runner checks after each
notebook that they were written); the tables are :data:`TABLES`. ``tests/test_study_outputs.py``
keeps the catalogue and the committed folders equal both ways (a file there that the catalogue
does not name fails, and so does a catalogued file that is missing), and checks the label lists
below against the Makefile's commands, so a notebook or command that starts writing a new file
fails the tests at the next ``make study`` until the catalogue names it."""

from __future__ import annotations

from pathlib import Path

from vpr_study.figures import FIGURES, NOTEBOOKS

__all__ = [
    "EVAL_OUTPUTS",
    "EXTRA_FIGURES",
    "FIGURES_FILES",
    "LABEL_NOTEBOOKS",
    "ONE_OFF",
    "RESULTS_FILES",
    "TABLES",
    "TIMINGS_ONLY",
    "figure_stems",
    "strays",
    "study_outputs",
]

#: Figures a notebook writes that :data:`~vpr_study.figures.FIGURES` does not list yet
#: (``{notebook stem: (figure stems)}``).
EXTRA_FIGURES: dict[str, tuple[str, ...]] = {}

#: The tables each notebook saves (``results/<label>/<stem>.csv``). ``table5_cost`` holds only
#: one machine's timings: it is written as the git-ignored ``table5_cost.timings.csv`` alone.
TABLES: dict[str, tuple[str, ...]] = {
    "01_pipeline_tour": (),
    "02_scale_statistics": ("fig04_scale_statistics", "fig04_matches"),
    "03_landmark_selection": ("fig05_selection", "fig06a_scheme1_scales", "fig06b_scheme2_scales"),
    "04_overlap": ("fig07a_overlap_nms", "fig07b_overlap_soft_nms"),
    "05_dense_sampling_parameters": (
        "fig10_scale_levels",
        "fig11_landmarks_per_scale",
        "fig12_normalized_scales",
        "own_scheme_and_backbone",
    ),
    "06_comparison": (
        "fig13_comparison",
        "disagreements_dense_classical",
        "geometry_dense",
        "geometry_classical",
        "fig14_coverage_comparison",
        "weighting_dense",
        "weighting_classical",
    ),
    "07_places_alike": (
        "places_alike",
        "places_alike_carried",
        "places_alike_steps",
        "places_alike_vs_contrast",
        "places_alike_changes",
        "places_alike_vs_best",
        "places_alike_whitening",
    ),
}

#: Tables of timings only (``<stem>.timings.csv``, git-ignored; no ``<stem>.csv``).
TIMINGS_ONLY: dict[str, tuple[str, ...]] = {"06_comparison": ("table5_cost",)}

#: The notebooks run for each label of the committed study: ``make study`` runs every notebook on
#: ``synthetic`` and notebooks 03-07 on each real dataset beside the project
#: (:func:`vpr_study.runner.study_datasets`); ``make study-nordland`` runs 05-07 on
#: ``nordland_step5``; ``nordland_step50_k25`` is the same shortlist on the 72-place subset and
#: ``nordland_step1`` notebook 07 on all 3,576 places (:data:`ONE_OFF`).
LABEL_NOTEBOOKS: dict[str, tuple[str, ...]] = {
    "synthetic": NOTEBOOKS,
    "gardens_point_mini": NOTEBOOKS[2:],
    "nordland_step50": NOTEBOOKS[2:],
    "nordland_step5": NOTEBOOKS[4:],
    "nordland_step50_k25": NOTEBOOKS[4:6],
    "nordland_step1": NOTEBOOKS[6:],
}

#: Labels no Makefile target writes, with the command that wrote them.
ONE_OFF: dict[str, str] = {
    "nordland_step50_k25": (
        "vpr-study run --dataset nordland --root ../shared/data/nordland_64x32 --step 50 "
        "--tolerance 0 --pooling roi --shortlist 25 --label nordland_step50_k25 "
        "--notebooks 05_dense_sampling_parameters 06_comparison"
    ),
    "nordland_step1": (  # about 22 GB of memory at its peak (docs/MEASUREMENTS.md)
        "VPR_TUNE_MALLOC=0 vpr-study run --dataset nordland --root ../shared/data/nordland_64x32 "
        "--step 1 --tolerance 0 --pooling roi --shortlist 25 --label nordland_step1 "
        "--notebooks 07_places_alike"
    ),
}

#: The ``vpr-study eval`` outputs of ``make study`` (``{label: (stems)}``: a figure and a table
#: each).
EVAL_OUTPUTS: dict[str, tuple[str, ...]] = {"synthetic": ("eval_synthetic_dense+classical",)}

#: Files directly under ``results/``: the findings table (``vpr-study findings --write`` and
#: ``vpr-study run``) and the benchmark tables (``make bench``, ``benchmarks/bench_*.py``).
RESULTS_FILES: tuple[str, ...] = (
    "findings.md",
    "benchmarks/descriptor_choice.csv",
    "benchmarks/descriptor_paired.csv",
    "benchmarks/study_profile.csv",
    "benchmarks/weighting.csv",
    "benchmarks/weighting_statistics.csv",
    "benchmarks/weighting_scaling.csv",
    "benchmarks/nordland_full.csv",
    "benchmarks/nordland_full_contrast.csv",
    "benchmarks/two_sided_cost_716.csv",
    "benchmarks/two_sided_cost_3576.csv",
    "benchmarks/whiten_cost_716.csv",
    "benchmarks/whiten_cost_3576.csv",
)

#: Files directly under ``figures/``: the benchmark figures (``benchmarks/bench_*.py``).
FIGURES_FILES: tuple[str, ...] = ("benchmarks/weighting_scaling.png",)


def figure_stems(notebook: str) -> list[str]:
    """The figures ``notebook`` writes (``figures/<label>/<stem>.png``)."""
    return [s.stem for s in FIGURES if s.notebook == notebook] + list(
        EXTRA_FIGURES.get(notebook, ())
    )


def study_outputs(labels: dict[str, tuple[str, ...]] | None = None) -> set[str]:
    """Every file the study writes under the output root, as POSIX paths relative to it
    (``figures/synthetic/fig05_selection.png``, ``results/findings.md``), for ``labels``
    (``{label: notebooks}``; default :data:`LABEL_NOTEBOOKS`). Timings files (git-ignored,
    one machine's) are not listed: :func:`is_study_output` accepts those of listed tables."""
    out = {f"results/{name}" for name in RESULTS_FILES}
    out |= {f"figures/{name}" for name in FIGURES_FILES}
    for label, notebooks in (LABEL_NOTEBOOKS if labels is None else labels).items():
        for nb in notebooks:
            out |= {f"figures/{label}/{stem}.png" for stem in figure_stems(nb)}
            out |= {f"results/{label}/{stem}.csv" for stem in TABLES.get(nb, ())}
        for stem in EVAL_OUTPUTS.get(label, ()):
            out |= {f"figures/{label}/{stem}.png", f"results/{label}/{stem}.csv"}
    return out


def _timings(labels: dict[str, tuple[str, ...]]) -> set[str]:
    out = set()
    for label, notebooks in labels.items():
        for nb in notebooks:
            stems = (*TABLES.get(nb, ()), *TIMINGS_ONLY.get(nb, ()))
            out |= {f"results/{label}/{s}.timings.csv" for s in stems}
        out |= {f"results/{label}/{s}.timings.csv" for s in EVAL_OUTPUTS.get(label, ())}
    return out


def strays(root: str | Path, labels: dict[str, tuple[str, ...]] | None = None) -> list[str]:
    """The files under ``root/figures`` and ``root/results`` that the study does not write
    (relative POSIX paths, sorted): not in :func:`study_outputs` nor the timings of a listed
    table."""
    root = Path(root)
    labels = LABEL_NOTEBOOKS if labels is None else labels
    known = study_outputs(labels) | _timings(labels)
    found = [
        p.relative_to(root).as_posix()
        for top in ("figures", "results")
        if (root / top).is_dir()
        for p in (root / top).rglob("*")
        if p.is_file() or p.is_symlink()
    ]
    return sorted(p for p in found if p not in known)
