"""vpr_study.arguments, usage and choices (issue 60 item 9): every ``--opt`` parses by the type
of the loader's option, and every help (``eval --help``, ``run --help``, ``findings --help``)
and ``--version`` answers without importing torch, saying what the full parser says."""

from __future__ import annotations

import argparse
import contextlib
import io
import subprocess
import sys

import pytest

from vpr_study import choices
from vpr_study.arguments import dataset_options


def _opts(*items: str, dataset: str = "synthetic") -> dict:
    return dataset_options(argparse.Namespace(dataset=dataset, opt=list(items)))


@pytest.mark.parametrize(
    ("item", "value"),
    [
        ("image_size=120,160", (120, 160)),
        ("image_size=120x160", (120, 160)),
        ("n_places=12", 12),
        ("repetition=0.5", 0.5),
        ("difficulty=hard", "hard"),
        ("seed=3", 3),
    ],
)
def test_an_option_parses_by_the_type_of_the_loaders_option(item, value):
    key = item.partition("=")[0]
    assert _opts(item) == {key: value}


def test_a_string_option_stays_a_string_and_unknown_ones_parse_as_before():
    assert _opts("query=5", dataset="nordland") == {"query": "5"}  # a season folder named 5
    assert _opts("unknown=3") == {"unknown": 3}  # load_dataset lists the valid ones


@pytest.mark.parametrize(
    ("item", "words"),
    [
        ("image_size=120", "image_size takes 2 numbers separated by commas .*360,640"),
        ("image_size=120,160,3", "image_size takes 2 numbers"),
        ("image_size=a,b", "image_size takes 2 numbers"),
        ("n_places=4.5", r"n_places takes an integer \(e.g. --opt n_places=60\), got '4.5'"),
        ("repetition=high", "repetition takes a finite number"),
        ("repetition=inf", "'inf' is not a finite number"),
        ("tolerance=one", "tolerance takes an integer"),
    ],
)
def test_an_option_of_the_wrong_type_is_refused_naming_it_and_an_example(item, words):
    with pytest.raises(ValueError, match=rf"^--opt '{item}': {words}"):
        _opts(item)


def _answer(argv: list[str]) -> tuple[str, str, int]:
    """``vpr-study ARGV`` in a fresh interpreter: (torch-like modules loaded, stdout, status)."""
    code = (
        "import sys, contextlib, io\n"
        "from vpr_study.usage import main\n"
        "out, status = io.StringIO(), 0\n"
        "with contextlib.redirect_stdout(out):\n"
        "    try:\n"
        f"        main({argv!r})\n"
        "    except SystemExit as exc:\n"
        "        status = exc.code\n"
        "print(sorted(m for m in ('torch', 'kornia', 'cv2') if m in sys.modules))\n"
        "print(status)\n"
        "print(out.getvalue(), end='')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded, status, text = done.stdout.split("\n", 2)
    return loaded, text, int(status)


@pytest.mark.parametrize(
    "argv",
    [
        ["eval", "--help"],
        ["run", "--help"],
        ["findings", "--help"],
        ["eval", "--method", "x", "-h"],
    ],
    ids=["eval", "run", "findings", "eval, -h after options"],
)
def test_every_help_answers_without_torch_and_says_what_the_cli_says(argv):
    loaded, text, status = _answer(argv)
    assert loaded == "[]" and status == 0
    from vpr_study import cli

    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        cli.main(argv)
    assert text == out.getvalue() and "usage: vpr-study " + argv[0] in text


def test_version_answers_without_torch():
    loaded, text, status = _answer(["--version"])
    assert loaded == "[]" and status == 0 and text.startswith("vpr-study ")
    from importlib.metadata import version

    assert text.strip() == f"vpr-study {version('vpr-landmarks')}"


def test_the_parsers_names_are_the_pipelines():
    from vpr_core import NORMALISATIONS, SPATIAL_OPTIONS, WEIGHTINGS, available_methods
    from vpr_core.backbones import available_backbones
    from vpr_core.datasets import DATASETS
    from vpr_core.evaluation import PROTOCOLS
    from vpr_core.matching import WHITEN_K

    assert tuple(DATASETS) == choices.DATASETS
    assert tuple(available_methods()) == choices.METHODS
    assert tuple(available_backbones()) == choices.BACKBONES
    assert tuple(PROTOCOLS) == choices.PROTOCOLS
    assert tuple(SPATIAL_OPTIONS) == choices.SPATIAL_OPTIONS
    assert tuple(WEIGHTINGS) == choices.WEIGHTING_OPTIONS  # read from the rooms' source
    assert tuple(NORMALISATIONS) == choices.NORMALISE_OPTIONS
    assert WHITEN_K == choices.WHITEN_K


@pytest.mark.parametrize("where", ["nowhere", "torch hub", "variable"])
def test_the_helps_weights_check_is_the_pipelines(tmp_path, monkeypatch, where):
    from vpr_core.backbones import weights_sha256

    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch"))
    monkeypatch.delenv("VPR_ALEXNET_WEIGHTS", raising=False)
    if where == "torch hub":
        hub = tmp_path / "torch" / "hub" / "checkpoints"
        hub.mkdir(parents=True)
        (hub / "alexnet-owt-7be5be79.pth").write_bytes(b"x")
    elif where == "variable":
        (tmp_path / "w.pth").write_bytes(b"x")
        monkeypatch.setenv("VPR_ALEXNET_WEIGHTS", str(tmp_path / "w.pth"))
        monkeypatch.setenv("VPR_EFFICIENTNET_LITE1_WEIGHTS", str(tmp_path / "none.pth"))
    for name in choices.BACKBONES:
        try:
            found = weights_sha256(name) != "missing"
        except FileNotFoundError:
            found = False
        assert choices.weights_found(name) == found, name
