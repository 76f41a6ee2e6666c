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
# # 04 · The impact of overlap: NMS and soft-NMS (Section 3.2, Algorithms 3-4, Fig. 7)
#
# **Scheme 1** (Algorithm 3): greedy NMS over 1,000 Edge Box candidates in proposal order, keep
# a candidate whose IoU with every kept box is <= t, until 100 (t = 0.4 ... 0.7).
# **Scheme 2** (Algorithm 4): classical landmarks, but the reciprocal-match scores are rescaled
# by soft-NMS before Eq. (1): the best remaining pair suppresses pairs overlapping it (overlap =
# min of the query-box and reference-box IoUs) by `exp(-IoU^2 / 0.5)` (t = 0.3 ... 0.7).
# The paper: both match the classical method at 0.7 and fall as t decreases.


# %%
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
# ## Fig. 7 (a) — overlap reduction Scheme 1: NMS on the landmarks, one run per IoU threshold

# %%
classical = run_method("classical", ds, **run_options)
runs = [classical] + [run_method("overlap_scheme1", ds, iou_threshold=t, **run_options)
                      for t in paper.FIG7_NMS_THRESHOLDS]
table = compare(runs, baseline="classical")
fig = plot_pr_curves(runs, title="Fig. 7a: NMS on landmarks (Alg. 3)")
save(fig, "fig07a_overlap_nms", label), save(table, "fig07a_overlap_nms", label)
table

# %% [markdown]
# ## Fig. 7 (b) — overlap reduction Scheme 2: soft-NMS on the match scores

# %%
runs = [classical] + [run_method("overlap_scheme2", ds, soft_nms_iou=t, **run_options)
                      for t in paper.FIG7_SOFT_NMS_THRESHOLDS]
table = compare(runs, baseline="classical")
fig = plot_pr_curves(runs, title="Fig. 7b: soft-NMS on matches (Alg. 4)")
save(fig, "fig07b_overlap_soft_nms", label), save(table, "fig07b_overlap_soft_nms", label)
table
