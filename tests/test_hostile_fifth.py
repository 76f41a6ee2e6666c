"""Hostile input, fifth round (issue 53): nothing written where the user did not ask, a named file
used or refused, no verdict a few queries cannot give, findings that trust no table."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from vpr_core.datasets import load_dataset

SMALL = (32, 48)


# -- 1. a loader writes only where it was asked to write -------------------------------------------


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


@pytest.mark.parametrize("kind", ["empty", "user data", "missing"])
def test_synthetic_never_writes_into_a_folder_the_user_named(tmp_path, kind):
    root = tmp_path / "data"
    if kind != "missing":
        root.mkdir()
    if kind == "user data":
        for side in ("query", "reference"):
            (root / side).mkdir()
            (root / side / "0000.png").write_bytes(b"my photo")
        (root / "manifest.json").write_text('{"mine": true}')
    before = _tree(root) if root.exists() else None
    with pytest.raises(ValueError, match=r"synthetic: root=.* was not made by the generator.*"):
        load_dataset("synthetic", root=root, n_places=2, image_size=SMALL)
    assert (_tree(root) if root.exists() else None) == before  # nothing written, nothing changed


def test_synthetic_reads_a_folder_the_generator_made_and_refuses_more_places(tmp_path):
    made = load_dataset("synthetic", n_places=2, image_size=SMALL)  # into the cache
    assert made.root.is_relative_to(Path(os.environ["VPR_CACHE_DIR"]).resolve())
    copy = tmp_path / "copy"
    shutil.copytree(made.root, copy)
    again = load_dataset("synthetic", root=copy, n_places=2, image_size=SMALL)
    assert again.root == copy and again.load_image("query", 1).shape[:2] == SMALL
    before = _tree(copy)
    with pytest.raises(ValueError, match="holds fewer places than asked"):
        load_dataset("synthetic", root=copy, n_places=3, image_size=SMALL)
    with pytest.raises(ValueError, match="was not made by the generator with these settings"):
        load_dataset("synthetic", root=copy, n_places=2, seed=1, image_size=SMALL)
    assert _tree(copy) == before
    assert np.array_equal(again.load_image("query", 0), made.load_image("query", 0))


# -- 2. a file the user named by its place is used or refused, never skipped ---------------------


def _special(path: Path, kind: str) -> Path:
    """Put a ``kind`` of non-file at ``path``."""
    if kind == "dangling symlink":
        path.symlink_to(path.parent / "nowhere.npy")
    elif kind == "folder":
        path.mkdir()
    elif kind == "FIFO":
        os.mkfifo(path)
    elif kind == "device":
        path.symlink_to("/dev/zero")
    return path


KINDS = ["dangling symlink", "folder", "FIFO", "device"]
NAMED = {"dangling symlink": "symlink", "folder": "folder", "FIFO": "FIFO", "device": "device"}


def _folder_dataset(root: Path, n: int = 3) -> Path:
    import cv2

    rng = np.random.default_rng(0)
    for side in ("query", "reference"):
        (root / side).mkdir(parents=True)
        for i in range(n):
            cv2.imwrite(str(root / side / f"{i}.png"), rng.integers(0, 255, (40, 40, 3), np.uint8))
    return root


@pytest.mark.parametrize("name", ["ground_truth.npy", "ground_truth.csv"])
@pytest.mark.parametrize("kind", KINDS)
def test_a_ground_truth_file_that_is_no_file_is_refused_not_skipped(tmp_path, kind, name):
    root = _folder_dataset(tmp_path / "d")
    _special(root / name, kind)
    with pytest.raises(ValueError, match=rf"ground-truth file .*{name} is .*{NAMED[kind]}"):
        load_dataset("folder", root=root)  # today: silently |q - r| <= 0


@pytest.mark.parametrize("kind", KINDS)
def test_named_weights_matrix_and_image_that_are_no_file_are_not_called_missing(tmp_path, kind):
    from vpr_core.backbones import build_backbone
    from vpr_core.datasets import read_image
    from vpr_study.peers import peer_from_matrix

    for i, call in enumerate(
        (
            lambda p: peer_from_matrix(p, "Mine"),
            lambda p: build_backbone("efficientnet_lite0", weights=p),
            lambda p: build_backbone("alexnet_conv3", weights=p),
            read_image,
        )
    ):
        path = _special(tmp_path / f"x{i}.npy", kind)
        with pytest.raises(ValueError, match=rf"{path} is .*{NAMED[kind]}.*not a regular file"):
            call(path)


# -- 4. no verdict a few queries cannot give ------------------------------------------------------


@pytest.mark.parametrize("nq", [2, 5, 6])
def test_a_difference_on_fewer_than_min_queries_is_too_few_never_higher(tmp_path, nq):
    from vpr_core.evaluation import compare
    from vpr_core.evaluation.bootstrap import MIN_QUERIES
    from vpr_study.peers import peer_from_matrix, peer_result

    ds = load_dataset("folder", root=_folder_dataset(tmp_path / "d", nq))
    # A ranks the right reference first for every query, B second: "higher" from 6 queries on
    good = np.eye(nq) + 0.1 * np.arange(nq)[None, ::-1]
    bad = good.copy()
    bad[np.arange(nq), (np.arange(nq) + 1) % nq] = 2.0
    runs = [
        peer_result(peer_from_matrix(m, name), ds, n_bootstrap=200)
        for m, name in ((good, "A"), (bad, "B"))
    ]
    table = compare(runs, baseline="B (VPR-Bench)", n_bootstrap=200)
    verdict = table.loc["A (VPR-Bench)", "dAUC verdict"]
    if nq < MIN_QUERIES:
        assert verdict == f"too few queries ({nq} < {MIN_QUERIES})"
    else:
        assert verdict == "higher"


def test_findings_say_too_few_queries_below_the_minimum():
    from vpr_core import claim_verdict as _verdict

    assert _verdict(">", 0.1, 0.3, 0.2, queries=3) == "too few queries (3 < 6)"
    assert _verdict("~", -0.01, 0.01, 0.0, queries=5) == "too few queries (5 < 6)"
    assert _verdict(">", 0.1, 0.3, 0.2, queries=6) == "higher (as the paper says)"


# -- 5. findings trust no table ----------------------------------------------------------------

_PAR_RUN = "overlap_scheme1(iou_threshold=0.7)"
_PAR = "Fig. 7a: NMS at IoU 0.7 is on par with classical"


def _compare_table(tmp_path, rows, label="d"):
    """A compare()-shaped table saved as the study saves it (6 decimals): baseline row, then
    ``(run, d, lo, hi)`` rows against it."""
    import pandas as pd

    from vpr_study.viz.base import save_all

    recs = [{"method": "base", "run": "classical", "baseline": None, "queries": 60}]
    for k, (run, d, lo, hi) in enumerate(rows):
        recs.append(
            {"method": f"m{k}", "run": run, "baseline": "base", "queries": 60, "dAUC": d}
            | {"dAUC lo": lo, "dAUC hi": hi, "dAUC p": 0.5, "dAUC needs": 100.0}
        )
    save_all([("fig07a_overlap_nms", pd.DataFrame(recs))], label, out=tmp_path)
    return tmp_path / "results" / label / "fig07a_overlap_nms.csv"


@pytest.mark.parametrize(
    ("rows", "why"),
    [
        ([(_PAR_RUN, 0.01, 0.03, -0.02)], r"line 3 the interval of dAUC is reversed"),
        ([(_PAR_RUN, 0.2, -0.02, 0.03)], r"line 3 dAUC 0.2 lies outside its own interval"),
        ([(_PAR_RUN, 0.01, np.nan, np.nan)], r"line 3 dAUC 0.01 \[nan, nan\] is not finite"),
        ([(_PAR_RUN, 0.01, -0.01, 0.02)] * 2, r"line 3 holds a second row of run"),
        ([(_PAR_RUN, "abc", -0.01, 0.02)], r"line 3 column 'dAUC' holds 'abc', not a number"),
    ],
)
def test_findings_refuse_a_malformed_table_naming_file_and_line(tmp_path, rows, why):
    from vpr_study import findings

    csv = _compare_table(tmp_path, rows)
    with pytest.raises(ValueError, match=rf"{csv} {why}.*rerun"):
        findings.findings_table(["d"], out=tmp_path)


def test_on_par_is_not_decided_on_a_bound_rounded_into_the_margin(tmp_path):
    from vpr_study import findings

    csv = _compare_table(tmp_path, [(_PAR_RUN, 0.01, -0.03, 0.0500004)])
    assert "0.050000" in csv.read_text()  # the table keeps 6 decimals
    verdict = findings.findings_table(["d"], out=tmp_path)["d verdict"][_PAR]
    assert not verdict.startswith("on par"), verdict


def test_findings_refuse_a_results_folder_whose_name_is_no_label(tmp_path):
    from vpr_study import findings

    _compare_table(tmp_path, [(_PAR_RUN, 0.01, -0.01, 0.02)], label="ok")
    (tmp_path / "results" / "ok").rename(tmp_path / "results" / "[x](http:evil)")
    labels = findings.result_labels(out=tmp_path)
    with pytest.raises(ValueError, match=r"label '\[x\]\(http:evil\)' must be one folder name"):
        findings.findings_markdown(labels, out=tmp_path)


def test_markdown_cells_escape_link_and_image_syntax():
    from vpr_study.findings import markdown_cell

    assert markdown_cell("[x](http://a)") == "[x]\\(http://a)"
    assert markdown_cell("![i](http://a/p.png)") == "![i]\\(http://a/p.png)"
    assert markdown_cell("[x][ref]") == "[x]\\[ref]"
    assert markdown_cell("+0.200 [+0.100, +0.300] p=0.002") == "+0.200 [+0.100, +0.300] p=0.002"


def test_findings_refuse_a_matches_table_without_its_columns_or_with_text(tmp_path):
    import pandas as pd

    from vpr_study import findings

    folder = tmp_path / "results" / "d"
    folder.mkdir(parents=True)
    pd.DataFrame({"pair": ["gt"], "query": [0]}).to_csv(folder / "fig04_matches.csv", index=False)
    with pytest.raises(ValueError, match=r"fig04_matches.csv lacks the column\(s\) correct, scale"):
        findings.findings_table(["d"], out=tmp_path)
    table = {"pair": ["gt", "gt"], "query": [0, 1], "scale": [2, "big"], "correct": [True, False]}
    pd.DataFrame(table).to_csv(folder / "fig04_matches.csv", index=False)
    with pytest.raises(ValueError, match=r"line 3 holds 'big' in column 'scale', not a number"):
        findings.findings_table(["d"], out=tmp_path)


# -- 6. checks that hold for the whole run -----------------------------------------------------


class _Turning:
    """A user backbone factory: ``kind`` ``late_constant`` (sound for its first ``sound`` calls,
    then the same output for every crop) or ``batch_mean`` (subtracts its batch's mean)."""

    @staticmethod
    def make(kind: str, sound: int = 3):
        import torch
        from torch import nn

        class Net(nn.Module):
            def __init__(self) -> None:
                super().__init__()
                self.calls = 0
                self.conv = nn.Conv2d(3, 8, 3, stride=4, padding=1)
                with torch.no_grad():
                    g = torch.Generator().manual_seed(0)
                    self.conv.weight.copy_(torch.randn(self.conv.weight.shape, generator=g) * 0.2)

            def forward(self, x):
                self.calls += 1
                out = torch.relu(self.conv(x))
                if kind == "batch_mean":
                    return out - out.mean(0, keepdim=True)
                return out if self.calls <= sound else torch.ones_like(out)

        return Net()


@pytest.fixture(scope="module")
def street():
    return load_dataset("synthetic", n_places=2, image_size=(64, 112)).load_image("query", 0)


def test_a_module_that_turns_constant_after_its_first_batches_is_refused(street):
    from vpr_core.features import LandmarkEncoder

    boxes = np.array([[0, 0, 50, 40], [10, 20, 60, 30], [40, 8, 30, 50], [60, 10, 40, 40]], float)
    # probe (2 calls), then batches of 2 crops: the first real batch is sound, the later calls
    # constant (the crops of real batches compared alone, issue 60, may be the first to see it)
    enc = LandmarkEncoder(_Turning.make("late_constant"), dim=16, input_size=32, batch_size=2)
    with pytest.raises(
        ValueError,
        match=r"returns (the same features for every crop on|other features for crop \d+ of) a",
    ):
        enc.encode(street, boxes)


def test_a_module_that_depends_on_the_rest_of_its_batch_is_refused():
    from vpr_core.features import LandmarkEncoder

    with pytest.raises(
        ValueError, match=r"Net returns other features for a crop alone than for the same crop in"
    ):
        LandmarkEncoder(_Turning.make("batch_mean"), dim=16, input_size=32)


def test_a_constant_peer_matrix_gets_the_chance_notice(tmp_path):
    from vpr_core.notices import VPRWarning
    from vpr_study.peers import peer_from_matrix, peer_result

    ds = load_dataset("folder", root=_folder_dataset(tmp_path / "d", 6))
    with pytest.warns(VPRWarning, match=r"similarity matrix is constant \(every value 0.5\)"):
        run = peer_result(peer_from_matrix(np.full((6, 6), 0.5), "Flat"), ds, n_bootstrap=0)
    assert any("metrics are chance levels" in w for w in run.warnings)


@pytest.fixture(scope="module")
def carried_runs():
    from vpr_core import run_method

    ds = load_dataset("synthetic", n_places=6, image_size=(64, 112), repetition=0.9)
    kw = {"n_bootstrap": 0, "keep_descriptors": True, "per_scale": 4}
    weighted = run_method("dense", ds, weighting="contrast", dim=64, **kw)
    return ds, weighted, {d: run_method("dense", ds, dim=d, **kw) for d in (32, 64)}


def test_plot_carried_landmarks_refuses_runs_differing_in_more_than_the_weighting(carried_runs):
    from vpr_study.viz import plot_carried_landmarks

    ds, weighted, plain = carried_runs
    with pytest.raises(ValueError, match=r"differ in more than the weighting \(dim\)"):
        plot_carried_landmarks(ds, plain[32], weighted)
    with pytest.raises(ValueError, match=r"k \(landmarks a figure row fits\) must be in \[1, 10\]"):
        plot_carried_landmarks(ds, plain[64], weighted, k=100)


# -- 3. bounded by the file, messages included; finite numbers from the CLI ------------------------


def _pickle_file(path: Path, obj) -> Path:
    import pickle

    path.write_bytes(pickle.dumps(obj, protocol=2))
    return path


class _HugeScalar:
    """Pickles as ``numpy scalar(dtype("V200000000"))``: two allowed callables, 200 MB."""

    def __reduce__(self):
        from numpy._core.multiarray import scalar

        return (scalar, (np.dtype("V200000000"),))


def test_a_tiny_pickle_asking_for_a_huge_scalar_is_refused_before_allocating(tmp_path):
    import resource

    from vpr_core.datasets.vpr_bench import read_vprbench_ground_truth

    path = _pickle_file(tmp_path / "ground_truth_new.npy", _HugeScalar())
    assert path.stat().st_size < 200
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(ValueError, match=r"from a \d+-byte pickle .*nothing was allocated") as e:
        read_vprbench_ground_truth(path, 3, 3)
    assert len(str(e.value)) < 500
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 100_000  # KiB


@pytest.mark.parametrize(
    ("rows", "match"),
    [
        ([{0: 0, 1: [0]}], r"row 0: expected rows \[query index.*got a dict"),
        ([{0, 1}], r"row 0: expected rows \[query index.*got a set"),
        ([[True, [0]]], r"row 0: the query index must be integer indices, got True"),
        ([[0, [1, 0, 0, 0]]], r"row 0: the references are 4 zeros and ones.*a 0/1 mask"),
        ([[0, np.array([0, 1, 1, 0])]], r"row 0: the references are 4 zeros and ones"),
    ],
)
def test_vpr_bench_rows_of_the_wrong_kind_are_refused_naming_the_row(tmp_path, rows, match):
    from vpr_core.datasets.vpr_bench import read_vprbench_ground_truth

    arr = np.empty(len(rows), dtype=object)
    arr[:] = rows if not isinstance(rows[0], (dict, set)) else [rows[0]]
    path = tmp_path / "ground_truth_new.npy"
    np.save(path, arr, allow_pickle=True)
    with pytest.raises(ValueError, match=match):
        read_vprbench_ground_truth(path, 4, 4)


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--opt", "tolerance=inf"], r"--opt 'tolerance=inf': 'inf' is not a finite number"),
        (["--opt", "n_places=1e400"], r"'1e400' is not a finite number"),
        (["--opt", "n_places=nan"], r"'nan' is not a finite number"),
        (["--n-places", "1000000000"], r"n_places=1,000,000,000 is more than 20,000"),
        (["--opt", f"n_places={10**30}"], r"is more than 20,000"),
    ],
)
def test_cli_numbers_are_finite_and_sizes_fit_the_machine(tmp_path, capsys, argv, match):
    from vpr_study import cli

    try:
        rc = cli.main(["eval", "--dataset", "synthetic", "--out", str(tmp_path), *argv])
    except SystemExit as stop:  # argparse's usage error
        rc = stop.code
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert re.search(match, err), err


