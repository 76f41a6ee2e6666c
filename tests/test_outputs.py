"""Where outputs go and how they are written: the output root from any working directory,
labels that stay one folder, tables without machine-specific cells, concurrent writers, the
layout check, and the ground-truth wording."""

from __future__ import annotations

import logging
import subprocess
import sys
import threading
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from vpr_core import paths  # noqa: E402
from vpr_core.datasets.ground_truth import ground_truth_text  # noqa: E402
from vpr_study import outputs  # noqa: E402
from vpr_study.viz import base  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def test_a_kernel_in_notebooks_reads_and_writes_under_the_project_root(tmp_path):
    """A kernel started in notebooks/ (as JupyterLab does) without any VPR_* setting."""
    code = (
        "from vpr_core import paths, utils; from vpr_study import outputs; "
        "print(paths.output_root()); print(paths.cache_root()); print(outputs.figures_dir('x'))"
    )
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    out = subprocess.run(
        [sys.executable, "-c", code.replace("'x'", "None")],
        cwd=REPO / "notebooks",
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    # a user's own figures go to the git-ignored user/ (the study's kernels get VPR_OUTPUT_DIR)
    assert out == [str(REPO), str(REPO / ".cache"), str(REPO / "user" / "figures")]
    assert not (REPO / "notebooks" / ".cache").exists()


def test_output_root_rules(tmp_path, monkeypatch):
    monkeypatch.delenv("VPR_OUTPUT_DIR", raising=False)
    monkeypatch.delenv("VPR_CACHE_DIR", raising=False)
    monkeypatch.chdir(REPO / "notebooks")
    assert paths.project_root() == REPO and paths.output_root() == REPO
    monkeypatch.chdir(tmp_path)  # outside a checkout: the cwd
    assert paths.project_root() is None and paths.output_root() == tmp_path.resolve()
    other = tmp_path / "other"  # a foreign project with notebooks/ is not this one
    (other / "notebooks").mkdir(parents=True)
    (other / "pyproject.toml").write_text('[project]\nname = "something-else"\n')
    monkeypatch.chdir(other / "notebooks")
    assert paths.output_root() == (other / "notebooks").resolve()
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "env"))
    assert paths.output_root() == tmp_path / "env"
    with paths.using_output_root(tmp_path / "cli"):
        assert paths.output_root() == tmp_path / "cli"
        assert paths.cache_root() == tmp_path / "cli" / ".cache"
    assert paths.output_root() == tmp_path / "env"


@pytest.mark.parametrize("label", ["../../x", "/tmp/x", "a/b", "..", ""])
def test_a_label_is_one_folder_name(tmp_path, label):
    fig = plt.figure()
    with pytest.raises(ValueError, match="one folder name"):
        base.save(fig, "f", label, out=tmp_path)
    plt.close(fig)
    with pytest.raises(TypeError, match="label must be a string"):
        outputs.check_label(5)
    assert list(tmp_path.rglob("*")) == []


def test_no_library_function_writes_os_environ():
    source = "\n".join(p.read_text() for p in (REPO / "vpr_core").rglob("*.py"))
    for bad in ("os.environ[", "os.environ.update", "os.environ.pop", "os.environ.setdefault"):
        assert bad not in source, bad
    assert "putenv" not in source


def test_committed_tables_hold_no_timing_and_no_absolute_root(tmp_path):
    table = pd.DataFrame(
        {
            "AUC": [0.5, 0.7],
            "features s/img": [0.1, 0.2],
            "matching two images (s)": [1.0, 2.0],
            "root": [str(tmp_path / "data" / "corridor"), None],
        },
        index=pd.Index(["dense", "classical"], name="method"),
    )
    path = base.save(table, "t", "lab", out=tmp_path)
    saved = path.read_text()
    assert "s/img" not in saved and "(s)" not in saved and str(tmp_path) not in saved
    assert pd.read_csv(path)["root"].tolist()[0] == "corridor"
    timings = pd.read_csv(path.with_name("t.timings.csv"))
    assert list(timings.columns) == ["method", "features s/img", "matching two images (s)"]
    ignored = subprocess.run(
        ["git", "check-ignore", "-q", "results/synthetic/table5_cost.timings.csv"], cwd=REPO
    )
    assert ignored.returncode == 0, "timings files must be git-ignored"
    cost = pd.DataFrame({"method": ["dense"], "extract landmarks (s/img)": [0.1]})
    only = base.save(cost, "table5_cost", "lab", out=tmp_path)
    assert only.name == "table5_cost.timings.csv" and not only.with_name("table5_cost.csv").exists()


def test_replacing_a_file_with_other_content_is_said(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="vpr_core")
    logging.getLogger("vpr_core").propagate = True
    try:
        base.save(pd.DataFrame({"a": [1]}), "t", "lab", out=tmp_path)
        base.save(pd.DataFrame({"a": [1]}), "t", "lab", out=tmp_path)
        assert "replaced" not in caplog.text  # same content: nothing to say
        base.save(pd.DataFrame({"a": [2]}), "t", "lab", out=tmp_path)
    finally:
        logging.getLogger("vpr_core").propagate = False
    assert f"replaced {tmp_path / 'results' / 'lab' / 't.csv'}" in caplog.text


