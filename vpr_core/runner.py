"""Execute the study notebooks headless (papermill) and check their figures.

``vpr-study run`` and ``make study`` call :func:`run_study`. Each notebook in ``notebooks/``
is executed with its ``parameters`` cell overridden (dataset, root, backbone, quick), with the
working directory ``notebooks/``, into ``runs/<label>/<notebook>.ipynb``. Afterwards every
expected figure must exist in ``figures/<label>/``, else a clear error lists the missing ones.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from .utils import REPO_DIR, logger

NOTEBOOKS_DIR = REPO_DIR / "notebooks"

#: Figures each notebook writes to ``figures/<label>/`` (stems, ``.png``).
EXPECTED_FIGURES: dict[str, list[str]] = {
    "01_pipeline_tour": ["examples", "fig03_classical_pipeline", "fig08_dense_pipeline",
                         "fig09_dense_scales", "fig14_coverage"],
    "02_scale_statistics": ["fig01_labelled_matches", "fig02_irrelevant_matches", "fig04a_cmr",
                            "fig04b_cls", "fig04c_asl", "fig04_scale_statistics"],
    "03_landmark_selection": ["fig05_selection", "fig06a_scheme1_scales", "fig06b_scheme2_scales"],
    "04_overlap": ["fig07a_overlap_nms", "fig07b_overlap_soft_nms"],
    "05_dense_sampling_parameters": ["fig10_scale_levels", "fig11_landmarks_per_scale",
                                     "fig12_normalized_scales"],
    "06_comparison": ["fig13_comparison", "fig14_coverage_comparison"],
}


def notebook_paths(names: Sequence[str] | None = None) -> list[Path]:
    """The study notebooks (``notebooks/NN_*.ipynb``) in order, optionally a subset by stem."""
    paths = sorted(NOTEBOOKS_DIR.glob("[0-9][0-9]_*.ipynb"))
    if names:
        valid = {p.stem for p in paths}
        bad = [n for n in names if n not in valid]
        if bad:
            raise ValueError(f"Unknown notebook(s) {bad}; valid: {', '.join(sorted(valid))}.")
        paths = [p for p in paths if p.stem in names]
    if not paths:
        raise FileNotFoundError(f"No notebooks found in {NOTEBOOKS_DIR}.")
    return paths


def output_label(dataset: str, quick: bool) -> str:
    """The ``figures/`` and ``results/`` subfolder of a run."""
    return f"{dataset}_quick" if quick else dataset


def summary_table(label: str) -> pd.DataFrame:
    """All metrics rows written by the notebooks for ``label`` (``results/<label>/*.csv``)."""
    from .study import results_dir

    frames = []
    for csv in sorted(results_dir(label).glob("0[0-9]_*.csv")):
        df = pd.read_csv(csv)
        if "figure" in df.columns and "AUC(ratio)" in df.columns:
            df.insert(0, "notebook", csv.stem)
            frames.append(df)
    if not frames:
        return pd.DataFrame()
    return pd.concat(frames, ignore_index=True)


def run_study(dataset: str = "synthetic", root: str | None = None,
              backbone: str = "efficientnet_lite0", quick: bool = False,
              notebooks: Sequence[str] | None = None, kernel: str = "python3") -> pd.DataFrame:
    """Execute the notebooks with papermill and verify their figures.

    Returns:
        The summary metrics table (also printed).

    Raises:
        RuntimeError: a notebook failed (the message names it and the executed copy to open)
            or expected figures are missing.
    """
    import papermill as pm

    from .datasets import load_dataset
    from .viz import figures_dir

    if root is not None:  # notebooks run with cwd notebooks/: pass an absolute path
        root = str(Path(root).expanduser().resolve())
    load_dataset(dataset, root=root)  # fail fast, with the loader's clear message
    label = output_label(dataset, quick)
    out_dir = REPO_DIR / "runs" / label
    out_dir.mkdir(parents=True, exist_ok=True)
    params = {"dataset": dataset, "root": root, "backbone": backbone, "quick": quick}
    env_disable = os.environ.get("TQDM_DISABLE")
    missing: list[str] = []
    for nb in notebook_paths(notebooks):
        out = out_dir / nb.name
        t0 = time.perf_counter()
        logger.info("executing %s -> %s", nb.name, out)
        try:
            pm.execute_notebook(str(nb), str(out), parameters=params, cwd=str(NOTEBOOKS_DIR),
                                kernel_name=kernel, progress_bar=not env_disable,
                                log_output=False)
        except Exception as exc:  # papermill raises PapermillExecutionError with the cell
            raise RuntimeError(f"notebook {nb.name} failed; open {out} to see the failing cell:"
                               f"\n{exc}") from exc
        logger.info("%s done in %.1f s", nb.name, time.perf_counter() - t0)
        # notebooks on other datasets write the same figure names; check this run's label
        for stem in EXPECTED_FIGURES.get(nb.stem, []):
            if not (figures_dir(label) / f"{stem}.png").exists():
                missing.append(f"{label}/{stem}.png ({nb.stem})")
    if missing:
        raise RuntimeError("expected figures were not written: " + ", ".join(missing))
    table = summary_table(label)
    if not table.empty:
        with pd.option_context("display.width", 200, "display.max_rows", 200,
                               "display.float_format", "{:.3f}".format):
            cols = ["notebook", "figure", "method", "AUC(ratio)", "R@100P", "R@1"]
            print(f"\nSummary ({label}, backbone {backbone}):")
            print(table[cols].to_string(index=False))
    return table