def test_one_line_checks_refuse_numbers_beyond_float_range():
    from vpr_core.checks import check_int, check_range

    with pytest.raises(ValueError, match="tolerance must be a non-negative integer, got inf"):
        check_int(float("inf"), "tolerance")
    with pytest.raises(ValueError, match=r"x must be in \[0, 1\]"):
        check_range(10**400, "x", 0, 1)


# -- 7. every error a user can cause ends in a sentence --------------------------------------------


@pytest.mark.parametrize("kind", ["dangling symlink", "folder", "notebooks is a file"])
def test_lab_init_refuses_a_starter_path_that_is_no_file(tmp_path, capsys, kind):
    from vpr_study import lab

    notebooks = tmp_path / "user" / "notebooks"
    if kind == "notebooks is a file":
        notebooks.parent.mkdir(parents=True)
        notebooks.write_text("")
    else:
        notebooks.mkdir(parents=True)
        _special(notebooks / lab.STARTER_NAME, kind)
    with pytest.raises(SystemExit) as stop:
        lab.main(["init", "--root", str(tmp_path)])
    err = capsys.readouterr()
    assert stop.value.code == 2 and "kept" not in err.out
    assert re.search(r"init: error: .*(is a (symlink|folder)|a file is in the way)", err.err)


@pytest.mark.parametrize("backbone", ["efficientnet_lite0:input_size=100000", "hog"])
def test_an_input_size_beyond_memory_is_refused_before_allocating(backbone):
    from vpr_core.features import LandmarkEncoder

    size = None if ":" in backbone else 100_000
    with pytest.raises(ValueError, match=r"input_size \(crop side.*\) must be in \[1, 1024\]"):
        LandmarkEncoder(backbone, dim=8, input_size=size)


