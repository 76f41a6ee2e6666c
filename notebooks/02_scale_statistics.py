# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
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
from vpr_core.study import open_study, table1
from vpr_core.utils import tune_allocator

# Process-wide settings, made here where you see them (the library never changes them):
tune_allocator()  # glibc keeps freed memory for reuse: crop features ~1.7x faster, same bits

# %% tags=["parameters"]
dataset = "synthetic"  # synthetic | gardens_point | mapillary_berlin | freiburg_across_seasons | folder
root = None  # dataset folder for the real datasets
backbone = "efficientnet_lite0"  # see vpr_core.features.available_backbones()
quick = False  # small run (8 synthetic places / 20 images) used by the tests
label = None  # output subfolder of figures/ and results/ (default: the dataset name)
options = {}  # loader options, e.g. {"step": 50, "tolerance": 0} for nordland
pooling = "crop"  # crop: the paper's per-landmark crops; roi: one backbone pass per image

method = "classical"  # landmark method whose matches are studied
n_irrelevant = 5  # query-irrelevant references sampled per query

# %%
study = open_study(dataset, root=root, backbone=backbone, quick=quick,
                   notebook="02_scale_statistics", label=label, pooling=pooling, **options)
print(study.describe())

# %% [markdown]
# ## Table 1 — nine landmark scales (normalised scale = landmark area / image area)

# %%
table1()

# %% [markdown]
# ## Fig. 1 — matched landmarks between a query and its ground-truth reference

# %%
study.fig01_labelled_matches(pair=0, method=method)

# %% [markdown]
# ## Fig. 2 — matches between two irrelevant images (all wrong by definition; note the overlap)

# %%
study.fig02_irrelevant_matches(pair=0, method=method)

# %% [markdown]
# ## Fig. 4 — CMR, CLS and ASL per scale
# The panels are also saved one by one (`fig04a_cmr`, `fig04b_cls`, `fig04c_asl`); the table
# holds every number plotted.

# %%
study.fig04_scale_statistics(method=method, n_irrelevant=n_irrelevant)

# %% [markdown]
# ### Labelling by hand (optional, interactive only)
# `vpr_core.labels.label_widget(study.dataset, q, r, ...)` shows one pair's matches and
# writes a CSV usable with `label_matches(..., method="file")`. It needs `ipywidgets`
# (`pip install ipywidgets`) and is not used by the headless run.
