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
# # 01 · Pipeline tour: classical (Edge Boxes) and dense landmarks
#
# Paper Sections 2.1 and 4, Figures 3, 8, 9 and 14. The classical method (Sünderhauf et al.
# 2015) takes the top 100 Edge Box proposals of an image, describes each landmark with a CNN
# feature (the paper: AlexNet conv3, 64,896-d, Gaussian random projection to 1,024-d), matches
# landmarks between two images by reciprocal nearest neighbours on cosine distance and scores
# the pair with Eq. (1)-(2). The proposed method replaces Edge Boxes by dense multi-scale
# sampling: 4 normalised scales (0.16, 0.25, 0.36, 0.49) x 25 landmarks on a 5 x 5 grid.
#
# All logic lives in `vpr_core`; this notebook only calls it.

# %%
from IPython.display import Image, display

from vpr_core.study import open_study

# %% tags=["parameters"]
dataset = "synthetic"  # synthetic | gardens_point | mapillary_berlin | freiburg_across_seasons | folder
root = None  # dataset folder for the real datasets
backbone = "efficientnet_lite0"  # see vpr_core.features.available_backbones()
quick = False  # small run (8 synthetic places / 20 images) used by the tests

# %%
study = open_study(dataset, root=root, backbone=backbone, quick=quick, notebook="01_pipeline_tour")
print(study.describe())

# %% [markdown]
# Three places of the dataset: reference (left) and query (right) with the 100 dense landmarks.

# %%
display(Image(filename=study.examples()))

# %% [markdown]
# ## Fig. 3 — the classical pipeline on one pair
# Reciprocal landmark matches between a query and its ground-truth reference; green boxes are
# correct matches, red ones incorrect (labelled exactly from the generator's geometry on
# `synthetic`, by SIFT + RANSAC verification on real images).

# %%
study.pipeline_figure("classical", pair=0, figure="fig03_classical_pipeline")
display(Image(filename=study.figures_dir / "fig03_classical_pipeline.png"))

# %% [markdown]
# ## Fig. 8 — the dense-sampling pipeline on the same pair

# %%
study.pipeline_figure("dense", pair=0, figure="fig08_dense_pipeline")
display(Image(filename=study.figures_dir / "fig08_dense_pipeline.png"))

# %% [markdown]
# ## Fig. 9 — the four dense sampling scales (25 landmarks each, image aspect kept)

# %%
display(Image(filename=study.dense_scales()))

# %% [markdown]
# ## Fig. 14 — landmark coverage: top-100 Edge Boxes vs dense sampling
# Darker = covered by more landmarks. The table gives the share of the image covered by at
# least one landmark.

# %%
study.coverage(figure="fig14_coverage")

# %%
display(Image(filename=study.figures_dir / "fig14_coverage.png"))