def test_a_module_returning_a_meta_tensor_is_refused_in_a_sentence():
    import torch
    from torch import nn

    from vpr_core.features import LandmarkEncoder

    class Meta(nn.Module):
        def forward(self, x):
            return torch.empty(x.shape[0], 8, device="meta")

    with pytest.raises(ValueError, match=r"Meta returned a meta tensor \(2, 8\) \(no data\)"):
        LandmarkEncoder(Meta(), dim=8, input_size=32)


def test_a_peer_named_like_a_method_gets_advice_a_cli_user_can_follow(tmp_path, capsys):
    from vpr_study import cli

    root = _folder_dataset(tmp_path / "d", 6)
    np.save(tmp_path / "sim.npy", np.eye(6))
    argv = ["eval", "--dataset", "folder", "--root", str(root), "--method", "global"]
    argv += ["--backbone", "hog", "--n-bootstrap", "10", "--out", str(tmp_path / "out")]
    rc = cli.main([*argv, "--peer", f"global={tmp_path / 'sim.npy'}"])
    err = capsys.readouterr().err
    assert rc == 2 and "label=" not in err, err
    assert "--peer: 'global' names both a peer and a method" in err
    assert "--peer global-peer=PATH" in err


def test_a_fifo_named_like_an_image_in_a_folder_is_refused_not_dropped(tmp_path):
    root = _folder_dataset(tmp_path / "d", 3)
    os.mkfifo(root / "query" / "3.png")
    with pytest.raises(ValueError, match=r"query folder: image .*3.png is a FIFO"):
        load_dataset("folder", root=root)
