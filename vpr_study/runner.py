"""The study: which notebooks run on which datasets with which parameters (the real datasets of
``make study``, the quick test settings), executed headless by :mod:`vpr_study.execution` into
``<output root>/runs/<label>/``, then the summary of their tables and the paper's claims."""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from vpr_core import checks, load_dataset, settings
from vpr_study.catalogue import LABEL_NOTEBOOKS
from vpr_study.execution import run_labels
from vpr_study.figures import FIGURES, NOTEBOOKS
from vpr_study.findings import findings_document, read_table, result_labels
from vpr_study.tables import COMPARISON, check_table

from . import outputs

__all__ = [
    "NORDLAND_STUDY",
    "PARAMETER_TYPES",
    "QUICK_IMAGES",
    "QUICK_PLACES",
    "REAL_DATA_NOTEBOOKS",
    "check_parameters",
    "notebook_parameters",
    "notebook_paths",
    "notebooks_dir",
    "output_label",
    "run_study",
    "source_checkout",
    "study_datasets",
    "summary_table",
]

logger = logging.getLogger("vpr_core")

#: Places of the ``synthetic`` dataset in quick mode (the headless notebook tests).
QUICK_PLACES = 8
#: Images per side kept from a real dataset in quick mode (``PlaceDataset.subset``).
QUICK_IMAGES = 20


#: The Nordland subset of ``make study``: every 50th of the 3,576 places of
#: ``../shared/data/nordland_64x32`` (72 places, 500 original frames apart, so tolerance 0),
#: winter queries against summer references, ``roi`` pooling (one backbone pass per image: the
#: 64x32 frames make per-landmark crops as slow as full-size images for no extra detail).
NORDLAND_STUDY = {"dataset": "nordland", "options": {"step": 50, "tolerance": 0}, "pooling": "roi"}


def study_datasets() -> dict[str, dict]:
    """``{label: {"dataset", "root", "options", "pooling"}}`` of the real datasets beside the
    project for notebooks 03-07: ``../shared/data/gardens_point_mini`` (crop pooling) and
    ``nordland_64x32`` (:data:`NORDLAND_STUDY`) when present, and any ``VPR_DATASETS`` entries."""
    found: dict[str, dict] = {}
    checkout = source_checkout()
    if checkout is not None:
        data = checkout.parent / "shared" / "data"
        if (data / "gardens_point_mini").is_dir():
            found["gardens_point_mini"] = {
                "dataset": "folder",
                "root": str(data / "gardens_point_mini"),
                "options": {},
                "pooling": "crop",
            }
        if (data / "nordland_64x32").is_dir():
            found["nordland_step50"] = {**NORDLAND_STUDY, "root": str(data / "nordland_64x32")}
    for name, root in settings.extra_datasets().items():
        found[name] = {"dataset": name, "root": root, "options": {}, "pooling": "crop"}
    return found


#: The parameters every study notebook takes, with their types (checked by
#: :func:`check_parameters`).
PARAMETER_TYPES: dict[str, tuple[type, ...]] = {
    "dataset": (str,),
    "root": (str, type(None)),
    "options": (dict,),
    "limit": (int, type(None)),
    "label": (str, type(None)),
    "backbone": (str,),
    "pooling": (str,),
    "shortlist": (int, type(None)),
}


def check_parameters(quick: bool | None = None, **params) -> tuple[dict, int | None, str | None]:
    """Refuse notebook parameters of the wrong type with one TypeError line naming each and the
    fix (``options must be a dict such as {"tolerance": 0}, got a list``), and a ``limit`` or
    ``shortlist`` below 1 with a ValueError.

    Returns:
        ``(options, limit, label)``: as given, or, when ``quick`` (None: ``$VPR_QUICK``,
        :func:`vpr_core.settings.quick`, so a plain ``jupyter nbconvert --execute`` runs
        small), those of the small set of ``vpr-study run --quick``
        (:func:`notebook_parameters`): :data:`QUICK_PLACES` synthetic places or a real set's
        first :data:`QUICK_IMAGES` images, the label ending ``_quick``.
    """
    if quick is None:
        quick = settings.quick()
    if not isinstance(quick, bool):
        raise TypeError(f"notebook parameters: quick must be True, False or None, got {quick!r}")
    bad = []
    for name, value in params.items():
        types = PARAMETER_TYPES.get(name)
        if types is None or (isinstance(value, types) and not isinstance(value, bool)):
            continue
        want = " or ".join("None" if t is type(None) else t.__name__ for t in types)
        example = ' such as {"tolerance": 0}' if name == "options" else ""
        bad.append(f"{name} must be {want}{example}, got {type(value).__name__} {value!r}")
    if bad:
        raise TypeError("notebook parameters: " + "; ".join(bad))
    for name in ("limit", "shortlist"):  # `if limit:` in a notebook would run the whole set on 0
        value = params.get(name)
        if value is not None and value < 1:
            what = "all images" if name == "limit" else "exhaustive"
            raise ValueError(
                f"notebook parameters: {name} must be None ({what}) or >= 1, got {value}"
            )
    options, limit, label = params.get("options", {}), params.get("limit"), params.get("label")
    if not quick:
        return options, limit, label
    small = notebook_parameters(
        params.get("dataset", "synthetic"), quick=True, label=label, options=options
    )
    return small["options"], small["limit"] if limit is None else limit, small["label"]


