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
# # 05 · Dense sampling parameters (Section 5.1, Tables 2-4, Fig. 10-12)
#
# Exactly the paper's settings (about 100 landmarks per image): the number of scale levels
# (Table 2), the number of landmarks per scale (Table 3) and the normalised scales (Table 4).
# The paper ran these on Mapillary Berlin; here they run on the dataset chosen below.

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
                   notebook="05_dense_sampling_parameters", label=label, pooling=pooling, **options)
print(study.describe())

# %% [markdown]
# ## Table 2 / Fig. 10 — single vs multiple scale levels

# %%
study.dense_settings("table2")

# %%
study.fig10_scale_levels()

# %% [markdown]
# ## Table 3 / Fig. 11 — landmarks per scale at scales 0.16, 0.25, 0.36, 0.49

# %%
study.dense_settings("table3")

# %%
study.fig11_landmarks_per_scale()

# %% [markdown]
# ## Table 4 / Fig. 12 — normalised scales, 25 landmarks per scale

# %%
study.dense_settings("table4")

# %%
study.fig12_normalized_scales()
