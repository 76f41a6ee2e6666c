"""Every run of a figure told apart (issue 61): the combinations a user makes in one figure
(backbones, weightings, normalisations, peers, own schemes, scheme options), each drawn with its
own colour / line style / marker and a label that says what differs; one colour per method in
every figure, peers and a user's methods from their own palette."""

from __future__ import annotations

import dataclasses

import matplotlib
import numpy as np
import pytest
from fake_results import result_of
from matplotlib.colors import to_hex

from vpr_core import Method, get_method
from vpr_core.landmarks.schemes import Dense
from vpr_core.methods import as_method, default_label
from vpr_study.viz import METHOD_COLORS, plot_pr_curves
from vpr_study.viz.styles import OTHER_COLORS, method_color, run_styles

matplotlib.use("Agg")

GT = np.eye(12, dtype=bool)
ENCODER = {"backbone": "efficientnet_lite0", "pooling": "crop", "input_size": 128,
           "weights_sha256": "a" * 64}  # fmt: skip


@dataclasses.dataclass(frozen=True)
class CentreGrid:
    """A user's scheme (a frozen dataclass with boxes(image))."""

    g: int = 3

    def boxes(self, image: np.ndarray) -> np.ndarray:
        return np.zeros((self.g * self.g, 4))


def _run(method, seed: int, label: str | None = None, shortlist=None, **encoder):
    """A result as run_method makes it (its label run_method's default), on a matrix of its own."""
    config = as_method(method) if not isinstance(method, Method) else method
    enc = {**ENCODER, **encoder}
    sim = GT + np.random.default_rng(seed).random(GT.shape) * (0.6 + 0.2 * (seed % 7))
    return result_of(
        label or default_label(config, enc),
        sim,
        GT,
        config=config,
        method=config.name,
        encoder=enc,
        shortlist=shortlist,
    )


def _peer(name: str, seed: int, normalise: str | None = None):
    sim = GT + np.random.default_rng(seed).random(GT.shape)
    config = {"name": f"peer:{name}", "source": "VPR-Bench"}
    label = f"{name} (VPR-Bench)"
    if normalise:
        config["normalise"] = normalise
        label += f" (normalised: {normalise})"
    return result_of(label, sim, GT, config=config, method=f"peer:{name}")


def _module(name: str) -> dict:
    return {"backbone": name, "module": f"__main__.{name}", "input_size": 64,
            "weights_sha256": ""}  # fmt: skip


def _user_runs() -> list:
    """The runs a user puts in one figure in an afternoon."""
    mine = Method("mine", Dense(scales=(0.25,), per_scale=100))
    return [
        _run("dense", 0),
        _run(get_method("dense", weighting="contrast"), 1),
        _run(get_method("dense", weighting="idf"), 2),
        _run(get_method("dense", weighting="two_sided"), 3),
        _run(get_method("dense", normalise="query_batch"), 4),
        _run(get_method("dense", normalise="database"), 5),
        _run(get_method("dense", weighting="two_sided", normalise="query_batch"), 6),
        _run("dense", 7, **_module("TinyNet")),
        _run("dense", 8, label="dense, TinyNet", **_module("TinyNet")),
        _run("dense", 9, backbone="hog", input_size=64),
        _run("dense", 10, pooling="roi"),
        _run("dense", 11, shortlist=25),
        _run(get_method("dense", scales=(0.25,), per_scale=100), 12),
        _run(CentreGrid(), 13),
        _run(CentreGrid(g=4), 14),
        _run(mine, 15),
        _run("classical", 16),
        _run(get_method("classical", weighting="contrast"), 17),
        _run("selection_scheme1", 18),
        _run("global", 19),
        _run(get_method("overlap_scheme1", iou_threshold=0.4), 20),
        _run("overlap_scheme1", 21),
        _peer("NetVLAD", 22),
        _peer("HOG", 23),
        _peer("NetVLAD", 24, normalise="database"),
    ]


def _drawn(fig) -> list[tuple]:
    """``(colour, line style with its dashes, marker, fill)`` of every run drawn (not chance)."""
    ax = fig.axes[0]
    out = []
    for ln in ax.get_legend().legend_handles:
        if ln.get_label().startswith("chance"):
            continue
        out.append(
            (
                to_hex(ln.get_color()),
                ln.get_linestyle(),
                str(getattr(ln, "_unscaled_dash_pattern", "")),
                ln.get_marker(),
            )
        )
    return out


