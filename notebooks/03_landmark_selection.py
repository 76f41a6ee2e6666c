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
# # 03 · Landmark selection by scale (Section 3.1, Algorithms 1-2, Fig. 5-6)
#
# 1,000 Edge Box candidates per image; **Scheme 1** (Algorithm 1) keeps the first 100 in
# proposal order whose scale index is above 3; **Scheme 2** (Algorithm 2) takes all candidates
# of scale 5, then 6, 7, 8, 9, 4 until 100. The paper finds Scheme 1 > classical > Scheme 2 on
# Gardens Point and explains it by the scale distributions (Fig. 6): Scheme 1 keeps several
# scales, Scheme 2 concentrates on one.

# %%
from vpr_core.study import open_study
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

# %%
study = open_study(dataset, root=root, backbone=backbone, quick=quick,
                   notebook="03_landmark_selection", label=label, pooling=pooling, **options)
print(study.describe())

# %% [markdown]
# ## Fig. 5 — PR curves: classical vs Scheme 1 vs Scheme 2 (ratio protocol)

# %%
study.fig05_selection()

# %% [markdown]
# ## Fig. 6 — scale distribution of the selected landmarks (query and reference)

# %%
study.fig06a_scheme1_scales()

# %%
study.fig06b_scheme2_scales()