def test_concurrent_writers_never_mix_a_figure_and_its_table(tmp_path):
    """Two writers, same label and stem: after every round the table and the figure come from
    the same writer, and no writer fails on another's temporary file."""

    def figure(k: int) -> Figure:
        fig = Figure(figsize=(3, 3))
        FigureCanvasAgg(fig)  # no pyplot: each thread draws its own figure
        fig.add_subplot().plot([0, 1], [k, 1 - k])
        fig.tight_layout()
        return fig

    pngs = {base.save(figure(k), f"ref{k}", "lab", out=tmp_path).read_bytes(): k for k in (0, 1)}
    errors: list[BaseException] = []

    def write(k: int) -> None:
        table, fig = pd.DataFrame({"writer": [k]}), figure(k)
        try:
            for _ in range(15):
                base.save_all([("run", table), ("run", fig)], "lab", out=tmp_path)
        except BaseException as exc:  # pragma: no cover - the failure being tested
            errors.append(exc)

    folder_csv = tmp_path / "results" / "lab" / "run.csv"
    folder_png = tmp_path / "figures" / "lab" / "run.png"
    threads = [threading.Thread(target=write, args=(k,)) for k in (0, 1, 0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert pd.read_csv(folder_csv)["writer"][0] == pngs[folder_png.read_bytes()]
    assert not [p for p in tmp_path.rglob("*.tmp")]


def test_a_failed_write_names_the_file(tmp_path):
    def full(tmp: Path) -> None:
        raise OSError(28, "No space left on device")

    target = tmp_path / "x.csv"
    with pytest.raises(OSError, match=f"cannot write {target}.*No space left"):
        base._staged(target, full)
    assert list(tmp_path.iterdir()) == []


def test_layout_check_catches_a_cut_subtitle():
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1], [0, 1])
    fig.suptitle("a subtitle far too long for this small canvas, cut at both edges " * 2)
    problems = base.layout_problems(fig)
    assert any("a subtitle far too long" in p for p in problems), problems
    fig.suptitle("short")
    assert base.layout_problems(fig) == []
    plt.close(fig)


def test_an_invisible_curve_gets_a_note():
    from vpr_study.viz.curves import _curve_note

    assert "no query correctly matched" in _curve_note(np.zeros(5), np.r_[1.0, np.zeros(4)])
    assert _curve_note(np.linspace(0, 1, 5), np.ones(5)) == ""


def test_ground_truth_wording():
    gt = np.zeros((4, 10), bool)
    for q, n in enumerate([1, 5, 5, 0]):
        gt[q, :n] = True
    text = ground_truth_text(gt, 0, from_file=True)
    assert text == "ground truth from file: 1-5 correct references per query (median 5)"
    assert ground_truth_text(gt, 2, from_file=False) == "tolerance 2"
    assert "widened by 1 frames" in ground_truth_text(gt, 1, from_file=True)


def test_no_progress_bars_when_stderr_is_not_a_terminal(monkeypatch, capsys):
    import io

    from vpr_core.utils import progress

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    monkeypatch.delenv("VPR_PROGRESS", raising=False)
    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    assert list(progress(range(3), total=3, desc="features")) == [0, 1, 2]
    assert capsys.readouterr().err == ""  # a redirected log: no bar, no cleared blank line

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    screen = Terminal()
    assert list(progress(range(3), total=3, desc="features", file=screen)) == [0, 1, 2]
    assert "features" in screen.getvalue()


def test_figures_say_when_ground_truth_comes_from_a_file(tmp_path, tiny_synthetic):
    """Issue 26 item 5: a correspondence file is not "tolerance 0" in a figure's subtitle."""
    import shutil

    from vpr_core import run_method
    from vpr_core.datasets import load_dataset
    from vpr_study.viz import plot_pr_curves

    root = tmp_path / "corridor"
    for side, files in (
        ("query", tiny_synthetic.query_paths),
        ("reference", tiny_synthetic.reference_paths),
    ):
        (root / side).mkdir(parents=True)
        for p in files:
            shutil.copy(p, root / side / Path(p).name)
    n = len(tiny_synthetic.query_paths)
    rows = [f"{q},{q}" for q in range(n)] + [f"{q},{q + 1}" for q in range(0, n - 1, 2)]
    (root / "ground_truth.csv").write_text("\n".join(rows) + "\n")
    result = run_method("dense", load_dataset("folder", root), n_bootstrap=20)
    expected = "ground truth from file: 1-2 correct references per query (median 1.5)"
    assert result.ground_truth_from_file and expected in repr(result)
    title = plot_pr_curves([result]).axes[0].get_title(loc="left")
    assert expected in title and "tolerance" not in title
    aligned = run_method("dense", tiny_synthetic, n_bootstrap=20)
    assert "tolerance 0" in plot_pr_curves([aligned]).axes[0].get_title(loc="left")
    plt.close("all")


def test_statistics_panels_fit_a_file_based_ground_truth():
    from vpr_core.statistics import MatchRecord, scale_statistics_from_matches
    from vpr_study.viz import plot_asl, plot_cls, plot_cmr

    rng = np.random.default_rng(0)
    records = [
        MatchRecord(rng.integers(1, 10, 30), rng.random(30), rng.random(30) > 0.5, bool(i % 2))
        for i in range(20)
    ]
    truth = "ground truth from file: 1-2 correct references per query (median 2)"
    meta = {"dataset": "corridor", "label_method": "geometric", "queries_with_gt": [10, 10]}
    stats = scale_statistics_from_matches(records, meta={**meta, "ground_truth": truth})
    for plot in (plot_cmr, plot_cls, plot_asl):
        fig = plot(stats)
        assert truth in fig._suptitle.get_text() and base.layout_problems(fig) == []
    plt.close("all")
