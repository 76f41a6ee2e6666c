"""A researcher's afternoon in JupyterLab (issue 33): paths from notebooks/, a user's results
apart from the study's, tables that fit the terminal, figures that read, honest names, progress
outside a terminal and honest cost tables (a clean tree after a Lab session: test_lab.py)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from vpr_core import paths  # noqa: E402
from vpr_core.datasets import load_dataset  # noqa: E402
from vpr_study import outputs  # noqa: E402
from vpr_study.viz import base  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
README_ROOT = "../shared/data/gardens_point_mini"  # the README's Python example


def _checkout(tmp_path: Path) -> Path:
    """A minimal checkout of this project (what :func:`paths.project_root` recognises)."""
    root = tmp_path / "clone"
    (root / "notebooks").mkdir(parents=True)
    (root / "pyproject.toml").write_text(f'[project]\nname = "{paths.PROJECT_NAME}"\n')
    return root


# 1. Paths ------------------------------------------------------------------------------------


@pytest.mark.parametrize("cwd", [".", "notebooks"])
def test_the_readme_dataset_root_loads_from_the_project_root_and_from_notebooks(
    cwd, gardens_point_mini_root, monkeypatch
):
    if (REPO / README_ROOT).resolve() != gardens_point_mini_root.resolve():
        pytest.skip("the sample data is not beside this checkout")
    monkeypatch.chdir(REPO / cwd)
    ds = load_dataset("folder", root=README_ROOT)
    assert Path(ds.root).resolve() == gardens_point_mini_root.resolve()
    assert len(ds.query_paths) == 10


def test_a_missing_root_names_every_resolved_path_and_the_working_directory(tmp_path, monkeypatch):
    clone = _checkout(tmp_path)
    monkeypatch.chdir(clone / "notebooks")
    with pytest.raises(FileNotFoundError) as err:
        load_dataset("gardens_point", root="../data/nowhere")
    msg = str(err.value)
    assert "does not exist" in msg
    assert str(tmp_path / "clone" / "data" / "nowhere") in msg  # from notebooks/
    assert str(tmp_path / "data" / "nowhere") in msg  # from the project root
    assert f"working directory {clone / 'notebooks'}" in msg
    assert "download_dataset('gardens_point'" in msg
    (clone / "data" / "here").mkdir(parents=True)  # relative to the project root: found
    assert paths.find_input("data/here") == (clone / "data" / "here").resolve()


# 2. A user's results apart from the study's ---------------------------------------------------


def test_a_users_cells_save_into_the_ignored_user_area_and_the_study_keeps_its_folders(
    tmp_path, monkeypatch
):
    monkeypatch.delenv("VPR_OUTPUT_DIR", raising=False)
    clone = _checkout(tmp_path)
    monkeypatch.chdir(clone / "notebooks")  # a kernel of JupyterLab, no setting chosen
    fig = plt.figure(figsize=(2, 2))
    fig.add_subplot().plot([0, 1])  # a figure with no axes is refused (issue 54)
    table = pd.DataFrame({"run": ["a"], "AUC": [0.5]})
    written = base.save_all([("mine", fig), ("mine", table)], "gardens_point_mini")
    assert written == [
        clone / "user" / "figures" / "gardens_point_mini" / "mine.png",
        clone / "user" / "results" / "gardens_point_mini" / "mine.csv",
    ]
    assert outputs.results_dir("x") == clone / "user" / "results" / "x"
    assert not (clone / "figures").exists() and not (clone / "results").exists()
    # the CLI's commands (and the benchmarks) write the study's folders
    with outputs.study_outputs():
        assert base.save(fig, "study", "gardens_point_mini") == (
            clone / "figures" / "gardens_point_mini" / "study.png"
        )
    # the study runner's kernels get the output root in VPR_OUTPUT_DIR: the study's folders
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(clone))
    assert base.save(fig, "kernel", "g") == clone / "figures" / "g" / "kernel.png"
    plt.close(fig)


def test_the_user_area_is_git_ignored_and_the_runner_hands_its_kernels_the_output_root():
    from vpr_study import execution

    ignored = subprocess.run(
        ["git", "check-ignore", "-q", "user/figures/gardens_point_mini/mine.png"], cwd=REPO
    )
    assert ignored.returncode == 0
    tracked = subprocess.run(
        ["git", "check-ignore", "-q", "figures/gardens_point_mini/mine.png"], cwd=REPO
    )
    assert tracked.returncode == 1
    # the kernels write where this label's figures go: the study's output root for the study
    # (issue 54: a label it does not commit, under user/)
    with outputs.study_outputs():
        assert execution.kernel_settings()["VPR_OUTPUT_DIR"] == str(paths.output_root())
    assert execution.kernel_settings()["VPR_OUTPUT_DIR"] == str(outputs.figures_root())


def test_a_user_kernel_in_notebooks_does_not_modify_a_tracked_file(tmp_path):
    """Subprocess in the real notebooks/ with no VPR_* setting: the figure lands in user/."""
    code = (
        "from vpr_core import paths; from vpr_study import outputs; "
        "print(outputs.figures_root()); print(paths.output_root())"
    )
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO / "notebooks",
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    assert out == [str(REPO / "user"), str(REPO)]


# 9. Feedback ---------------------------------------------------------------------------------


def test_outside_a_terminal_progress_is_a_line_with_an_estimate_every_interval(monkeypatch):
    import io
    import time

    from vpr_core import utils

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    monkeypatch.delenv("VPR_PROGRESS", raising=False)
    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    monkeypatch.setattr(utils, "LINE_INTERVAL_S", 0.05)  # 30 s in the CLI
    log = io.StringIO()  # not a TTY: a redirected log
    for _ in utils.progress(range(6), desc="features query", file=log):
        time.sleep(0.06)
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and len(lines) >= 3
    assert all(line.startswith("features query:") for line in lines)
    assert all("<" in line for line in lines)  # elapsed<remaining: the estimate
    assert lines[-1].split("|")[-1].strip().startswith("6/6")
    quick = io.StringIO()  # a loop shorter than the interval prints nothing
    monkeypatch.setattr(utils, "LINE_INTERVAL_S", 30.0)
    for _ in utils.progress(range(3), file=quick):
        pass
    assert quick.getvalue() == ""


def test_in_a_notebook_progress_is_text_a_second_tab_can_show(monkeypatch, capsys):
    import types

    from tqdm.notebook import tqdm as tqdm_widget

    from vpr_core import utils

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    monkeypatch.delenv("VPR_PROGRESS", raising=False)
    monkeypatch.setitem(sys.modules, "ipykernel", types.ModuleType("ipykernel"))
    bar = utils.progress(range(4), desc="landmarks query")
    assert not isinstance(bar, tqdm_widget)
    list(bar)
    bar.close()
    out = capsys.readouterr().out
    assert "landmarks query" in out and "4/4" in out


# 5. PR figures -------------------------------------------------------------------------------


def _pr_result(label, sim, gt, **extra):
    from fake_results import result_of

    return result_of(label, sim, gt, **extra)


def _axes_inches(fig) -> tuple[float, float]:
    fig.canvas.draw()
    bb = fig.axes[0].get_window_extent()
    return round(bb.width / fig.dpi, 3), round(bb.height / fig.dpi, 3)


def test_a_long_legend_entry_keeps_the_axes_size_on_one_line(tmp_path):
    import numpy as np

    from vpr_study.viz import plot_pr_curves

    rng = np.random.default_rng(0)
    gt = np.eye(8, dtype=bool)
    good = gt + rng.random((8, 8)) * 0.9
    zero = np.where(gt, 0.0, 1.0) + rng.random((8, 8)) * 0.1  # never correctly matched
    short = plot_pr_curves([_pr_result("dense", good, gt)], title="Fig. 7a")
    long = plot_pr_curves(
        [_pr_result("dense", good, gt)]
        + [_pr_result(f"overlap scheme {i} with a long name", zero, gt) for i in range(6)],
        title="Fig. 7a",
    )
    from vpr_study.viz.curves import PR_AXES

    assert _axes_inches(short) == _axes_inches(long) == PR_AXES
    texts = [t.get_text() for t in long.axes[0].get_legend().get_texts()]
    assert any("no curve" in t for t in texts)
    assert all("\n" not in t for t in texts)  # an entry is one line, never wrapped
    assert base.layout_problems(long) == [] and base.layout_problems(short) == []
    base.save_figure(long, tmp_path / "long.png")  # looked at: the axes stay readable
    plt.close("all")


def test_a_curve_starts_at_its_last_point_at_recall_zero_and_says_it():
    import numpy as np

    from vpr_core.evaluation import auc_pr, pr_curve
    from vpr_study.viz import plot_pr_curves

    gt = np.eye(4, dtype=bool)
    sim = np.array(  # the most confident matches are wrong: precision 1 -> 0 at recall 0
        [
            [0.51, 0.95, 0.14, 0.95],
            [0.31, 0.42, 0.83, 0.41],
            [0.55, 0.03, 0.75, 0.54],
            [0.33, 0.79, 0.3, 0.45],
        ]
    )
    curve = pr_curve(sim, gt, warn=False)
    assert (curve.recall == 0).sum() > 1  # a vertical segment at recall 0
    fig = plot_pr_curves([_pr_result("dense", sim, gt)])
    x, y = fig.axes[0].lines[0].get_data()
    assert (np.asarray(x) == 0).sum() == 1
    assert np.trapezoid(y, x) == pytest.approx(auc_pr(curve))  # the drawn area is the AUC
    assert "last point at recall 0" in fig.axes[0].get_legend().get_title().get_text()
    plt.close(fig)


# 8. Names and titles -------------------------------------------------------------------------


def test_pr_titles_name_every_non_default_setting_pooling_roi_included():
    import numpy as np

    from vpr_study.viz import plot_pr_curves
    from vpr_study.viz.curves import dataset_line

    gt = np.eye(4, dtype=bool)
    sim = gt + 0.1
    roi = {"backbone": "efficientnet_lite0", "pooling": "roi", "dim": 128}
    runs = [_pr_result(m, sim, gt, encoder=roi, shortlist=25) for m in ("dense", "classical")]
    line = dataset_line(runs)
    assert line.endswith("protocol ratio, pooling roi, shortlist k=25")
    assert "backbone" not in line  # the default is not repeated
    hog = {**roi, "backbone": "hog", "pooling": "crop"}
    assert dataset_line([_pr_result("d", sim, gt, encoder=hog, shortlist=None)]).endswith(
        "protocol ratio, backbone hog"
    )
    fig = plot_pr_curves(runs, title="Fig. 13")
    assert "pooling roi" in fig.axes[0].get_title(loc="left")
    plt.close(fig)


def test_eval_outputs_are_named_by_the_settings_that_differ_from_the_defaults(tmp_path):
    from vpr_study import cli

    def stem(*argv: str) -> str:
        args = cli.build_parser().parse_args(["eval", "--dataset", "folder", *argv])
        return cli.eval_stem(args, "corridor")

    methods = ("--method", "dense", "classical")
    assert stem(*methods) == "eval_corridor_dense+classical"
    assert stem(*methods, "--pooling", "roi") == "eval_corridor_dense+classical_pooling-roi"
    assert stem(*methods, "--pooling", "roi", "--shortlist", "25") == (
        "eval_corridor_dense+classical_pooling-roi_shortlist-25"
    )
    assert stem("--root", str(tmp_path)) == "eval_corridor_dense"  # the label names the data
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, b = stem("--peer", f"Net={tmp_path / 'a'}"), stem("--peer", f"Net={tmp_path / 'b'}")
    assert a.startswith("eval_corridor_dense_peer-Net_") and a != b  # a hash only for files


# 4. Tables that fit, 10. honest cost tables ---------------------------------------------------


def _eval(monkeypatch, capsys, tmp_path, columns: int, *extra: str) -> str:
    from vpr_study import cli

    monkeypatch.setenv("COLUMNS", str(columns))
    # a cache of the test's own: the first run measures its seconds whatever ran before
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    argv = ["eval", "--dataset", "synthetic", "--n-places", "6", "--backbone", "hog"]
    argv += ["--method", "dense", "global", "--out", str(tmp_path), *extra]
    assert cli.main(argv) == 0
    return capsys.readouterr().out


def test_eval_tables_fit_80_and_160_columns_one_row_per_method(tmp_path, monkeypatch, capsys):
    out = _eval(monkeypatch, capsys, tmp_path, 80)
    assert max(len(line) for line in out.splitlines()) <= 80, out
    rows = [ln for ln in out.splitlines() if ln.startswith(("dense ", "global "))]
    assert len(rows) == 6  # the AUC block, the R@1 block, the cost table: one row per method each
    assert re.search(
        r"^global +\d\.\d{3} \[.*\] +[-+]\d\.\d{3} \[.*\] (higher|lower|inconclusive)",
        out,
        re.MULTILINE,
    )  # the difference on the method's row
    assert re.search(r"^method +R@1 ", out, re.MULTILINE)  # R@1 kept at 80 columns
    assert "not shown at 80 columns: R@100P" in out
    # the cost table says where its seconds come from: measured now, then read from the cache
    assert re.search(r"^dense .* this run$", out, re.MULTILINE)
    stem = "eval_synthetic_dense+global_backbone-hog_n-places-6"
    table = pd.read_csv(tmp_path / "results" / "synthetic" / f"{stem}.csv")
    for col in ("R@5 hi", "dR@100P verdict", "dR@1 lo", "queries"):
        assert col in table.columns  # the CSV keeps everything
    wide = _eval(monkeypatch, capsys, tmp_path, 160)
    assert max(len(line) for line in wide.splitlines()) <= 160
    rows = [ln for ln in wide.splitlines() if ln.startswith(("dense ", "global "))]
    assert len(rows) == 4 and "R@1" in wide and "dR@1 vs dense" in wide
    assert re.search(r"^dense .* earlier run$", wide, re.MULTILINE)  # read from the cache
    everything = _eval(monkeypatch, capsys, tmp_path, 80, "--wide")
    assert "dR@100P vs dense" in everything and "not shown" not in everything


# 7. Insight tools ----------------------------------------------------------------------------


def test_chance_prints_rounded_and_keeps_exact_values():
    import numpy as np

    from vpr_core.evaluation import chance

    level = chance(np.eye(10, dtype=bool))
    assert level["r@1"] == 1 - 9 / 10 != 0.1  # 0.09999999999999998, exact
    assert "'r@1': 0.1," in repr(level) and "0.0999" not in repr(level) + str(level)
    assert dict(level) == level and isinstance(level, dict)


def test_per_query_says_when_top1_matches_are_nan():
    import numpy as np

    from vpr_core.evaluation.queries import per_query
    from vpr_core.notices import VPRWarning

    gt = np.eye(4, dtype=bool)
    run = _pr_result("dense", gt + 0.1, gt, boxes=None, descriptors=None)
    with pytest.warns(VPRWarning, match=r"'top-1 matches' is NaN for dense.*keep_descriptors=True"):
        table = per_query(run)
    assert table["top-1 matches"].isna().all()


# 11. Figures that say something --------------------------------------------------------------


def test_the_coverage_overlay_leaves_the_image_visible():
    import numpy as np

    from vpr_core.landmarks import dense_sampling
    from vpr_study.viz import plot_coverage

    rng = np.random.default_rng(0)
    image = np.kron(rng.integers(0, 256, (12, 16)), np.ones((20, 20))).astype(np.uint8)
    image = np.repeat(image[:, :, None], 3, axis=2)  # 240 x 320 blocks of grey
    fig = plot_coverage(image, dense_sampling(image.shape[:2]))
    fig.canvas.draw()
    bb = fig.axes[0].get_window_extent()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    h = rgba.shape[0]
    shown = rgba[int(h - bb.y1) + 2 : int(h - bb.y0) - 2, int(bb.x0) + 2 : int(bb.x1) - 2, :3]
    ys = np.linspace(0, shown.shape[0] - 1, 12 * 4).astype(int)
    xs = np.linspace(0, shown.shape[1] - 1, 16 * 4).astype(int)
    seen = shown[np.ix_(ys, xs)].mean(axis=2)
    truth = image[np.ix_(np.linspace(0, 239, 48).astype(int), np.linspace(0, 319, 64).astype(int))]
    slope = np.polyfit(truth[:, :, 0].ravel().astype(float), seen.ravel(), 1)[0]
    assert slope > 0.55  # the image keeps most of its contrast (0.4 under the old alpha 0.6)
    plt.close(fig)


def test_a_shortlist_coverage_figure_says_it_equals_the_exhaustive_one(tiny_synthetic):

    import numpy as np

    from vpr_core.landmarks import dense_sampling
    from vpr_study.viz import plot_coverage_comparison

    size = tiny_synthetic.image_size("reference", 0)
    boxes = {"reference": [dense_sampling(size) for _ in range(len(tiny_synthetic))]}
    gt = np.asarray(tiny_synthetic.ground_truth, dtype=bool)

    def run(shortlist):
        return _pr_result("dense", gt + 0.1, gt, boxes=boxes, shortlist=shortlist)

    fig, _ = plot_coverage_comparison(tiny_synthetic, [run(25)], index=0)
    assert "shortlist does not change the landmarks" in fig._suptitle.get_text()
    fig, _ = plot_coverage_comparison(tiny_synthetic, [run(None)], index=0)
    assert "shortlist" not in fig._suptitle.get_text()
    plt.close("all")


# 6. The disagreements figure -----------------------------------------------------------------


def test_disagreements_draw_the_deciding_matches_and_label_rows_and_columns(
    tiny_synthetic, tmp_path
):
    from matplotlib.patches import Rectangle

    from vpr_core import run_method
    from vpr_study.viz import plot_disagreements, save
    from vpr_study.viz.disagreements import TOP_TERMS

    runs = [run_method(m, tiny_synthetic, keep_descriptors=True) for m in ("dense", "classical")]
    fig = plot_disagreements(tiny_synthetic, *runs, n=3)  # a figure, like every plot_*
    table = fig.table  # the rows shown, in order
    assert "ratio (lower = more confident)" in table.columns
    assert save(fig, "d", "mine", out=tmp_path).suffix == ".png"  # issue 61: not a tuple
    assert save(fig.table, "d", "mine", out=tmp_path).suffix == ".csv"
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[0].startswith("[dense] query | its top-1 reference")
    assert titles[1].startswith("[classical] query | its top-1 reference")
    assert titles[2].startswith("[correct] reference") and "QUERY" in titles[2]
    assert all("QUERY" in t for t in titles[2::3])  # every row names its query
    wrong = [t for t in titles if ": wrong: reference " in t]
    assert wrong and all(re.search(r"wrong: reference \d+, \d+ frames? away", t) for t in wrong)
    assert "all wrong (another place)" not in " ".join(t.split("\n")[0] for t in titles)
    for ax in [a for i, a in enumerate(fig.axes) if i % 3 != 2]:
        boxes = [p for p in ax.patches if isinstance(p, Rectangle)]
        assert len(boxes) <= 2 * TOP_TERMS  # the few largest terms, not 50-100 boxes
        assert f"the {min(TOP_TERMS, len(boxes) // 2)} largest terms drawn" in ax.get_title()
    plt.close("all")


def test_a_wrong_top1_next_to_the_correct_place_is_not_called_another_place():
    """Issue 61: on real frame-aligned data a wrong top-1 one frame from a correct reference may
    show the same scene: its matches are drawn unlabelled (yellow), not wrong (red)."""
    import numpy as np

    from vpr_study.viz.disagreements import NEAR_FRAMES, _frames_away, _panel_title

    row = pd.Series({"run": "dense", "top-1": 6, "top-1 correct": False,
                     "first correct rank": 2, "ratio": 0.9})  # fmt: skip
    assert _frames_away(row, [5], frames=True) == 1 <= NEAR_FRAMES
    assert _frames_away(row, [5], frames=False) is None  # ground truth from a file: no frames
    assert _frames_away(pd.Series({**row, "top-1 correct": True}), [6], frames=True) is None
    pm = type("PM", (), {"matches": np.zeros((7, 2)), "labels": np.zeros(7, bool),
                         "ground_truth": False})()  # fmt: skip
    near = _panel_title(row, pm, np.arange(5), "wrong: reference 6, 1 frame away", True)
    far = _panel_title(row, pm, np.arange(5), "wrong: reference 40, 35 frames away", False)
    assert near.endswith("unlabelled: it may show the same scene")
    assert far.endswith("all wrong (another place)")


def test_fig14_shows_the_first_image_with_a_scene_not_a_black_frame():
    """Issue 61: Nordland's first summer frames are black; Fig. 14 showed one, almost black
    under the overlay. By default it shows the first image that shows a scene."""
    from types import SimpleNamespace

    import numpy as np

    from vpr_study.viz.images import _first_visible

    rng = np.random.default_rng(0)
    scene = rng.integers(0, 255, (32, 64, 3), dtype=np.uint8)
    images = [np.zeros((32, 64, 3), np.uint8), np.full((32, 64, 3), 6, np.uint8), scene]
    ds = SimpleNamespace(reference_paths=["a", "b", "c"], query_paths=["q"],
                         load_image=lambda side, i: images[i])  # fmt: skip
    assert _first_visible(ds, "reference") == 2
    assert _first_visible(SimpleNamespace(**{**vars(ds), "reference_paths": ["a"]}),
                          "reference") == 0  # fmt: skip
