# ---
# jupyter:
#   jupytext:
#     formats: ipynb,scripts//py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (vpr-landmarks)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 07 · Places that look alike (beyond the paper: the workbench's own contribution)
#
# **Not in the paper.** Everything in this notebook is this workbench's own idea, not a result
# of the paper that notebooks 01-06 reproduce. Eq. (1) counts a match on a wall, a floor tile or
# a row of identical windows, which look alike in every place, as much as a match on a rare
# object. The database-contrast weighting, `weighting="contrast"` (docs/DEFINITIONS.md, "(not
# in the paper) database weighting"), multiplies each match's term by how far its query
# landmark's cosine lies above that landmark's mean best cosine over all references, in standard
# deviations (0 at or below the mean): a landmark that matches every place about equally weighs
# about 0, one that matches this place far better than the others carries the score.
# `weighting="idf"` (the log of the references over those the landmark matches) is its simpler
# sibling. Notebook 06 keeps the paper's Fig. 13 / Table 5 unchanged.
#
# Where it helps, where it is inconclusive, where it hurts: the table below answers for the
# dataset chosen here with paired differences (each method with a weighting against the same
# method without it: `higher` / `lower` only when the 95% interval excludes 0, else
# `inconclusive`), beside the chance level of each metric. On the small sets of `make study`
# most differences are inconclusive (too few queries), so read the verdict column, not the sign.
#
# *Measured outside this repository by the reporter* (issue 46; held-out sets that are
# not in `../shared`, ground truth and metrics computed by code independent of this workbench,
# default backbone, crop pooling; not reproduced here):
#
# | held-out set | R@1 without -> with `contrast` |
# |---|---|
# | VPR-Bench indoor corridor (111 pairs) | Scheme 1 0.847 -> **0.937**, classical 0.865 -> 0.919, dense 0.604 -> 0.910 (best of ten published VPR-Bench techniques: 0.901) |
# | ESSEX3IN1 thumbnails | classical 0.600 -> 0.686, Scheme 1 0.614 -> 0.671, dense 0.519 -> 0.619 |
# | Gardens Point day/day | dense 0.390 -> 0.415 |
# | SPEDTest thumbnails (604 pairs) | helps classical 0.661 -> 0.679 and Scheme 1 0.667 -> 0.674, **hurts dense** 0.795 -> 0.780 (AUC 0.964 -> 0.958) |
#
# So: it helps most where places repeat (corridors, a train line), and it can hurt a method that
# already separates varied outdoor places well.

# %%
import pandas as pd
from matplotlib_inline.backend_inline import set_matplotlib_formats

from vpr_core import compact, compare, configure_logging, load_dataset, run_method, step_changes
from vpr_core import tune_allocator
from vpr_study import check_parameters
from vpr_study.viz import plot_carried_landmarks, plot_pr_curves, save
from vpr_study.viz import plot_paired_differences, plot_step_changes, plot_whitening

# Process-wide settings, made here where you see them (the library never changes them):
tune_allocator()  # glibc keeps freed memory for reuse: crop features ~1.7x faster, same bits
configure_logging(stream="stdout", silence_warnings=True)  # log lines (and warnings) as output
set_matplotlib_formats("jpeg")  # inline pictures of photos as JPEG (the saved files stay PNG)

# %% tags=["parameters"]
dataset = "synthetic"  # synthetic | gardens_point | mapillary_berlin | freiburg_across_seasons | nordland | vpr_bench | utm | folder
root = None  # the dataset's folder (all but synthetic)
options = {}  # loader options: {"n_places": 8} (synthetic), {"step": 50, "tolerance": 0} (nordland), {"positive_dist_threshold": 25} (utm)
limit = None  # keep only the first N queries and references (quick runs)
label = None  # subfolder of figures/ and results/ (default: the dataset's name)
backbone = "efficientnet_lite0"  # see vpr_core.available_backbones()
pooling = "crop"  # crop: the paper's per-landmark crops; roi: one backbone pass per image
shortlist = None  # None: exhaustive (the paper's); K: re-rank each query's top-K by Eq. (1)
quick = None  # True: the small set of `vpr-study run --quick`; None: $VPR_QUICK (1: small, e.g. a headless nbconvert)

# %%
options, limit, label = check_parameters(dataset=dataset, root=root, options=options, limit=limit, label=label,
                                         backbone=backbone, pooling=pooling, shortlist=shortlist, quick=quick)
ds = load_dataset(dataset, root=root, **options)
if limit:
    ds = ds.subset(limit)
label = label or ds.name
run_options = {"backbone": backbone, "pooling": pooling, "shortlist": shortlist}  # every run below
ds

