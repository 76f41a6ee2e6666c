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
# # 05 · Dense sampling parameters (Section 5.1, Tables 2-4, Fig. 10-12)
#
# Exactly the paper's settings (about 100 landmarks per image): the number of scale levels
# (Table 2), the number of landmarks per scale (Table 3) and the normalised scales (Table 4).
# The paper ran these on Mapillary Berlin; here they run on the dataset chosen below.

# %%
from dataclasses import dataclass

import numpy as np
import torch

from vpr_core import compare, configure_logging, load_dataset, paper, run_method, tune_allocator
from vpr_study import check_parameters
from vpr_study.viz import plot_pr_curves, save

# Process-wide settings, made here where you see them (the library never changes them):
tune_allocator()  # glibc keeps freed memory for reuse: crop features ~1.7x faster, same bits
configure_logging(stream="stdout", silence_warnings=True)  # log lines (and warnings) as output

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
# Each figure below: one `run_method("dense", ...)` per row of the paper's table (edit the
# table's line to try another setting), `compare` against the table's Set 1, the PR curves.

# %% [markdown]
# ## Table 2 / Fig. 10 — single vs multiple scale levels

# %%
def dense_runs(table):
    return [run_method("dense", ds, scales=scales, per_scale=n, **run_options,
                       label=paper.dense_set_label(name, scales, n))
            for name, (scales, n) in table.items()]


settings = paper.TABLE2
runs = dense_runs(settings)
table = compare(runs)  # baseline: the first run, Set 1
fig = plot_pr_curves(runs, title="Fig. 10: scale levels (Table 2)")
save(fig, "fig10_scale_levels", label), save(table, "fig10_scale_levels", label)
display(paper.dense_settings(settings))
table

# %% [markdown]
# ## Table 3 / Fig. 11 — landmarks per scale at scales 0.16, 0.25, 0.36, 0.49

# %%
settings = paper.TABLE3
runs = dense_runs(settings)
table = compare(runs)
fig = plot_pr_curves(runs, title="Fig. 11: landmarks per scale (Table 3)")
save(fig, "fig11_landmarks_per_scale", label), save(table, "fig11_landmarks_per_scale", label)
display(paper.dense_settings(settings))
table

# %% [markdown]
# ## Table 4 / Fig. 12 — normalised scales, 25 landmarks per scale

# %%
settings = paper.TABLE4
runs = dense_runs(settings)
table = compare(runs)
fig = plot_pr_curves(runs, title="Fig. 12: normalised scales (Table 4)")
save(fig, "fig12_normalized_scales", label), save(table, "fig12_normalized_scales", label)
display(paper.dense_settings(settings))
table

# %% [markdown]
# ## Try your own landmark scheme (and your own backbone)
#
# A landmark scheme is any frozen dataclass with `boxes(self, image)` returning `(K, 4)` boxes
# `(x, y, w, h)`: its class and fields name the run and key its cache (an edited cell is a new
# scheme, computed afresh). A backbone is any `torch.nn.Module` mapping `(B, 3, S, S)` crops to
# features, passed as `backbone=` with its `input_size=S`. Both are compared with `dense` below.

# %%
@dataclass(frozen=True)
class CentreGrid:
    """g x g boxes of `side` times the image side, packed towards the image centre."""

    g: int = 4
    side: float = 0.5

    def boxes(self, image):
        h, w = image.shape[:2]
        t = (1 - self.side) * (np.linspace(-1, 1, self.g) ** 3 + 1) / 2  # cubed: denser inside
        return np.array([[x * w, y * h, self.side * w, self.side * h] for y in t for x in t])


torch.manual_seed(0)
random_conv = torch.nn.Sequential(torch.nn.Conv2d(3, 16, 8, stride=8), torch.nn.ReLU())  # untrained
runs = [run_method("dense", ds, **run_options),
        run_method(CentreGrid(), ds, **run_options),
        run_method("dense", ds, **{**run_options, "backbone": random_conv}, input_size=64,
                   label="dense, random conv")]
table = compare(runs)  # baseline: dense
fig = plot_pr_curves(runs, title="Your own landmark scheme and backbone against dense")
save(fig, "own_scheme_and_backbone", label), save(table, "own_scheme_and_backbone", label)
table
