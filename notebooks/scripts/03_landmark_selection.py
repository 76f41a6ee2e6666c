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
# # 03 · Landmark selection by scale (Section 3.1, Algorithms 1-2, Fig. 5-6)
#
# 1,000 Edge Box candidates per image; **Scheme 1** (Algorithm 1) keeps the first 100 in
# proposal order whose scale index is above 3; **Scheme 2** (Algorithm 2) takes all candidates
# of scale 5, then 6, 7, 8, 9, 4 until 100. The paper finds Scheme 1 > classical > Scheme 2 on
# Gardens Point and explains it by the scale distributions (Fig. 6): Scheme 1 keeps several
# scales, Scheme 2 concentrates on one.

# %%
from vpr_core import compare, configure_logging, load_dataset, run_method, scale_distribution
from vpr_core import tune_allocator
from vpr_study import check_parameters
from vpr_study.viz import dataset_line, plot_pr_curves, plot_scale_distribution, save

# Process-wide settings, made here where you see them (the library never changes them):
tune_allocator()  # glibc keeps freed memory for reuse: crop features ~1.7x faster, same bits
configure_logging(stream="stdout", silence_warnings=True)  # log lines (and warnings) as output

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
# ## Fig. 5 — PR curves: classical vs Scheme 1 vs Scheme 2 (ratio protocol)
# Three runs of `run_method`, then `compare` (metrics with 95% bootstrap intervals and the
# paired difference of each run against classical: higher or lower only when its interval
# excludes 0, else inconclusive), then the PR curves.

# %%
methods = ("classical", "selection_scheme1", "selection_scheme2")
runs = [run_method(m, ds, **run_options) for m in methods]
table = compare(runs, baseline="classical")
fig = plot_pr_curves(runs, title="Fig. 5: landmark selection schemes")
save(fig, "fig05_selection", label), save(table, "fig05_selection", label)
table

# %% [markdown]
# ## Fig. 6 — scale distribution of the selected landmarks (query and reference)

# %%
for run, stem in zip(runs[1:], ("fig06a_scheme1_scales", "fig06b_scheme2_scales")):
    counts = scale_distribution(run, ds)
    fig = plot_scale_distribution(counts, title=f"{run.label}: landmarks per scale\n{dataset_line([run], pr=False)}",
                                  method=run.method)  # bars in the method's colour
    save(fig, stem, label), save(counts, stem, label)
    display(counts.T)
