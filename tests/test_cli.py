"""The ``vpr-study`` command line."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from vpr_study import cli


def test_eval_prints_table_and_writes_plot(tmp_path, capsys):
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "6",
            "--method",
            "dense",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    for col in (
        "AUC(ratio)",
        "R@100P",
        "R@1",
        "R@5",
        "lm s/img",
        "feat s/img",
        "match s/pair",
    ):
        assert col in out
    assert "queries with ground truth: 6 of 6" in out
    # every metric as value [interval], and the chance row (the compact view of compare)
    assert re.search(r"dense +\d\.\d{3} \[\d\.\d{3}, \d\.\d{3}\]", out)
    assert re.search(r"chance .*\d\.\d{3}", out)
    res = tmp_path / "results" / "synthetic"
    (png,) = (tmp_path / "figures" / "synthetic").glob("eval_synthetic_dense_n-places-6.png")
    assert png.stat().st_size > 0 and png.name in out  # the closing lines list every file
    csv = (res / f"{png.stem}.csv").read_text()  # the figure and its table share a name
    assert csv.startswith("method,run,") and "AUC lo" in csv
    for col in ("dataset", "root", "tolerance", "protocol", "backbone", "pooling", "version"):
        assert f",{col}," in csv.splitlines()[0] + ","
    # the committed table holds no timing and no absolute path; timings go beside it
    assert " s/img" not in csv and str(tmp_path) not in csv
    timings = (res / f"{png.stem}.timings.csv").read_text()
    assert "features s/img" in timings.splitlines()[0]


def test_eval_label_keeps_two_folder_datasets_apart(tmp_path, gardens_point_mini_root, capsys):
    import shutil

    roots = []
    for name in ("site_a", "site_b"):
        root = tmp_path / name
        for side in ("query", "reference"):
            (root / side).mkdir(parents=True)
            for i in range(3):
                shutil.copy(gardens_point_mini_root / side / f"{i}.jpg", root / side)
        roots.append(root)
    for root in roots:
        assert (
            cli.main(
                [
                    "eval",
                    "--dataset",
                    "folder",
                    "--root",
                    str(root),
                    "--method",
                    "dense",
                    "--out",
                    str(tmp_path / "out"),
                ]
            )
            == 0
        )
    for name in ("site_a", "site_b"):
        found = list((tmp_path / "out" / "results" / name).glob(f"eval_{name}_dense.csv"))
        assert len(found) == 1, found


def test_seed_must_be_non_negative(capsys):
    with pytest.raises(SystemExit):
        cli.main(["eval", "--seed", "-1"])
    assert "argument --seed: must be an integer >= 0" in capsys.readouterr().err


def test_user_peer_from_a_matrix_enters_the_table(tmp_path, capsys):
    import numpy as np

    sim = np.eye(6) + 0.01 * np.arange(36).reshape(6, 6)
    np.save(tmp_path / "mine.npy", sim)
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "6",
            "--method",
            "dense",
            "--peer",
            f"MyNet={tmp_path / 'mine.npy'}",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if ln.startswith("MyNet")]  # one row per method
    assert "1.000 [1.000, 1.000]" in lines[0]  # the diagonal is always top-1
    assert any(re.search(r"\b(higher|lower|inconclusive)\b", ln) for ln in lines)
    assert os.environ.get("VPR_OUTPUT_DIR") != str(tmp_path)  # --out is per command


def test_eval_unknown_method_lists_valid(capsys):
    with pytest.raises(SystemExit):
        cli.main(["eval", "--method", "edgebox"])
    assert "valid: classical, dense" in capsys.readouterr().err


def test_eval_unknown_dataset_is_a_clear_error(capsys):
    rc = cli.main(["eval", "--dataset", "nowhere", "--method", "dense"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "nowhere" in err and "synthetic" in err


def test_eval_missing_root_is_a_clear_error(tmp_path, capsys):
    rc = cli.main(
        ["eval", "--dataset", "folder", "--root", str(tmp_path / "missing"), "--method", "dense"]
    )
    assert rc == 2
    assert "missing" in capsys.readouterr().err


def test_run_with_missing_root_fails_fast_with_the_loaders_message(tmp_path, capsys):
    rc = cli.main(["run", "--dataset", "folder", "--root", str(tmp_path / "missing")])
    assert rc == 2
    assert "does not exist" in capsys.readouterr().err


def test_unknown_backbone_is_reported_before_any_dataset_is_generated(
    tmp_path, monkeypatch, capsys
):
    from vpr_core import datasets

    def boom(*a, **k):
        raise AssertionError("the dataset must not be loaded before the backbone is checked")

    monkeypatch.setattr(datasets, "load_dataset", boom)
    with pytest.raises(SystemExit):
        cli.main(["eval", "--dataset", "synthetic", "--backbone", "resnet9000"])
    err = capsys.readouterr().err
    assert "resnet9000" in err and "efficientnet_lite0" in err


def test_unreadable_weights_file_is_named(tmp_path, capsys):
    bad = tmp_path / "alexnet.pth"
    bad.write_bytes(b"not a checkpoint")
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "4",
            "--method",
            "dense",
            "--backbone",
            "alexnet_conv3",
            "--weights",
            str(bad),
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert rc == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "Traceback" not in err


def test_log_output_follows_the_current_stderr(monkeypatch):
    """The console handler must not keep a stream that was replaced and closed."""
    import io
    import logging
    import sys

    from vpr_core.utils import configure_logging

    first = io.StringIO()
    monkeypatch.setattr(sys, "stderr", first)
    configure_logging()
    first.close()
    second = io.StringIO()
    monkeypatch.setattr(sys, "stderr", second)
    logging.getLogger("vpr_core").warning("hello %d", 1)
    assert "[vpr_core WARNING] hello 1" in second.getvalue()


def test_eval_protocol_is_named_in_table_file_and_csv(tmp_path, capsys):
    import pandas as pd

    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "6",
            "--method",
            "global",
            "--backbone",
            "hog",
            "--protocol",
            "vpr_bench",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "AUC(vpr_bench)" in out
    (csv,) = (tmp_path / "results" / "synthetic").glob(
        "eval_synthetic_global_backbone-hog*vpr_bench.csv"
    )
    assert set(pd.read_csv(csv)["protocol"]) == {"vpr_bench"}
    with pytest.raises(SystemExit):  # argparse names the valid choices
        cli.main(["eval", "--protocol", "nope"])


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--root", ""], "--root is empty"),
        (["--method", "dense", "dense"], "dense twice"),
        (["--protocol", "multi_match"], "add --n-bootstrap 0"),
        (["--device", "meta"], "--device must be cpu, cuda"),
        (["--label", "../../x"], "one folder name"),
        (["--label", "/tmp/x"], "one folder name"),
    ],
)
def test_bad_arguments_are_refused_before_any_work(monkeypatch, capsys, argv, message):
    from vpr_core import datasets

    def boom(*a, **k):
        raise AssertionError("nothing may be loaded before the arguments are checked")

    monkeypatch.setattr(datasets, "load_dataset", boom)
    with pytest.raises(SystemExit):
        cli.main(["eval", "--dataset", "synthetic", *argv])
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_an_infinite_scheduler_timeout_is_refused_at_parse_time(monkeypatch, capsys):
    monkeypatch.setenv("VPR_SCHEDULER_TIMEOUT", "inf")
    with pytest.raises(SystemExit):
        cli.main(["eval", "--dataset", "synthetic"])
    assert "VPR_SCHEDULER_TIMEOUT='inf' is not a positive number" in capsys.readouterr().err


def test_help_names_every_loader_and_the_readme_peer_dataset(capsys):
    with pytest.raises(SystemExit):
        cli.main(["eval", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "utm" in out and "vpr_bench" in out and "(e.g. GardensPoint)" in out


def test_two_runs_with_different_settings_leave_two_files(tmp_path, capsys):
    base = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "global"]
    base += ["--backbone", "hog", "--n-bootstrap", "0", "--out", str(tmp_path)]
    assert cli.main(base) == 0
    assert cli.main([*base, "--protocol", "vpr_bench"]) == 0
    assert cli.main([*base, "--shortlist", "3"]) == 0
    tables = sorted((tmp_path / "results" / "synthetic").glob("eval_synthetic_*[!s].csv"))
    figures = sorted((tmp_path / "figures" / "synthetic").glob("eval_synthetic_*.png"))
    assert len(tables) == 3 and [p.stem for p in tables] == [p.stem for p in figures]
    assert cli.main(base) == 0  # the same settings again: the same file
    assert len(list((tmp_path / "results" / "synthetic").glob("eval_*[!s].csv"))) == 3


def test_file_based_ground_truth_is_described_not_called_tolerance_0(
    tmp_path, gardens_point_mini_root, capsys
):
    import shutil

    import numpy as np

    root = tmp_path / "corridor"
    for side in ("query", "reference"):
        (root / side).mkdir(parents=True)
        for i in range(3):
            shutil.copy(gardens_point_mini_root / side / f"{i}.jpg", root / side)
    np.save(root / "ground_truth.npy", np.array([[1, 1, 0], [0, 1, 0], [0, 0, 1]], bool))
    argv = ["eval", "--dataset", "folder", "--root", str(root), "--method", "global"]
    assert cli.main([*argv, "--backbone", "hog", "--n-bootstrap", "0", "--out", str(tmp_path)]) == 0
    out = " ".join(capsys.readouterr().out.split())  # prose wraps at the terminal's width
    assert "ground truth from file: 1-2 correct references per query (median 1)" in out
    assert "tolerance=0" not in out and "tolerance 0" not in out


def test_eval_spatial_is_a_matching_option_in_the_run_key(tmp_path, capsys):
    args = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "dense"]
    assert cli.main([*args, "--spatial", "consistency", "--out", str(tmp_path)]) == 0
    assert cli.main([*args, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "dense (geometry: consistency)" in out
    tables = sorted((tmp_path / "results" / "synthetic").glob("eval_*[!s].csv"))
    assert len(tables) == 2  # on and off never share a file
    runs = {t.read_text().splitlines()[1].split(",")[1] for t in tables}
    assert runs == {"dense", "dense(spatial=consistency)"}


def test_eval_spatial_both_pairs_each_method_with_itself(tmp_path, capsys):
    args = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "dense", "global"]
    assert cli.main([*args, "--spatial", "both", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "geometry-aware score, each method with minus without" in out
    assert "dAUC vs each row's baseline" in out  # not "vs dense" for the global row
    folder = tmp_path / "results" / "synthetic"
    (table,) = folder.glob("eval_*_geometry.csv")
    rows = table.read_text().splitlines()
    header = rows[0].split(",")
    got = {
        r.split(",")[header.index("run")]: r.split(",")[header.index("baseline")] for r in rows[1:]
    }
    assert got == {
        "dense(spatial=consistency)": "dense",
        "global(spatial=consistency)": "global",
    }


def test_piped_output_has_the_stage_lines_alone_not_progress_bars_beside_them(monkeypatch):
    """Issue 54 item 6: without a terminal a stage's heartbeat lines are its progress; the
    stage's own progress bars (vpr_core.utils.progress) are off meanwhile, on again after."""
    from vpr_core.utils import progress

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    lines = cli.StageLines()
    lines.enabled = True  # stderr piped
    with lines.stage("features"):
        assert progress(range(3)).disable
    assert not progress(range(3)).disable
    monkeypatch.setenv("TQDM_DISABLE", "1")  # the user's own setting is kept
    with lines.stage("features"):
        pass
    assert os.environ["TQDM_DISABLE"] == "1"


