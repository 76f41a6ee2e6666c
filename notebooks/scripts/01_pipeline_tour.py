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
# figure and saves it with `save`: into `figures/<label>/` when the study runs it
# (`vpr-study run`), into the git-ignored `user/figures/<label>/` when you run it in Lab.

# %%
import numpy as np
from matplotlib_inline.backend_inline import set_matplotlib_formats

from vpr_core import configure_logging, cosine_distance, dense_sampling, edge_boxes
from vpr_core import ground_truth_references, image_similarity, LandmarkEncoder, load_dataset
from vpr_core import normalized_scale, paper, reciprocal_matches, run_method, shape_penalty
from vpr_core import tune_allocator
from vpr_study import check_parameters
from vpr_study.viz import (plot_dense_scales, plot_descriptor_matrices,
                          plot_examples, plot_labelled_matches, plot_landmark_panels, plot_pair,
                          plot_pair_terms, save)

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
pair = 0  # the query walked through the pipeline (with its ground-truth reference)

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
# Three places of the dataset: reference (left) and query (right) with the 25 dense landmarks
# of the smallest scale.

# %%
smallest = paper.DENSE_SCALES[0]
fig = plot_examples(ds, indices=(0, 1, 2),
                    boxes=lambda side, i, size: dense_sampling(size, scales=(smallest,)),
                    title=f"{ds.name}: reference (left) / query (right), dense landmarks of "
                          f"scale {smallest:g}")
save(fig, "examples", label);

# %% [markdown]
# ## The pipeline, step by step, on one pair
# ### 1. Landmarks: `edge_boxes` (classical) and `dense_sampling` (proposed)
# The classical method keeps the 100 best Edge Box proposals (of a structured-edge model when
# `VPR_SED_MODEL` names one, else of a gradient edge map). Dense sampling puts 25 boxes
# per scale on a 5 x 5 grid from the top-left corner to the far edges; a box of area ratio *a*
# is `sqrt(a)*W` wide and `sqrt(a)*H` high, so its normalised scale (Eq. 3) is *a*.

# %%
q, r = pair, ground_truth_references(ds.ground_truth, pair)[0]
images = {"query": ds.load_image("query", q), "reference": ds.load_image("reference", r)}
proposals = {s: edge_boxes(im, max_boxes=paper.N_LANDMARKS) for s, im in images.items()}
fig = plot_landmark_panels({s: (images[s], proposals[s].boxes) for s in images},
                           title=f"step 1a, edge_boxes: query {q} / reference {r}")
save(fig, "tour1_edge_boxes", label);

# %%
boxes = {s: dense_sampling(im.shape[:2], scales=paper.DENSE_SCALES,
                           per_scale=paper.DENSE_PER_SCALE) for s, im in images.items()}
level = np.repeat(np.arange(len(paper.DENSE_SCALES)), paper.DENSE_PER_SCALE)
fig = plot_landmark_panels({s: (images[s], boxes[s]) for s in images}, colors_by=level,
                           group_labels={k: f"scale {a:g}" for k, a in enumerate(paper.DENSE_SCALES)},
                           title=f"step 1b, dense_sampling: query {q} / reference {r}")
save(fig, "tour1_dense_sampling", label)
scale = normalized_scale(boxes["query"], images["query"].shape[:2])
{f"scale {a:g}": round(float(scale[level == k].mean()), 4) for k, a in enumerate(paper.DENSE_SCALES)}

# %% [markdown]
# ### 2. `LandmarkEncoder.encode`: one descriptor per landmark
# Each box is cropped, resized and passed through the backbone; the mid-level feature map is
# flattened and randomly projected to 1,024 dimensions. One row per landmark.

# %%
landmark_encoder = LandmarkEncoder(backbone, dim=paper.PROJECTION_DIM, seed=0, pooling=pooling)
desc = {s: landmark_encoder.encode(images[s], boxes[s]) for s in images}
fig = plot_descriptor_matrices(desc, title=f"step 2, LandmarkEncoder.encode ({backbone})")
save(fig, "tour2_descriptors", label)
{s: d.shape for s, d in desc.items()}, landmark_encoder.config["weights"]

# %% [markdown]
# ### 3. `reciprocal_matches`: mutual nearest neighbours on cosine distance
# Landmark *i* of the query and *j* of the reference match when *j* is *i*'s nearest neighbour
# and *i* is *j*'s.

# %%
matches = reciprocal_matches(desc["query"], desc["reference"])
d = cosine_distance(desc["query"], desc["reference"])[matches[:, 0], matches[:, 1]]
fig = plot_labelled_matches(images["query"], images["reference"], boxes["query"],
                            boxes["reference"], matches, None,
                            title=f"step 3, reciprocal_matches: {len(matches)} mutual neighbours")
save(fig, "tour3_reciprocal_matches", label);

# %% [markdown]
# ### 4. `image_similarity`: Eq. (1) with the shape penalty of Eq. (2)
# `S = sum over the matched pairs of (1 - d*s) / sqrt(na*nb)`; the figure shows every pair's
# cosine distance *d*, shape penalty *s* and term; the last line recomputes Eq. (1) from them.

# %%
S = image_similarity(desc["query"], boxes["query"], desc["reference"], boxes["reference"])
s = shape_penalty(boxes["query"], boxes["reference"])[matches[:, 0], matches[:, 1]]
na, nb = len(boxes["query"]), len(boxes["reference"])
fig = plot_pair_terms(d, s, na, nb, S, title=f"step 4, image_similarity (Eq. 1): query {q} / reference {r}")
save(fig, "tour4_image_similarity", label)
print(f"image_similarity: {S:.6f}; from the terms: {(1 - d * s).sum() / np.sqrt(na * nb):.6f}")

# %% [markdown]
# ## Fig. 3 and 8 — the classical and the dense pipeline on the same pair, over the dataset
# `run_method` runs every image; the figure draws this pair's reciprocal matches, green when
# correct and red when not (labelled exactly from the generator's geometry on `synthetic`, by
# SIFT + RANSAC verification on real images).

# %%
classical = run_method("classical", ds, keep_descriptors=True, **run_options)
dense = run_method("dense", ds, keep_descriptors=True, **run_options)
save(plot_pair(ds, classical, query=q), "fig03_classical_pipeline", label)
save(plot_pair(ds, dense, query=q), "fig08_dense_pipeline", label);

# %% [markdown]
# ## Fig. 9 — the four dense sampling scales (25 landmarks each, image aspect kept)

# %%
save(plot_dense_scales(ds.load_image("reference", 0)), "fig09_dense_scales", label);