def test_every_run_a_user_makes_is_drawn_apart_and_labelled_apart():
    runs = _user_runs()
    fig = plot_pr_curves(runs, title="an afternoon")
    drawn = _drawn(fig)
    assert len(drawn) == len(runs)
    alike = {d for d in drawn if drawn.count(d) > 1}
    assert not alike, f"runs drawn alike (colour, style, marker): {alike}"
    texts = [t.get_text().split("  ")[0] for t in fig.axes[0].get_legend().get_texts()][:-1]
    assert len(set(texts)) == len(texts), texts
    # each label says what differs from the others
    assert texts[7] == "dense (backbone: TinyNet)"  # run_method's label names a user's module
    assert texts[8] == "dense, TinyNet"  # a user's label that says it is kept
    assert "backbone: hog" in texts[9] and "pooling roi" in texts[10]
    assert "shortlist k=25" in texts[11] and "0.25 x 100" in texts[12]
    assert texts[13] == "CentreGrid" and "g=4" in texts[14]
    assert "weighting: contrast" in texts[1] and "normalised: database" in texts[5]
    assert texts[-1] == "NetVLAD (VPR-Bench) (normalised: database)"


def test_one_colour_per_method_in_every_figure_others_from_their_own_palette():
    runs = _user_runs()
    styles = run_styles(runs)
    for r, st in zip(runs, styles, strict=True):
        if r.method in METHOD_COLORS:
            assert to_hex(st.color) == to_hex(METHOD_COLORS[r.method]), r.label
        else:  # a user's scheme or method, a peer: never a paper method's colour
            assert to_hex(st.color) in {to_hex(c) for c in OTHER_COLORS}, r.label
    # the weighting is the line style, in every figure
    assert styles[1].linestyle != styles[0].linestyle == styles[16].linestyle
    assert styles[1].linestyle == styles[17].linestyle  # contrast, for dense and classical
    # a method keeps its colour in another figure with other runs
    again = run_styles([runs[13], runs[22], runs[0]])
    assert to_hex(again[0].color) == to_hex(styles[13].color)
    assert to_hex(again[1].color) == to_hex(styles[22].color)
    assert method_color("global") == METHOD_COLORS["global"]
    assert len(set(METHOD_COLORS.values())) == len(METHOD_COLORS)


@pytest.mark.parametrize("k", [2, 3, 5])
def test_any_few_runs_of_a_users_figure_are_drawn_apart(k):
    """Every k-subset of consecutive runs (the figures a user draws from the same cells)."""
    runs = _user_runs()
    for i in range(len(runs) - k + 1):
        styles = run_styles(runs[i : i + k])
        idents = [(to_hex(s.color), str(s.linestyle), s.marker) for s in styles]
        assert len(set(idents)) == k, [s.label for s in styles]
        assert len({s.label for s in styles}) == k


def test_a_run_given_twice_and_an_unknown_setting_are_still_drawn_apart():
    a = _run("dense", 0)
    b = _run("dense", 1)  # the same configuration, another matrix (e.g. another seed)
    c = _run("dense", 2, label="dense")
    styles = run_styles([a, b, c])
    assert len({(to_hex(s.color), str(s.linestyle), s.marker) for s in styles}) == 3
    assert len({s.label for s in styles}) == 3


def test_coinciding_curves_are_drawn_and_said():
    a = _run("classical", 0)
    b = dataclasses.replace(a)
    b.method, b.label, b.config = (
        "selection_scheme1",
        "selection_scheme1",
        get_method("selection_scheme1"),
    )
    fig = plot_pr_curves([a, b, _run("dense", 3)])
    handles = fig.axes[0].get_legend().legend_handles
    assert "same curve as classical" in handles[1].get_label()
    assert to_hex(handles[1].get_color()) == to_hex(METHOD_COLORS["selection_scheme1"])
    assert handles[1].get_fillstyle() == "none" and handles[1].get_marker() not in ("", "None")
    # drawn: its hollow markers lie on classical's line
    lines = [ln for ln in fig.axes[0].lines if ln.get_label() == handles[1].get_label()]
    assert lines and np.array_equal(lines[0].get_ydata(), fig.axes[0].lines[0].get_ydata())
