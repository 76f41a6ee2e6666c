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
# # 02 · The impact of landmark scale: CMR, CLS and ASL (Section 3.1, Table 1, Fig. 1, 2, 4)
#
# The paper labelled landmark matches by hand between 200 day-left / night-right Gardens Point
# pairs and measured, per Table-1 scale:
#
# * **CMR** — correct matches / all matches between query and its ground-truth reference;
# * **CLS** — the share of the Eq. (1) similarity mass contributed by matches whose query-side
#   landmark has that scale, for ground-truth and for query-irrelevant pairs;
# * **ASL** — the mean pair score `1 - d*s` of those matches.
#
# Here the labels are automatic: `exact` on `synthetic` (the generator knows each pair's
# homography: a match is correct when the query box mapped into the reference overlaps the
# matched reference box with IoU >= 0.5), `geometric` (SIFT + RANSAC) on real images, or a CSV
# of manual labels (`vpr_core.statistics.label_matches(..., method="file")`).

# %%
from matplotlib_inline.backend_inline import set_matplotlib_formats

from vpr_core import configure_logging, load_dataset, paper, run_method, scale_statistics
from vpr_core import tune_allocator
from vpr_study import check_parameters
from vpr_study.viz import plot_asl, plot_cls, plot_cmr, plot_pair, plot_scale_statistics, save

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
method = "classical"  # landmark method whose matches are studied
n_irrelevant = 5  # query-irrelevant references sampled per query

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
# ## Table 1 — nine landmark scales (normalised scale = landmark area / image area)

# %%
paper.table1()

# %% [markdown]
# ## Fig. 1 — matched landmarks between a query and its ground-truth reference
# One run of the method over the dataset, kept with its descriptors for the statistics below.
# Query 1 (notebook 01's Fig. 3 draws query 0 of the same classical run).

# %%
run = run_method(method, ds, keep_descriptors=True, **run_options)
save(plot_pair(ds, run, query=1), "fig01_labelled_matches", label);

# %% [markdown]
# ## Fig. 2 — matches between two irrelevant images (all wrong by definition; note the overlap)

# %%
save(plot_pair(ds, run, query=1, reference=ds.n_reference // 2), "fig02_irrelevant_matches",
     label);

# %% [markdown]
# ## Fig. 4 — CMR, CLS and ASL per scale
# Every query against its ground-truth reference (labelled matches) and `n_irrelevant`
# irrelevant references. The panels are also saved one by one (`fig04a_cmr`, `fig04b_cls`,
# `fig04c_asl`); the table holds every number plotted, `fig04_matches.csv` every match.

# %%
stats = scale_statistics(ds, run, n_irrelevant=n_irrelevant)
for stem, plot in (("fig04a_cmr", plot_cmr), ("fig04b_cls", plot_cls), ("fig04c_asl", plot_asl)):
    save(plot(stats), stem, label)
save(plot_scale_statistics(stats), "fig04_scale_statistics", label)
save(stats.to_frame(), "fig04_scale_statistics", label), save(stats.matches_frame(), "fig04_matches", label)
stats.to_frame()

# %% [markdown]
# ### Labelling by hand (optional, interactive only)
# `vpr_study.viz.pair_label_widget(ds, run, query=0)` shows one pair's matches and writes a CSV
# usable with `label_matches(..., method="file")`. It needs `ipywidgets` (`make lab` installs
# it with JupyterLab) and is not used by the headless run.
