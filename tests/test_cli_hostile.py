"""The ``vpr-study`` CLI as a newcomer and a hostile user meet it: help that tells the truth, the
subcommand's usage on an error, tables within the terminal, each notice once, honest cost
provenance, progress without a terminal, a user's outputs under ``user/``, one label rule, an
option given once (issues 44.6, 44.2, 45.1, 45.4)."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from vpr_core import paths  # noqa: E402
from vpr_study import (
    cli,  # noqa: E402
    outputs,  # noqa: E402
)

#: The fast eval of these tests: 6 synthetic places, the handcrafted backbone.
FAST = ["eval", "--dataset", "synthetic", "--n-places", "6", "--backbone", "hog"]


def _help(capsys, *argv: str) -> str:
    with pytest.raises(SystemExit) as stop:
        cli.main([*argv, "--help"])
    assert stop.value.code == 0
    return capsys.readouterr().out


# 44.6 help ------------------------------------------------------------------------------------


def test_help_lists_only_backbones_that_build_here_or_says_what_they_need(capsys):
    from vpr_core.backbones import available_backbones, build_backbone

    text = " ".join(_help(capsys, "eval").split())
    start = text.index("--backbone BACKBONE landmark")
    block = text[start : text.index("--out OUT", start)]
    listed = re.findall(
        r"\b([a-z][a-z0-9_]*[a-z0-9])\b( \(needs [^)]*\))?", block.split(" of: ")[1]
    )
    names = {name: bool(need) for name, need in listed if name in available_backbones()}
    unknown = [n for n, _ in listed if n not in available_backbones() and "_" in n]
    assert not unknown, f"help lists backbones that do not exist: {unknown}"
    assert "sift" not in re.findall(r"\w+", block)
    assert set(available_backbones()) <= set(names)
    for name, needs in names.items():
        if not needs:
            build_backbone(name)  # each listed without a need builds in this install


def test_eval_help_has_examples_and_names_the_defaults(capsys):
    out = _help(capsys, "eval")
    examples = out[out.index("examples:") :]
    assert "vpr-study eval --dataset synthetic --method dense classical" in examples
    assert "vpr-study eval --study" in examples and "user/figures/<label>/" in examples
    flat = " ".join(out.split())
    for option, default in (("--dataset", "synthetic"), ("--method", "dense")):
        assert re.search(rf"{option} \S+ .*?\(default: {default}\)", flat), option
    assert "(default: ratio" in flat or "ratio (the paper's, default)" in flat


@pytest.mark.parametrize(
    ("argv", "usage"),
    [
        (["eval", "--method", "nope"], "usage: vpr-study eval"),
        (["eval", "--label", "a|b"], "usage: vpr-study eval"),
        (["eval", "--backbone", "resnet9000"], "usage: vpr-study eval"),
        (["run", "--label", "a b"], "usage: vpr-study run"),
    ],
)
def test_an_error_prints_the_subcommands_usage(monkeypatch, capsys, argv, usage):
    from vpr_core import datasets

    monkeypatch.setattr(datasets, "load_dataset", lambda *a, **k: pytest.fail("loaded"))
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(usage) and "{eval,run,findings}" not in err
    assert f"{usage.split()[-2]} {usage.split()[-1]}: error:" in err


# 44.6 tables, notices, cost provenance, progress -----------------------------------------------


def test_at_80_columns_every_line_fits_and_the_table_keeps_r1(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    argv = [*FAST, "--method", "dense", "global", "--spatial", "both", "--out", str(tmp_path)]
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    paths_written = [ln for ln in out.splitlines() if ln.endswith((".csv", ".png"))]
    too_long = [ln for ln in out.splitlines() if len(ln) > 80 and ln not in paths_written]
    assert not too_long, too_long  # a file's name is never broken; all else fits
    r1 = re.search(r"^method +R@1( |$)", out, re.MULTILINE)  # R@1 kept, in a block of its own
    assert r1 and re.search(r"^method .*dR@1 vs dense( |$)", out, re.MULTILINE), out
    assert re.search(r"^global +\d\.\d{3} \[\d\.\d{3}, \d\.\d{3}\]", out[r1.start() :], re.M)
    # the cost table of the longer labels (dense (geometry: consistency)) fits too
    assert re.search(r"^dense \(geometry: consistency\) .*this run", out, re.MULTILINE)


def test_each_notice_prints_once_and_progress_lines_come_without_a_terminal(tmp_path):
    """A real process with stderr piped (no terminal): one line per distinct notice, none with
    Python's source line, and one ``[vpr-study]`` line per stage."""
    env = {
        **{k: v for k, v in __import__("os").environ.items() if k != "TQDM_DISABLE"},
        "VPR_CACHE_DIR": str(tmp_path / "cache"),
        "COLUMNS": "100",
        "MPLBACKEND": "Agg",
    }
    argv = ["eval", "--dataset", "synthetic", "--n-places", "4", "--tolerance", "3"]
    argv += ["--backbone", "hog", "--method", "dense", "global", "--out", str(tmp_path)]
    done = subprocess.run(
        [sys.executable, "-m", "vpr_study.cli", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    err = done.stderr
    warned = [line for line in err.splitlines() if "WARNING" in line]
    assert any("saturated" in line for line in warned), err  # 4 places, tolerance 3
    assert len(warned) == len(set(warned)), warned
    assert "VPRWarning" not in err and "warnings.warn" not in err and ".py:" not in err
    stages = [line for line in err.splitlines() if line.startswith("[vpr-study] ")]
    for stage in ("loading synthetic", "dense on synthetic (1 of 2)", "global on synthetic"):
        assert any(line.startswith(f"[vpr-study] {stage}") for line in stages), stages
    assert any(line.startswith("[vpr-study] comparing 2 runs") for line in stages)


def test_a_long_stage_prints_a_line_every_interval_without_a_terminal(
    tmp_path, monkeypatch, capsys
):
    real = cli.run_method

    def slow(*args, **kwargs):
        time.sleep(0.5)
        return real(*args, **kwargs)

    monkeypatch.setattr(cli, "PROGRESS_INTERVAL_S", 0.1)
    monkeypatch.setattr(cli, "run_method", slow)
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    assert cli.main([*FAST, "--method", "global", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err  # pytest's capture: not a terminal
    beats = [ln for ln in err.splitlines() if "global on synthetic: still running" in ln]
    assert len(beats) >= 2, err


def test_earlier_run_marks_only_runs_read_from_the_cache(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "120")
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    base = [*FAST, "--method", "global", "--out", str(tmp_path)]
    assert cli.main(base) == 0
    capsys.readouterr()
    # computed in this call (a new matrix), on landmarks and features an earlier call cached:
    # their recorded seconds exceed this call's wall time, yet the run is this call's
    assert cli.main([*base, "--spatial", "consistency"]) == 0
    fresh = capsys.readouterr().out
    row = [ln for ln in fresh.splitlines() if ln.startswith("global (geometry: consistency) ")][-1]
    assert row.endswith("this run") and "earlier run" not in row, fresh
    assert cli.main([*base, "--spatial", "consistency"]) == 0  # the same again: the cache
    again = capsys.readouterr().out
    row = [ln for ln in again.splitlines() if ln.startswith("global (geometry: consistency) ")][-1]
    assert row.endswith("earlier run"), again


# 44.2 where eval writes -----------------------------------------------------------------------


def _checkout(tmp_path: Path) -> Path:
    root = tmp_path / "clone"
    (root / "notebooks").mkdir(parents=True)
    (root / "pyproject.toml").write_text(f'[project]\nname = "{paths.PROJECT_NAME}"\n')
    return root


def test_eval_writes_under_user_unless_study_or_out_says_otherwise(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("VPR_OUTPUT_DIR", raising=False)
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    clone = _checkout(tmp_path)
    monkeypatch.chdir(clone)
    argv = [*FAST, "--method", "global", "--n-bootstrap", "0"]
    stem = "eval_synthetic_global_backbone-hog_n-bootstrap-0_n-places-6"
    assert cli.main(argv) == 0
    assert (clone / "user" / "figures" / "synthetic" / f"{stem}.png").is_file()
    assert (clone / "user" / "results" / "synthetic" / f"{stem}.csv").is_file()
    assert not (clone / "figures").exists() and not (clone / "results").exists()
    assert f"wrote under {clone / 'user'}" in " ".join(capsys.readouterr().out.split())
    assert cli.main([*argv, "--study"]) == 0  # the study's own call (make study)
    assert (clone / "figures" / "synthetic" / f"{stem}.png").is_file()
    assert (clone / "results" / "synthetic" / f"{stem}.csv").is_file()
    assert cli.main([*argv, "--out", str(tmp_path / "elsewhere")]) == 0
    assert (tmp_path / "elsewhere" / "figures" / "synthetic" / f"{stem}.png").is_file()
    with pytest.raises(SystemExit):  # one place at a time
        cli.main([*argv, "--study", "--out", str(tmp_path / "x")])
    assert "give one of them" in capsys.readouterr().err
    # findings keeps reading and writing the study's results/
    assert cli.main(["findings", "--write", "--labels", "synthetic"]) == 0
    assert (clone / "results" / "findings.md").is_file()
    assert not (clone / "user" / "results" / "findings.md").exists()


# 45.1 one label rule --------------------------------------------------------------------------

HOSTILE_LABELS = [
    "a|b",
    "a\nb",
    "\r=1+1",
    "<img src=x onerror=alert(1)>",
    "a b",
    ".hidden",
    "x=1",
    "tab\there",
    "../../x",
    "",
]


@pytest.mark.parametrize("label", HOSTILE_LABELS)
def test_a_hostile_label_is_refused_everywhere_naming_the_allowed_characters(
    tmp_path, monkeypatch, capsys, label
):
    from vpr_core import datasets
    from vpr_study import runner
    from vpr_study.viz.base import save

    allowed = "letters, digits, '_', '-', '.' and '+'"
    with pytest.raises(ValueError, match=re.escape(allowed)):
        outputs.check_label(label)
    monkeypatch.setattr(datasets, "load_dataset", lambda *a, **k: pytest.fail("loaded"))
    with pytest.raises(SystemExit):
        cli.main(["eval", "--dataset", "synthetic", "--label", label])
    assert allowed in " ".join(capsys.readouterr().err.split())
    fig = plt.figure()
    with pytest.raises(ValueError, match=re.escape(allowed)):
        save(fig, "f", label, out=tmp_path)
    plt.close(fig)
    with pytest.raises(ValueError, match=re.escape(allowed)):
        runner.run_study("synthetic", quick=True, label=label)
    assert list(tmp_path.rglob("*")) == []


@pytest.mark.parametrize(
    "label", ["synthetic", "gardens_point_mini", "nordland_step50_quick", "v1.2+b-c", "zürich"]
)
def test_the_studys_labels_and_readable_ones_pass(label):
    assert outputs.check_label(label) == label


def test_a_folder_datasets_name_becomes_a_valid_default_label():
    assert cli.default_label("my photos|2024") == "my_photos_2024"
    assert cli.default_label(".hidden") == "hidden"
    assert outputs.check_label(cli.default_label("<img src=x>")) == "_img_src_x_"


# 45.4 an option given twice --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (
            ["eval", "--opt", "tolerance=1", "--tolerance", "2"],
            ("--opt tolerance=1", "--tolerance 2"),
        ),
        (["eval", "--opt", "a=1", "--opt", "a=2"], ("--opt a=1", "--opt a=2")),
        (["eval", "--tolerance", "1", "--tolerance", "2"], ("--tolerance 1", "--tolerance 2")),
        (
            ["eval", "--method", "dense", "--method", "global"],
            ("--method dense", "--method global"),
        ),
        (["eval", "--n-places", "4", "--opt", "n_places=5"], ("--n-places 4", "--opt n_places=5")),
        (["run", "--step", "2", "--opt", "step=3"], ("--step 2", "--opt step=3")),
    ],
)
def test_an_option_given_twice_is_refused_naming_both(monkeypatch, capsys, argv, named):
    from vpr_core import datasets

    monkeypatch.setattr(datasets, "load_dataset", lambda *a, **k: pytest.fail("loaded"))
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    err = " ".join(capsys.readouterr().err.split())
    assert all(n in err for n in named), err
    assert err.startswith(f"usage: vpr-study {argv[0]}")