def notebook_parameters(
    dataset: str,
    root: str | None = None,
    backbone: str = "efficientnet_lite0",
    quick: bool = False,
    label: str | None = None,
    options: dict | None = None,
    pooling: str = "crop",
    shortlist: int | None = None,
) -> dict:
    """The ``parameters`` cell values papermill injects into a study notebook (``quick`` among
    them, so the kernel's ``$VPR_QUICK`` never changes a run of the study).

    Quick mode: ``synthetic`` with :data:`QUICK_PLACES` places, a real dataset cut to its first
    :data:`QUICK_IMAGES` images (``limit``); the label gets ``_quick`` appended.
    """
    options = dict(options or {})
    limit = None
    if quick and dataset == "synthetic":
        options.setdefault("n_places", QUICK_PLACES)
    elif quick:
        limit = QUICK_IMAGES
    return {
        "dataset": dataset,
        "root": root,
        "backbone": backbone,
        "label": output_label(label or dataset, quick),
        "options": options,
        "pooling": pooling,
        "limit": limit,
        "shortlist": shortlist,
        "quick": quick,
    }


def source_checkout() -> Path | None:
    """The repository this package runs from (the folder holding ``pyproject.toml`` next to
    ``vpr_core/``), or None when the package is installed without its repository."""
    root = Path(__file__).resolve().parents[1]
    return root if (root / "pyproject.toml").is_file() else None


def notebooks_dir() -> Path:
    """The study notebooks' folder: ``notebooks/`` of the source checkout."""
    root = source_checkout()
    if root is None or not (root / "notebooks").is_dir():
        raise FileNotFoundError(
            "The study notebooks are not part of the installed package "
            f"({Path(__file__).resolve().parent}); run `vpr-study run` from a clone of the "
            "repository (pip install -e .), where notebooks/ sits beside vpr_core/."
        )
    return root / "notebooks"


def notebook_paths(names: Sequence[str] | None = None) -> list[Path]:
    """The study notebooks in order, optionally a subset by stem: the catalogue
    (:data:`vpr_study.figures.NOTEBOOKS`) by path, ``notebooks/<stem>.ipynb``. Any other
    notebook in ``notebooks/`` (a Lab duplicate, a user's own) is not the study's and never
    runs here."""
    folder = notebooks_dir()
    found = [folder / f"{stem}.ipynb" for stem in NOTEBOOKS]
    absent = [p.name for p in found if not p.is_file()]
    if absent:
        raise FileNotFoundError(
            f"study notebook(s) {', '.join(absent)} missing from {folder}; restore them with "
            f"`git checkout -- notebooks/` (the catalogue: vpr_study/figures.py NOTEBOOKS)"
        )
    if names:
        bad = [n for n in names if n not in NOTEBOOKS]
        if bad:
            raise ValueError(
                f"Unknown notebook(s) {bad}; the study's: {', '.join(NOTEBOOKS)} (run a notebook "
                "of your own in JupyterLab; its figures go under user/)."
            )
        found = [p for p in found if p.stem in names]
    return found


def output_label(dataset: str, quick: bool) -> str:
    """The ``figures/`` and ``results/`` subfolder of a run."""
    return f"{dataset}_quick" if quick and not dataset.endswith("_quick") else dataset


def summary_table(label: str) -> pd.DataFrame:
    """Every comparison table the notebooks saved for ``label`` (``results/<label>/fig*.csv``
    with an ``AUC`` column), one row per run, with the figure's notebook and stem."""
    notebook = {spec.stem: spec.notebook for spec in FIGURES}
    frames = []
    for csv in sorted(outputs.results_dir(label).glob("fig*.csv")):
        df = read_table(csv)  # a FIFO or a folder named like a table: refused by name
        if "AUC" in df.columns and "run" in df.columns:
            check_table(df, COMPARISON, csv)
            df.insert(0, "figure", csv.stem)
            df.insert(0, "notebook", notebook.get(csv.stem, "?"))
            frames.append(df)
    if not frames:
        return pd.DataFrame()
    return pd.concat(frames, ignore_index=True)


def _print_summary(table: pd.DataFrame, label: str, backbone: str) -> None:
    with pd.option_context(
        "display.width", 200, "display.max_rows", 200, "display.float_format", "{:.3f}".format
    ):
        want = ["notebook", "figure", "method", "AUC", "AUC lo", "AUC hi", "R@100P", "R@1"]
        cols = [c for c in [*want, "R@1 lo", "R@1 hi"] if c in table.columns]
        print(f"\nSummary ({label}, backbone {backbone}):")
        print(table[cols].to_string(index=False))


#: The comparison notebooks that ``make study`` also runs on the real datasets beside the
#: project (:func:`study_datasets`): 03-07 (07: places that look alike, beyond the paper).
REAL_DATA_NOTEBOOKS = NOTEBOOKS[2:]


