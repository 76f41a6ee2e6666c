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
# Dense sampling (4 x 25) vs landmark selection Scheme 1 vs the classical method, beside a
# `global` whole-image descriptor from the same backbone (not in the paper: it shows what the
# landmarks add) and, when a VPR-Bench checkout is given (`peers` or `$VPR_BENCH_ROOT`), its
# precomputed techniques on the same images. Legends and the table carry 95% bootstrap
# intervals; the paired differences below say which gaps are findings. `make study` runs this
# notebook on the embedded default and on the real datasets beside the project
# (`figures/<dataset>/`). Then the cost of each stage measured on this machine (Table 5).

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
peers = None  # VPR-Bench checkout with precomputed_matches/ (default: $VPR_BENCH_ROOT)
peer_dataset = None  # its dataset folder, e.g. "GardensPointWalking" (None: no peers)

# %%
study = open_study(dataset, root=root, backbone=backbone, quick=quick,
                   notebook="06_comparison", label=label, pooling=pooling, **options)
print(study.describe())

# %% [markdown]
# ## Fig. 13 — dense sampling vs Scheme 1 vs classical

# %%
study.fig13_comparison(extra=["global", *study.vprbench_peers(peers, peer_dataset)])

# %% [markdown]
# Paired bootstrap of each method against dense sampling (same resampled queries): a
# difference is a finding only when its interval excludes 0.

# %%
study.paired_differences("fig13_comparison", baseline="dense")

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