def test_piped_output_is_not_wrapped_at_a_terminals_default_80_columns(monkeypatch):
    """Issue 54 item 6: stdout piped and no $COLUMNS: eval's text is fitted to PIPED_WIDTH, not
    to the 80 columns a missing terminal defaults to; $COLUMNS still decides when set."""
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.setattr("sys.stdout.isatty", lambda: False, raising=False)
    assert cli.output_width() == cli.PIPED_WIDTH > 80
    monkeypatch.setenv("COLUMNS", "80")
    assert cli.output_width() == 80


def test_top_level_help_answers_without_torch():
    """Issue 54: ``vpr-study --help`` is answered from the standard library (no torch, no
    pipeline), and says what the full parser says."""
    code = (
        "import sys, contextlib, io\n"
        "from vpr_study.usage import main\n"
        "out = io.StringIO()\n"
        "with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):\n"
        "    main(['--help'])\n"
        "print(sorted(m for m in ('torch', 'vpr_core', 'numpy') if m in sys.modules))\n"
        "print(out.getvalue())\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded, _, text = done.stdout.partition("\n")
    assert loaded == "[]"
    from vpr_study.cli import build_parser

    assert text.strip() == build_parser().format_help().strip()
    script = Path(sys.executable).with_name("vpr-study")
    if script.is_file():  # the installed entry point takes the same path
        assert (
            "usage: vpr-study"
            in subprocess.run(
                [str(script), "--help"], capture_output=True, text=True, check=True
            ).stdout
        )