def _write_findings(labels: Sequence[str]) -> None:
    """``results/findings.md``: the paper's claims against these labels' paired differences."""
    labels = result_labels(labels)  # this run's, then every other result folder
    text = findings_document(labels)
    out = outputs.results_dir() / "findings.md"
    out.write_text(text + "\n")
    print(f"\nThe paper's claims (dAUC [95% CI], paired bootstrap), also in {out}:\n{text}")


def run_study(
    dataset: str = "synthetic",
    root: str | Path | None = None,
    backbone: str = "efficientnet_lite0",
    quick: bool = False,
    notebooks: Sequence[str] | None = None,
    kernel: str = "python3",
    real_data: bool | None = None,
    label: str | None = None,
    options: dict | None = None,
    pooling: str = "crop",
    shortlist: int | None = None,
    force: bool = False,
    jobs: int = 1,
) -> pd.DataFrame:
    """Execute the notebooks (all, or the stems in ``notebooks``) with papermill, verify their
    figures and return the summary metrics table of ``dataset`` (also printed).

    ``real_data``: also run :data:`REAL_DATA_NOTEBOOKS` on every dataset of :func:`study_datasets`
    (default: on for the full ``synthetic`` study). ``label``: the output subfolder (default the
    dataset's name; ``_quick`` appended in quick mode). ``options``: loader options; ``pooling``
    and ``shortlist`` go to every ``run_method`` of the notebooks. A notebook whose inputs and
    recorded outputs are unchanged is not executed again unless ``force``
    (:mod:`vpr_study.memo`). ``jobs``: dataset labels executed at once, each in its own kernel
    (the outputs are the same for any count); every label runs, also after another failed.
    RuntimeError names each failed label with its failed notebook (and the executed copy to
    open), or the missing figures.
    """
    if isinstance(root, Path):
        root = str(root)
    check_parameters(
        quick=quick,
        dataset=dataset,
        root=root,
        options={} if options is None else options,
        label=label,
        backbone=backbone,
        pooling=pooling,
        shortlist=shortlist,
    )
    if label is not None:
        outputs.check_label(label)
    jobs = checks.check_int(jobs, "jobs (labels executed at once)", 1)
    if root is not None:
        root = str(Path(root).expanduser().resolve())
    # fail fast, with the loader's clear message (quick synthetic: only the places it uses)
    t_start = time.perf_counter()
    options = dict(options or {})
    load_dataset(
        dataset,
        root=root,
        **({"n_places": QUICK_PLACES, **options} if quick and dataset == "synthetic" else options),
    )
    if real_data is None:
        real_data = dataset == "synthetic" and not quick and label is None
    params = notebook_parameters(
        dataset, root, backbone, quick, label, options, pooling=pooling, shortlist=shortlist
    )
    label = params["label"]
    # a label the study does not commit (--quick, --label mine) writes under user/
    with outputs.study_outputs(label in LABEL_NOTEBOOKS):
        return _run_chains(
            label, params, notebooks, kernel, real_data, quick, backbone, force, jobs, t_start
        )


def _run_chains(
    label: str,
    params: dict,
    notebooks: Sequence[str] | None,
    kernel: str,
    real_data: bool,
    quick: bool,
    backbone: str,
    force: bool,
    jobs: int,
    t_start: float,
) -> pd.DataFrame:
    """:func:`run_study` after its checks: every label's notebooks, findings, summary."""
    selected = notebook_paths(notebooks)
    extra = study_datasets() if real_data else {}
    logger.info("figures and tables under %s", outputs.figures_root())
    chains = [(label, selected, params)]
    real_selected = [nb for nb in selected if nb.stem in REAL_DATA_NOTEBOOKS]
    for name, spec in extra.items():
        sub = output_label(name, quick)
        logger.info("real data: %s (%s, %s)", sub, spec["dataset"], spec["root"])
        sub_params = notebook_parameters(
            spec["dataset"],
            spec["root"],
            backbone,
            quick,
            label=name,
            options=spec.get("options", {}),
            pooling=spec.get("pooling", "crop"),
        )
        chains.append((sub, real_selected, sub_params))
    missing = run_labels(chains, kernel, force, jobs)
    if missing:
        raise RuntimeError("expected figures were not written: " + ", ".join(missing))
    table = summary_table(label)
    others = {output_label(n, quick): summary_table(output_label(n, quick)) for n in extra}
    if len(selected) == len(notebook_paths()):
        _write_findings([label, *others])
    if not table.empty:
        _print_summary(table, label, backbone)
    for sub, t in others.items():
        if not t.empty:
            _print_summary(t, sub, backbone)
    print(f"\nwrote, in {time.perf_counter() - t_start:.0f} s:")
    for sub in (label, *others):
        figs = sorted(outputs.figures_dir(sub).glob("*.png"))
        tables = [t for t in outputs.results_dir(sub).glob("*.csv") if ".timings" not in t.suffixes]
        print(
            f"  {len(figs)} figures in {outputs.figures_dir(sub)}, {len(tables)} tables in "
            f"{outputs.results_dir(sub)}, executed notebooks in {outputs.runs_dir(sub)}"
        )
    return table