# %% [markdown]
# ## Each method without and with each weighting
# The paper's three methods (classical, Scheme 1 = the selection scheme of notebook 03, dense
# sampling), each without a weighting (the paper's Eq. (1)) and with `contrast` and `idf`. Each
# block of three rows is one `compare` with the method's own unweighted run as the baseline, so
# every paired difference is "the same method with the weighting minus without"; the `chance`
# columns say what a random ranking would score. The runs of notebook 06 come from the cache.

# %%
runs, tables = [], []
for m in ("classical", "selection_scheme1", "dense"):
    trio = [run_method(m, ds, weighting=w, **run_options) for w in (None, "contrast", "idf")]
    runs += trio
    tables.append(compare(trio, baseline=m))
table = pd.concat(tables)
fig = plot_pr_curves(runs, title="(not in the paper) each method without and with a weighting")
save(fig, "places_alike_pr", label), save(table, "places_alike", label)
compact(table)  # as compare shows it, verdicts included (the CSV keeps every column)

# %% [markdown]
# ## Which landmarks carried the score
# For queries whose top-1 the contrast weighting changed (dense sampling; first one it fixed,
# then one it broke, if any): top, the 5 matches with the largest weighted Eq. (1) terms in the
# weighted run's top-1, each a query crop beside its reference crop with its cosine, its
# contrast weight `w` and the other place its query landmark matches best (`also rN`, with that
# cosine); below, in grey, the matches with the largest plain terms in the plain run's top-1
# that the weighting silenced (`w = 0`: they match another place about as well).

# %%
plain = run_method("dense", ds, keep_descriptors=True, **run_options)
weighted = run_method("dense", ds, weighting="contrast", keep_descriptors=True, **run_options)
fig, carried = plot_carried_landmarks(ds, plain, weighted, n_queries=2, k=5)
save(fig, "places_alike_carried", label), save(carried, "places_alike_carried", label)
carried

# %% [markdown]
# ## A two-sided contrast and a normalisation of the matrix (issue 55)
# Two hypotheses from outside the project, judged here before anything was tuned (the
# settings are fixed in docs/DEFINITIONS.md, "(not in the paper) two-sided contrast" and
# "normalisation of a similarity matrix"):
#
# - **two-sided contrast**, `weighting="two_sided"`: each match's term times `(1 + w_q)(1 + w_r)`,
#   `w_q` the query landmark's contrast weight (as `contrast`), `w_r` the same statistic of the
#   matched **reference** landmark over the other references (the database alone: computed once
#   per database, cached by its content).
# - **query-batch normalisation**, `normalise="query_batch"`: the matrix z-normalised per query over
#   the references plus per reference over the batch of queries. **It needs the batch of
#   queries** (the offline setting of a benchmark, not a single live query): the table's
#   `query batch` column says `needed` on those rows.
# - **database normalisation**, `normalise="database"` (for a single live query, CSLS-like):
#   each reference's score minus its mean similarity to its 10 nearest references.
#
# *Measured outside this repository by the reporter* (not reproduced here; R@1 /
# ratio-AUC): SPEDTest thumbnails (604) dense 0.795 / 0.964, two-sided 0.785 / 0.961,
# two-sided + query batch 0.829 / 0.977; indoor corridor (111) dense 0.604, two-sided 0.928,
# two-sided + query batch 0.955. Each block of rows below is one `compare` against the
# method's own plain run: `higher` / `lower` only where the 95% paired interval excludes 0. The
# figure draws each difference with its interval (green higher, red lower, grey: the interval
# holds 0); a method whose rows are another's, number for number, says so (`(= classical)`:
# on Nordland Scheme 1 keeps classical's boxes). `steps` names each step by its `run_method`
# options, and `step_runs[method][step]` is its run: a new step is one more line there.

# %%
steps = {  # each step by name: its run_method options
    "contrast": {"weighting": "contrast"},
    "two_sided": {"weighting": "two_sided"},
    "query_batch": {"normalise": "query_batch"},
    "database": {"normalise": "database"},
    "two_sided + query_batch": {"weighting": "two_sided", "normalise": "query_batch"},
    "two_sided + database": {"weighting": "two_sided", "normalise": "database"},
    "whiten": {"whiten": 256},  # issue 62, below
    "whiten + contrast + query_batch": {"whiten": 256, "weighting": "contrast", "normalise": "query_batch"},
}
step_runs = {m: {"plain": run_method(m, ds, **run_options)}  # step_runs[method][step]: its run
             | {step: run_method(m, ds, **opts, **run_options) for step, opts in steps.items()}
             for m in ("classical", "selection_scheme1", "dense")}
