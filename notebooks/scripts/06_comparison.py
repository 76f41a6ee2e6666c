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
# # 06 · Comparison and cost (Section 5.2-5.3, Fig. 13-14, Table 5)
#
# Dense sampling (4 x 25) vs landmark selection Scheme 1 vs the classical method, beside a
# `global` whole-image descriptor from the same backbone (not in the paper: it shows what the
# landmarks add) and, when a VPR-Bench checkout is given (`peers` or `$VPR_BENCH_ROOT`), its
# precomputed techniques on the same images. Legends and the table carry 95% bootstrap
# intervals; the paired differences below say which gaps are findings. `make study` runs this
# notebook on the embedded default and on the real datasets beside the project
# (`figures/<dataset>/`). Then the cost of each stage measured on this machine (Table 5).

# %%
from matplotlib_inline.backend_inline import set_matplotlib_formats

from vpr_core import compare, configure_logging, cost_table, load_dataset, per_query, run_method
from vpr_core import tune_allocator
from vpr_study import check_parameters, find_vprbench_peers, peer_from_matrix, peer_result
from vpr_study.viz import plot_coverage_comparison, plot_disagreements, plot_pr_curves, save

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
peers = None  # a VPR-Bench checkout with precomputed_matches/ (None: $VPR_BENCH_ROOT)
peer_dataset = None  # its dataset folder, e.g. "GardensPointWalking" (None: no VPR-Bench peers)
my_method = None  # your method's (Nq, Nr) similarity matrix .npy on this dataset (None: none)

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
# ## Fig. 13 — dense sampling vs Scheme 1 vs classical (and peers)
# `compare` puts every run beside dense sampling: the paired bootstrap resamples the same
# queries for both methods; a difference is higher or lower only when its interval excludes 0
# (else inconclusive).

# %%
runs = [run_method(m, ds, **run_options) for m in ("dense", "selection_scheme1", "classical", "global")]
if peer_dataset:
    runs += [peer_result(p, ds) for p in find_vprbench_peers(peers, peer_dataset)]
if my_method:
    runs.append(peer_result(peer_from_matrix(my_method, "my method"), ds, label="my method"))
table = compare(runs, baseline="dense")
fig = plot_pr_curves(runs, title="Fig. 13: dense vs selection vs classical")
save(fig, "fig13_comparison", label), save(table, "fig13_comparison", label)
table

# %% [markdown]
# ## Where dense wins and where it loses (not in the paper)
# Per query and run: the rank of the first correct reference, whether the top-1 is correct, the
# ratio score `S2/S1` and the reciprocal landmark matches of the top-1 pair; queries where dense
# and classical disagree come first. The figure shows, for such queries, each run's top-1 with its
# matched landmarks (green: correct match, red: wrong) beside the correct reference. The dashed
# line of the PR figure and the `chance` row of the table: what a random ranking would score.

# %%
dense, classical = (run_method(m, ds, keep_descriptors=True, **run_options) for m in ("dense", "classical"))
fig = plot_disagreements(ds, dense, classical, n=6)
queries = per_query([dense, classical])
save(fig, "disagreements_dense_classical", label), save(queries, "disagreements_dense_classical", label)
fig.table  # the queries the figure shows, in its order

# %% [markdown]
# ## Geometry in the score (not in the paper)
# Eq. (1) ignores where the matched landmarks lie. `spatial="consistency"` weights each
# reciprocal match by how well its box displacement agrees with the pair's median displacement
# (docs/DEFINITIONS.md), for any method. Each figure pairs a method with and without it; the
# table's paired difference says whether geometry scores higher, lower or inconclusive on this
# dataset. Off by default: on the shared real data every difference is inconclusive.

# %%
for m, stem in (("dense", "geometry_dense"), ("classical", "geometry_classical")):
    pair = [run_method(m, ds, spatial=s, **run_options) for s in (None, "consistency")]
    table = compare(pair, baseline=m)
    fig = plot_pr_curves(pair, title=f"(not in the paper) {m} with and without geometry")
    save(fig, stem, label), save(table, stem, label)
table

# %% [markdown]
# ## Fig. 14 — coverage of the image by the landmarks (top-100 Edge Boxes vs dense)

# %%
fig, coverage = plot_coverage_comparison(ds, [runs[2], runs[0]], side="reference")  # the first image with a scene
save(fig, "fig14_coverage_comparison", label), save(coverage, "fig14_coverage_comparison", label)
coverage

# %% [markdown]
# ## Table 5 — cost per stage, measured here (fresh computation, no cache)
# Seconds per image for landmark extraction (the pipeline's landmark stage: 1,000 Edge Box
# candidates then the method's selection, or the dense grid) and CNN features, seconds per
# image pair for the remaining steps (reciprocal matching + Eq. (1)), and the total for
# matching two new images. Saved as `results/<label>/table5_cost.timings.csv`: a measurement of
# this machine, so it is not committed.

# %%
cost = cost_table(ds, methods=("classical", "dense"), n_images=2 if limit or len(ds) < 10 else 6,
                  backbone=backbone, pooling=pooling)
save(cost, "table5_cost", label)
cost

# %% [markdown]
# ## Places that look alike: a database weighting of the matches (not in the paper)
# Eq. (1) counts a match on a wall or a floor tile, which looks alike in every place, as much as
# a match on a rare object. `weighting="contrast"` multiplies each match's term by how far its
# query landmark's cosine lies above that landmark's mean best cosine over all references (in
# standard deviations, 0 below the mean); `weighting="idf"` by the log of the references over
# those the landmark matches (docs/DEFINITIONS.md). Each figure shows a method with each
# weighting; the table's paired differences against the paper's Eq. (1) say whether a weighting
# is higher, lower or inconclusive on this dataset. Off by default: the study reproduces
# the paper. Which landmarks carried a score the weighting changed: notebook 07.

# %%
for m, stem in (("dense", "weighting_dense"), ("classical", "weighting_classical")):
    trio = [run_method(m, ds, weighting=w, **run_options) for w in (None, "contrast", "idf")]
    table = compare(trio, baseline=m)
    fig = plot_pr_curves(trio, title=f"(not in the paper) {m} with and without a weighting")
    save(fig, stem, label), save(table, stem, label)
table
