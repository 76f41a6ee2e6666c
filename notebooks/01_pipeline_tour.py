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
# All logic lives in `vpr_core`; this notebook only calls it. Every figure cell shows the
# figure and the numbers behind it; the files are in `figures/<dataset>/`.

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
pair = 0  # the query of the pair walked through the pipeline (with its ground-truth reference)

# %%
study = open_study(dataset, root=root, backbone=backbone, quick=quick,
                   notebook="01_pipeline_tour", label=label, pooling=pooling, **options)
print(study.describe())

# %% [markdown]
# Three places of the dataset: reference (left) and query (right) with the 25 dense landmarks
# of the smallest scale.

# %%
study.examples()

# %% [markdown]
# ## The pipeline, step by step, on one pair
# ### 1. `dense_sampling`: 4 scales x 25 boxes on each image
# A box of area ratio *a* is `sqrt(a)*W` wide and `sqrt(a)*H` high; 25 boxes per scale sit on a
# 5 x 5 grid from the top-left corner to the far edges. The table checks Eq. (3): each level's
# normalised scale (box area / image area) equals the requested one.

# %%
study.tour_dense_sampling(pair)

# %% [markdown]
# ### 2. `LandmarkEncoder.encode`: one descriptor per landmark
# Each box is cropped, resized and passed through the backbone; the mid-level feature map is
# flattened and randomly projected to 1,024 dimensions. One row per landmark.

# %%
study.tour_descriptors(pair)

# %% [markdown]
# ### 3. `reciprocal_matches`: mutual nearest neighbours on cosine distance
# Landmark *i* of the query and *j* of the reference match when *j* is *i*'s nearest neighbour
# and *i* is *j*'s.

# %%
study.tour_reciprocal_matches(pair)

# %% [markdown]
# ### 4. `image_similarity`: Eq. (1) with the shape penalty of Eq. (2)
# `S = sum over the matched pairs of (1 - d*s) / sqrt(na*nb)`; the table lists every pair's
# cosine distance *d*, shape penalty *s* and term.

# %%
study.tour_image_similarity(pair)

# %% [markdown]
# ## Fig. 3 — the classical pipeline on one pair
# Reciprocal landmark matches between a query and its ground-truth reference; green boxes are
# correct matches, red ones incorrect (labelled exactly from the generator's geometry on
# `synthetic`, by SIFT + RANSAC verification on real images).

# %%
study.fig03_classical_pipeline(pair)

# %% [markdown]
# ## Fig. 8 — the dense-sampling pipeline on the same pair

# %%
study.fig08_dense_pipeline(pair)

# %% [markdown]
# ## Fig. 9 — the four dense sampling scales (25 landmarks each, image aspect kept)

# %%
study.fig09_dense_scales()

# %% [markdown]
# ## Fig. 14 — landmark coverage: top-100 Edge Boxes vs dense sampling
# Darker = covered by more landmarks. The table gives the share of the image covered by at
# least one landmark.

# %%
study.fig14_coverage()