step_table = pd.concat([compare(list(by_step.values()), baseline=m) for m, by_step in step_runs.items()])
fig = plot_paired_differences(step_table, title=f"(not in the paper) each method with minus without each step: {label}")
save(fig, "places_alike_steps", label), save(step_table, "places_alike_steps", label)
compact(step_table)

# %% [markdown]
# ## Against today's contrast
# The outside prototype's question: does the two-sided contrast, alone or with a normalisation,
# beat the `contrast` weighting each method already has? The same runs, each block now paired
# against the method with `contrast` (`higher`: better than today's contrast).

# %%
against = ("contrast", "two_sided", "two_sided + query_batch", "two_sided + database",  # contrast: the baseline
           "whiten + contrast + query_batch")
vs_contrast = pd.concat([compare([by_step[step] for step in against], baseline=by_step["contrast"].label)
                         for by_step in step_runs.values()])
fig = plot_paired_differences(vs_contrast, title=f"(not in the paper) each step minus today's contrast weighting: {label}",
                              baseline="the method with contrast")
save(fig, "places_alike_vs_contrast", label), save(vs_contrast, "places_alike_vs_contrast", label)
compact(vs_contrast)

# %% [markdown]
# ## What each step changed, query by query
# For dense sampling: the queries whose top-1 a step changed (first one it fixed, then one it
# broke, if any), each reference in the top 5 before or after with its rank and score before and
# after, and why it moved: for the two-sided contrast the mean query-side (`w_q`) and
# reference-side (`w_r`) weights of the pair's matches; for the query-batch normalisation the
# reference's row and column z-scores (a reference that scores high for every query of the
# batch falls); for the database normalisation `rho`, the reference's mean similarity to its
# nearest references. The figure draws each shown reference's rank before and after (the
# correct ones green); the table's `why` column says what moved it. Below, today's
# per-landmark view for the two-sided contrast.

# %%
two_sided = run_method("dense", ds, weighting="two_sided", keep_descriptors=True, **run_options)
changes = pd.concat([step_changes(plain, two_sided).assign(step="two_sided"),
                     step_changes(plain, step_runs["dense"]["query_batch"]).assign(step="query_batch (needs the batch)"),
                     step_changes(plain, step_runs["dense"]["database"]).assign(step="database")])
fig = plot_step_changes(changes, title=f"(not in the paper) what each step changed for dense sampling: {label}")
save(fig, "places_alike_changes", label), save(changes, "places_alike_changes", label)
changes  # the `why` column: what moved each reference

# %%
fig, carried_two = plot_carried_landmarks(ds, plain, two_sided, n_queries=2, k=5)
carried_two

# %% [markdown]
# ## Landmark descriptors whitened on the reference database (issue 62)
# A third hypothesis from outside the project, fixed before any result here (docs/DEFINITIONS.md,
# "(not in the paper) whitening of the landmark descriptors"): `whiten=256` L2-normalises every
# landmark descriptor, subtracts the mean of the reference landmarks and rotates and rescales it
# onto the reference database's 256 principal components, each to unit variance (fitted on the
# references only; the queries never enter the fit), then Eq. (1) as before. What many places
# share (the mean, the directions along which the database varies most) loses its weight, as
# `contrast` discounts at the match level a landmark that matches every place alike. The rows
# `whiten` and `whiten + contrast + query_batch` (the recipe) of the steps table above pair each
# with the plain method; the recipe also stands against today's `contrast` in the table before
# and, below, against today's best, two-sided + query batch (**both need the query batch**).
#
# *Measured outside this repository by the reporter* (not reproduced here): on SPEDTest
# thumbnails (604 queries) the recipe scores 0.858 R@1 against dense's 0.795 and two-sided +
# query batch's 0.829 (+0.028 [+0.010, +0.046]); whitening alone 0.796.

# %%
best = ("two_sided + query_batch", "whiten + contrast + query_batch")  # today's best: the baseline
vs_best = pd.concat([compare([by_step[step] for step in best], baseline=by_step[best[0]].label)
                     for by_step in step_runs.values()])
save(vs_best, "places_alike_vs_best", label)
compact(vs_best)

# %% [markdown]
# What whitening does to the landmarks of dense sampling: left, the share of the chosen pairs'
# match cosines that the mean and the largest principal components carry, before (grey) and
# after (blue); then, for the queries whose top-1 it changed, each reference's rank before and
# after, with the share of its plain match cosine those shared components carried.

# %%
fig, whitening = plot_whitening(ds, plain, run_method("dense", ds, whiten=256, keep_descriptors=True, **run_options))
save(fig, "places_alike_whitening", label), save(whitening, "places_alike_whitening", label)
whitening  # the `why` column: what moved each reference
