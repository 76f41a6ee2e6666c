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
# # 06 · Comparison and cost (Section 5.2-5.3, Fig. 13-14, Table 5)
#
# Dense sampling (4 x 25) vs landmark selection Scheme 1 vs the classical method on every
# dataset available: the study's dataset, plus the real Gardens Point day/night pairs in
# `../shared/data/gardens_point_mini` when present, plus `VPR_DATASETS` entries
# (`name=root;...`). Then the cost of each stage measured on this machine (Table 5).

# %%
from IPython.display import display

from vpr_core.study import extra_datasets, open_study

# %% tags=["parameters"]
dataset = "synthetic"  # synthetic | gardens_point | mapillary_berlin | freiburg_across_seasons | folder
root = None  # dataset folder for the real datasets
backbone = "efficientnet_lite0"  # see vpr_core.features.available_backbones()
quick = False  # small run (8 synthetic places / 20 images) used by the tests

include_extra = True  # also run on the real datasets found beside the project

# %%
study = open_study(dataset, root=root, backbone=backbone, quick=quick, notebook="06_comparison")
print(study.describe())

# %% [markdown]
# ## Fig. 13 — dense sampling vs Scheme 1 vs classical

# %%
study.fig13_comparison()

# %% [markdown]
# The same comparison on the other datasets found (figures in `figures/<name>/`).

# %%
for name, spec in (extra_datasets() if include_extra else {}).items():
    other = open_study(spec["dataset"], root=spec["root"], backbone=backbone, quick=quick,
                       notebook="06_comparison", label=name + ("_quick" if quick else ""))
    print(other.describe())
    display(other.fig13_comparison(note=name))

# %% [markdown]
# ## Fig. 14 — coverage of the image by the landmarks

# %%
study.fig14_coverage(figure="fig14_coverage_comparison")

# %% [markdown]
# ## Table 5 — cost per stage, measured here (fresh computation, no cache)
# Seconds per image for landmark extraction (the pipeline's landmark stage: 1,000 Edge Box
# candidates then the method's selection, or the dense grid) and CNN features, seconds per
# image pair for the remaining steps (reciprocal matching + Eq. (1)), and the total for
# matching two new images.

# %%
study.cost_table(n_images=2 if quick else 6)
