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
# # 04 · The impact of overlap: NMS and soft-NMS (Section 3.2, Algorithms 3-4, Fig. 7)
#
# **Scheme 1** (Algorithm 3): greedy NMS over 1,000 Edge Box candidates in proposal order, keep
# a candidate whose IoU with every kept box is <= t, until 100 (t = 0.4 ... 0.7).
# **Scheme 2** (Algorithm 4): classical landmarks, but the reciprocal-match scores are rescaled
# by soft-NMS before Eq. (1): the best remaining pair suppresses pairs overlapping it (overlap =
# min of the query-box and reference-box IoUs) by `exp(-IoU^2 / 0.5)` (t = 0.3 ... 0.7).
# The paper: both match the classical method at 0.7 and fall as t decreases.

# %%
from vpr_core.study import FIG7_NMS_THRESHOLDS, FIG7_SOFT_NMS_THRESHOLDS, open_study
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
                   notebook="04_overlap", label=label, pooling=pooling, **options)
print(study.describe())

# %% [markdown]
# ## Fig. 7 (a) — overlap reduction Scheme 1 (NMS on the landmarks)

# %%
study.fig07a_overlap_nms(FIG7_NMS_THRESHOLDS)

# %% [markdown]
# ## Fig. 7 (b) — overlap reduction Scheme 2 (soft-NMS on the match scores)

# %%
study.fig07b_overlap_soft_nms(FIG7_SOFT_NMS_THRESHOLDS)
