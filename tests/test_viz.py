"""Plot helpers: deterministic saving under the output root, the pipeline-tour pictures."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vpr_study import viz

PNG = b"\x89PNG\r\n\x1a\n"


def _bytes(fig, path):
    return viz.save_figure(fig, path).read_bytes()


def test_save_figure_goes_under_the_output_root(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path))
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    p = viz.save_figure(fig, "f1", dataset="lab")
    assert p == tmp_path / "figures" / "lab" / "f1.png"
    assert p.read_bytes()[:8] == PNG
    assert b"Software" not in p.read_bytes()  # no version stamp: byte-identical reruns
    pdf = viz.save_figure(fig, tmp_path / "x" / "f2.pdf")
    assert pdf.read_bytes()[:4] == b"%PDF"
    plt.close(fig)


def test_landmark_panels_colour_groups_and_check_them(tmp_path):
    img = np.zeros((60, 80, 3), np.uint8)
    boxes = np.array([[0, 0, 10, 10], [5, 5, 20, 20], [30, 30, 10, 10]], float)
    a = _bytes(
        viz.plot_landmark_panels({"q": (img, boxes), "r": (img, boxes)}, colors_by=[0, 0, 1]),
        tmp_path / "a.png",
    )
    b = _bytes(
        viz.plot_landmark_panels({"q": (img, boxes), "r": (img, boxes)}, colors_by=[0, 0, 1]),
        tmp_path / "b.png",
    )
    c = _bytes(
        viz.plot_landmark_panels({"q": (img, boxes), "r": (img, boxes)}, colors_by=[0, 1, 1]),
        tmp_path / "c.png",
    )
    assert a == b and a != c


def test_descriptor_matrices_and_pair_terms(tmp_path):
    rng = np.random.default_rng(0)
    d = {"query": rng.normal(size=(10, 32)), "reference": rng.normal(size=(12, 32))}
    a = _bytes(viz.plot_descriptor_matrices(d, title="t"), tmp_path / "d1.png")
    assert a == _bytes(viz.plot_descriptor_matrices(d, title="t"), tmp_path / "d2.png")
    dist, shape = rng.uniform(0, 1, 7), rng.uniform(1, 2.7, 7)
    fig = viz.plot_pair_terms(dist, shape, 10, 12, 0.25)
    title = fig.axes[0].get_title()
    assert f"{(1 - dist * shape).sum():.3f}" in title and "sqrt(10 x 12)" in title


def _result(label, sim, gt, auc=None):
    from fake_results import result_of

    return result_of(label, sim, gt, **({} if auc is None else {"intervals": {"auc": auc}}))


def test_pr_curves_legend_below_identical_curves_said_and_dataset_named():
    import numpy as np
    from matplotlib.colors import to_hex

    from vpr_study.viz import plot_pr_curves
    from vpr_study.viz.curves import METHOD_COLORS

    rng = np.random.default_rng(0)
    gt = np.eye(6, dtype=bool)
    a, b = gt + rng.random((6, 6)) * 0.9, gt + rng.random((6, 6)) * 3.0
    results = [
        _result("dense", a, gt, (0.5, 0.25, 0.75)),
        _result("x", b, gt),
        _result("y", a.copy(), gt),
    ]
    fig = plot_pr_curves(results, title="Fig. T")
    ax = fig.axes[0]
    legend = ax.get_legend()
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts[0] == "dense  0.500 [0.250, 0.750]"  # the metric is named in the title
    assert legend.get_title().get_text().startswith("AUC [95% CI]")
    assert texts[1].startswith("x  0.") and "[" not in texts[1]
    assert texts[2].startswith("y  ") and texts[2].endswith(", same curve as dense")
    drawn = [ln for ln in ax.lines if len(ln.get_xdata())]
    assert len(drawn) == 4  # dense, x, y over dense's line, the chance level
    assert to_hex(ax.lines[0].get_color()) == to_hex(METHOD_COLORS["dense"])
    # the same curve is still seen: its own colour, thin, hollow markers over the line it repeats
    twin = legend.legend_handles[2]
    assert twin.get_fillstyle() == "none" and twin.get_marker() not in ("", "None")
    assert twin.get_linewidth() < ax.lines[0].get_linewidth()
    assert to_hex(twin.get_color()) not in (to_hex(ln.get_color()) for ln in ax.lines[:2])
    assert np.array_equal(ax.lines[2].get_ydata(), ax.lines[0].get_ydata())
    assert "toy: 6 of 6 queries with ground truth, tolerance 0" in ax.get_title(loc="left")
    fig.canvas.draw()
    box = legend.get_window_extent()
    assert box.y1 <= ax.get_window_extent().y0  # below the axes, never over the curves
    assert viz.layout_problems(fig) == []


def test_pr_curves_refuse_what_is_not_a_list_of_results_in_compares_words():
    """One rule for a list of results (evaluation.compare.check_results), the figure named."""
    from vpr_study.viz import plot_pr_curves

    gt = np.eye(3, dtype=bool)
    one = _result("dense", gt + 0.5, gt)
    with pytest.raises(ValueError, match=r"^plot_pr_curves\(\) needs at least one result"):
        plot_pr_curves([])
    with pytest.raises(TypeError, match=r"^plot_pr_curves\(\): results is one result \('dense'\)"):
        plot_pr_curves(one)
    with pytest.raises(TypeError, match=r"^plot_pr_curves\(\): results\[1\] is a str"):
        plot_pr_curves([one, "classical"])


def test_pr_curves_same_curve_is_said_and_colours_never_repeat():
    from matplotlib.colors import to_hex

    from vpr_study.viz import plot_pr_curves

    rng = np.random.default_rng(1)
    gt = np.eye(6, dtype=bool)
    a = gt + rng.random((6, 6)) * 3.0
    scaled = a * 0.5  # another matrix, the same ranking: same curve and metrics
    other = gt + rng.random((6, 6)) * 3.0
    results = [
        _result("classical", a, gt),
        _result("s2", scaled, gt),
        _result("global", other, gt),
        _result("peer", other[::-1].copy(), gt),
    ]
    fig = plot_pr_curves(results)
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts[1].startswith("s2  ") and texts[1].endswith("same curve as classical")
    drawn = [
        to_hex(ln.get_color())
        for ln in ax.lines
        if len(ln.get_xdata()) and ln.get_linestyle() != "--"  # "--": the chance level
    ]
    # four methods, four colours (s2 and peer from the palette of methods not in the paper)
    assert len(drawn) == 4 and len(set(drawn)) == 4  # classical's blue is not reused


def test_landmark_panels_say_which_colour_is_which_scale():
    img = np.zeros((60, 80, 3), np.uint8)
    boxes = np.array([[0, 0, 10, 10], [5, 5, 20, 20], [30, 30, 10, 10]], float)
    fig = viz.plot_landmark_panels(
        {"q": (img, boxes)}, colors_by=[0, 0, 1], group_labels={0: "scale 0.16", 1: "scale 0.25"}
    )
    texts = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    assert texts == ["scale 0.16", "scale 0.25"]


def test_pair_and_coverage_figures_of_runs(tiny_synthetic):
    import matplotlib.pyplot as plt

    from vpr_core import run_method

    runs = [
        run_method(m, tiny_synthetic, keep_descriptors=True, backbone="hog", n_bootstrap=0)
        for m in ("dense", "global")
    ]
    fig = viz.plot_pair(tiny_synthetic, runs[0], query=1)
    assert "query 1 vs reference 1 (ground truth)" in fig._suptitle.get_text()
    fig, table = viz.plot_coverage_comparison(tiny_synthetic, runs, index=0)
    assert list(table.index) == ["dense", "global"] and len(fig.axes) >= 2
    assert table.loc["global", "covered share (mean)"] == 1.0  # the whole-image box
    assert 0 < table.loc["dense", "covered share (this image)"] <= 1
    # issue 54: the panels compare a count, so they share one colour scale; the outlines are
    # said on each colour bar
    scales = {  # the coverage layers: translucent (the image under them is opaque)
        im.get_clim() for ax in fig.axes for im in ax.get_images() if im.get_alpha() is not None
    }
    assert len(scales) == 1 and scales.pop()[1] > 1, scales
    bars = [ax.get_ylabel() for ax in fig.axes if "boxes covering" in ax.get_ylabel()]
    assert len(bars) == 2 and all("white outlines:" in b for b in bars)
    assert "one colour scale" in fig._suptitle.get_text()
    plt.close("all")


def test_layout_problems_finds_cut_text_and_a_legend_over_the_curves():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot(np.linspace(0, 1, 50), np.linspace(1, 0, 50), label="a curve")
    ax.set_title("a title far too long to fit on a figure this narrow, so it is cut at the edge")
    ax.legend(loc="center")  # right over the diagonal
    problems = viz.layout_problems(fig)
    assert any("extends beyond the canvas" in p for p in problems)
    assert any("legend covers" in p for p in problems)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 3), constrained_layout=True)
    ax.plot([0, 1], [1, 0], label="a curve")
    ax.set_title("short")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
    assert viz.layout_problems(fig) == []
    plt.close(fig)


def test_scale_distribution_wraps_a_dataset_line_longer_than_the_figure():
    """Nordland's dataset line (name, subsampling, settings) was cut at the right edge of the
    committed Fig. 6; a line that fits stays one line."""
    import matplotlib.pyplot as plt

    counts = {"query": np.arange(10), "reference": np.arange(10)}
    line = (
        "nordland_64x32, every 50th place: 72 of 72 queries with ground truth, tolerance 0, "
        "protocol ratio, pooling crop"
    )
    fig = viz.plot_scale_distribution(counts, title=f"scheme: landmarks per scale\n{line}")
    assert viz.layout_problems(fig) == []
    assert fig.axes[0].get_title(loc="left").count("\n") == 2
    short = "gardens_point_mini: 10 of 10 queries with ground truth, tolerance 0, protocol ratio"
    fig2 = viz.plot_scale_distribution(counts, title=f"scheme\n{short}")
    assert fig2.axes[0].get_title(loc="left") == f"scheme\n{short}"
    plt.close(fig)
    plt.close(fig2)


def test_save_warns_about_a_broken_layout(tmp_path):
    import matplotlib.pyplot as plt

    from vpr_core.notices import VPRWarning

    fig, ax = plt.subplots(figsize=(3, 2))
    ax.set_title("x" * 200)
    with pytest.warns(VPRWarning, match="layout of bad"):
        viz.save(fig, "bad", "t", out=tmp_path)
    plt.close(fig)


def test_pair_label_widget_starts_from_a_run_and_says_when_saved(tiny_synthetic, tmp_path):
    from vpr_core import run_method
    from vpr_core.labels._file import read_label_file

    res = run_method("dense", tiny_synthetic, keep_descriptors=True, backbone="hog", n_bootstrap=0)
    out = tmp_path / "labels.csv"
    box = viz.pair_label_widget(tiny_synthetic, res, query=0, out=out)
    yes, no, status = box.children[0].children
    n = int(status.value.split("/")[1])
    assert status.value == f"match 1/{n}" and n > 0
    for k in range(n):
        (yes if k % 2 == 0 else no).click()
    assert status.value == f"saved {n} labels to {out}" and yes.disabled and no.disabled
    rows = read_label_file(out)
    assert len(rows) == n and rows["correct"].tolist() == [k % 2 == 0 for k in range(n)]


class _ThreePlaces:
    ground_truth = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 0]], dtype=bool)


IMG = np.zeros((60, 80, 3), np.uint8)
BOXES = np.array([[0, 0, 10, 10], [5, 5, 20, 20], [30, 30, 10, 10]], float)

#: id -> (call, exception, message) of every bad input of the figure functions.
BAD_VIZ_CALLS = {
    "panels: groups": (
        lambda: viz.plot_landmark_panels({"q": (IMG, BOXES)}, colors_by=[0, 1]),
        ValueError,
        "colors_by has 2 entries for 3 boxes in panel 'q'; give one group per box",
    ),
    "panels: empty": (
        lambda: viz.plot_landmark_panels({}),
        ValueError,
        "panels is empty",
    ),
    "descriptors: shape": (
        lambda: viz.plot_descriptor_matrices({"q": np.zeros(5)}),
        ValueError,
        r"descriptors\['q'\] must have shape \(K, D\)",
    ),
    "descriptors: empty": (
        lambda: viz.plot_descriptor_matrices({}),
        ValueError,
        "descriptors is empty",
    ),
    "pair terms": (
        lambda: viz.plot_pair_terms(np.zeros(7), np.ones(3), 10, 12, 0.25),
        ValueError,
        r"distances \(7,\) and shape \(3,\) must have one entry per pair",
    ),
    "matches: labels": (
        lambda: viz.plot_labelled_matches(IMG, IMG, BOXES, BOXES, [[0, 0]], [True, False]),
        ValueError,
        r"labels \(2\) must have one entry per match \(1\)",
    ),
    "matches: boxes": (
        lambda: viz.plot_labelled_matches(IMG, IMG, BOXES[:, :3], BOXES, [[0, 0]], None),
        ValueError,
        r"boxes_q must have shape \(K, 4\)",
    ),
    "examples: none": (
        lambda: viz.plot_examples(_ThreePlaces(), indices=()),
        ValueError,
        "indices is empty; pass at least one query index",
    ),
    "examples: index": (
        lambda: viz.plot_examples(_ThreePlaces(), indices=(5,)),
        IndexError,
        r"query index 5 out of range 0\.\.2",
    ),
}


@pytest.mark.parametrize("case", BAD_VIZ_CALLS)
def test_bad_viz_inputs_raise_one_clear_line(case):
    call, exc, match = BAD_VIZ_CALLS[case]
    with pytest.raises(exc, match=match) as info:
        call()
    assert "\n" not in str(info.value)


def test_dataset_line_names_the_subset_and_the_ground_truth():
    from fake_results import result_of

    from vpr_study.viz import dataset_line

    r = result_of("r", np.eye(3), np.eye(3), dataset="nordland_64x32")
    r = dataclasses.replace(r, dataset_title="nordland_64x32, every 50th place")
    line = dataset_line([r])
    assert line == (
        "nordland_64x32, every 50th place: 3 of 3 queries with ground truth, tolerance 0, "
        "protocol ratio"
    )


def _fake_run(label, sim, gt, method=None, weighting=None, metrics=None):
    from fake_results import result_of

    from vpr_core import Dense, Matching, Method

    config = Method(method or label, Dense(), Matching(weighting=weighting))
    extra = {} if metrics is None else {"metrics": metrics}
    return result_of(label, sim, gt, config=config, method=config.name, **extra)


def test_pr_curves_colour_per_method_style_per_weighting_and_coinciding_curves_said():
    """Issue 54 item 4: runs varying in method and weighting read at a glance (the colour is
    the method, the line style the weighting); a curve that coincides with another one's,
    though not the same result, is drawn over it and its legend says so."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    plt.close("all")
    rng = np.random.default_rng(0)
    gt = np.eye(8, dtype=bool)
    sims = [0.6 * gt + rng.random((8, 8)) for _ in range(4)]
    runs = [
        _fake_run(f"{m}{' (weighting: ' + w + ')' if w else ''}", sims[i + 2 * j], gt, m, w)
        for i, m in enumerate(("dense", "classical"))
        for j, w in enumerate((None, "contrast"))
    ]
    fig = viz.plot_pr_curves(runs)
    lines = {ln.get_label().split("  ")[0]: ln for ln in fig.axes[0].get_lines()}
    colour = {k: to_hex(v.get_color()) for k, v in lines.items() if not k.startswith("chance")}
    assert colour["dense"] == colour["dense (weighting: contrast)"] != colour["classical"]
    assert colour["classical"] == colour["classical (weighting: contrast)"]
    style = {k: str(v.get_linestyle()) for k, v in lines.items()}
    assert style["dense"] == style["classical"] != style["dense (weighting: contrast)"]
    plt.close(fig)
    # the same curve, another result (its metrics differ, e.g. a tie broken otherwise)
    same = _fake_run("dense (geometry: consistency)", sims[0] * 2, gt)
    same = dataclasses.replace(same, metrics={**same.metrics, "r@5": -1.0})
    fig = viz.plot_pr_curves([runs[0], same])
    labels = (
        [t.get_text() for t in fig.legends[0].get_texts()]
        if fig.legends
        else [ln.get_label() for ln in fig.axes[0].get_lines()]
    )
    assert any("same curve as dense" in t for t in labels), labels
    plt.close(fig)
