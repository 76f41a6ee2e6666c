"""Hostile files and names (issue 32): formulas never reach a spreadsheet, model files and pickles
never kill the process, downloads and soft ground truth hold, and every error names its cause."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest

from vpr_core import run_method
from vpr_core.datasets import load_dataset
from vpr_core.evaluation import compare
from vpr_study.peers import PRECOMPUTED_FILE, find_vprbench_peers, peer_from_matrix, peer_result
from vpr_study.rows import csv_safe, read_rows, write_rows
from vpr_study.viz.base import save_all

#: Names a hostile user gives a method or a folder (issue 32.1).
FORMULAS = ('=HYPERLINK("http://x","y")', "+cmd|/C calc!A0", "@SUM(1)", "-2+3")


def _cells(path: Path) -> list[str]:
    with open(path, newline="") as f:
        return [c for row in csv.reader(f) for c in row]


def _assert_no_formula(path: Path) -> None:
    """No cell a spreadsheet would evaluate: text starting with = + - @ tab CR (numbers allowed)."""
    for cell in _cells(path):
        if cell[:1] in ("=", "+", "-", "@", "\t", "\r"):
            float(cell)  # a negative number is a number; anything else fails here


def test_csv_safe_escapes_text_and_keeps_numbers():
    for text in (*FORMULAS, "\tx", "\rx"):
        assert csv_safe(text) == "'" + text
    for kept in (-0.25, 3, "-0.25", "1e-3", "plain", "", "'=already", None, np.float64(-1.5)):
        assert csv_safe(kept) is kept or csv_safe(kept) == kept
    assert csv_safe(csv_safe("=x")) == "'=x"  # idempotent: a table read and written again


def test_escaped_tables_keep_their_index_rule(tmp_path):
    """Escaping must not turn a RangeIndex into a written index column (a committed table would
    gain an unnamed first column), and a named index is still written, escaped."""
    import pandas as pd

    plain = pd.DataFrame({"name": ["=x", "y"], "v": [1.5, -2.0]})
    scaled = pd.DataFrame({"v": [1.0, 2.0]}, index=pd.RangeIndex(1, 3, name="scale"))
    keyed = pd.DataFrame({"v": [1.0]}, index=pd.Index(["@k"], name="run"))
    save_all([("plain", plain), ("scaled", scaled), ("keyed", keyed)], "t", out=tmp_path)
    results = tmp_path / "results" / "t"
    assert (results / "plain.csv").read_text().splitlines() == [
        "name,v",
        "'=x,1.500000",
        "y,-2.000000",
    ]
    assert (results / "scaled.csv").read_text().splitlines()[0] == "v"
    assert (results / "keyed.csv").read_text().splitlines() == ["run,v", "'@k,1.000000"]


def test_write_rows_escapes_text_cells(tmp_path):
    path = tmp_path / "t.csv"
    write_rows(path, [{"name": "=1+1", "value": -0.5, "neg": "-3"}])
    assert read_rows(path) == [{"name": "'=1+1", "value": "-0.5", "neg": "-3"}]
    _assert_no_formula(path)


def test_peer_names_never_reach_a_csv_as_formulas(tmp_path, tiny_synthetic):
    ds = tiny_synthetic
    n = len(ds.query_paths)
    sim = np.eye(n, len(ds.reference_paths)) + 0.01
    results = [peer_result(peer_from_matrix(sim, name), ds, n_bootstrap=20) for name in FORMULAS]
    table = compare(results, n_bootstrap=20)
    (path,) = save_all([("peers", table)], "hostile", out=tmp_path)
    _assert_no_formula(path)
    cells = _cells(path)
    assert '\'=HYPERLINK("http://x","y") (VPR-Bench)' in cells or any(
        c.startswith("'=HYPERLINK") for c in cells
    )
    df = __import__("pandas").read_csv(path)
    assert df["AUC"].dtype == float  # numbers stay numbers


def _folder_dataset(root: Path, source: Path, n: int = 3) -> None:
    for side in ("query", "reference"):
        (root / side).mkdir(parents=True)
        for i in range(n):
            shutil.copy(source / side / f"{i}.jpg", root / side)


def test_dataset_root_named_as_a_formula_is_escaped(tmp_path, gardens_point_mini_root):
    root = tmp_path / "=HYPERLINK(1)"
    _folder_dataset(root, gardens_point_mini_root)
    ds = load_dataset("folder", root=root)
    result = peer_result(peer_from_matrix(np.eye(3) + 0.1, "mine"), ds, n_bootstrap=20)
    table = compare([result], n_bootstrap=20)
    (path,) = save_all([("t", table)], "safe_label", out=tmp_path / "out")
    _assert_no_formula(path)
    row = read_rows(path)[0]
    assert row["dataset"] == "'=HYPERLINK(1)" and row["root"] == "'=HYPERLINK(1)"


def test_vpr_bench_technique_folder_named_as_a_formula_is_escaped(tmp_path, tiny_synthetic):
    ds = tiny_synthetic
    n = len(ds.query_paths)
    sim = np.eye(n, len(ds.reference_paths)) + 0.01
    path = tmp_path / "precomputed_matches" / "SPED" / "@SUM(1)" / PRECOMPUTED_FILE
    path.parent.mkdir(parents=True)
    items = [np.arange(n), np.argmax(sim, 1), sim.max(1), sim, 0.01, 0.002]
    arr = np.empty(6, dtype=object)
    for k, item in enumerate(items):
        arr[k] = item
    np.save(path, arr, allow_pickle=True)
    (peer,) = find_vprbench_peers(tmp_path, "SPED")
    table = compare([peer_result(peer, ds, n_bootstrap=20)], n_bootstrap=20)
    (out,) = save_all([("t", table)], "safe_label", out=tmp_path / "out")
    _assert_no_formula(out)
    assert any(c.startswith("'@SUM(1)") for c in _cells(out))


def test_cli_peer_name_is_escaped(tmp_path, capsys):
    from vpr_study import cli

    np.save(tmp_path / "mine.npy", np.eye(6) + 0.01 * np.arange(36).reshape(6, 6))
    argv = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "dense"]
    argv += [f"--peer=-2+3={tmp_path / 'mine.npy'}", "--n-bootstrap", "20"]
    assert cli.main([*argv, "--out", str(tmp_path)]) == 0
    (path,) = (tmp_path / "results" / "synthetic").glob("eval_*[0-9a-f].csv")
    _assert_no_formula(path)
    assert any(c.startswith("'-2+3") for c in _cells(path))


# ------------------------------------------------------------------------------------------
# 32.2 structured-edge model files: checked against their own sizes before OpenCV reads them
# ------------------------------------------------------------------------------------------

#: id -> (replaced text of the test forest, replacement); each one crashed or hung OpenCV.
BAD_FORESTS = {
    "child beyond the tree": ("[ 2, 0, 0 ]", "[ 100, 0, 0 ]"),
    "negative child": ("[ 2, 0, 0 ]", "[ -5, 0, 0 ]"),
    "child pointing at itself": ("[ 2, 0, 0 ]", "[ 1, 0, 0 ]"),
    "feature id beyond the features": ("[ 904, 0, 0 ]", "[ 1000000000, 0, 0 ]"),
    "negative feature id": ("[ 904, 0, 0 ]", "[ -3, 0, 0 ]"),
    "edge boundary beyond edgeBins": ("[ 0, 0, 0, 64 ]", "[ 0, 0, 0, 6400 ]"),
    "edge bin beyond the patch": ("[8, 24,", "[100000, 24,"),
    "1000 gradient orientations": (
        "numberOfGradientOrientations: 4",
        "numberOfGradientOrientations: 1000",
    ),
    "huge patch": ("patchSize: 32", "patchSize: 100000"),
    "negative smoothing radius": ("regFeatureSmoothingRadius: 2", "regFeatureSmoothingRadius: -4"),
}

_PROBE = """
import sys
import numpy as np
import pytest
from vpr_core.landmarks.edge_boxes import edge_boxes
image = np.random.default_rng(0).integers(0, 255, (90, 120, 3), dtype=np.uint8)
for path in sys.argv[1:]:
    try:
        edge_boxes(image, max_boxes=20, model=path)
        print("ACCEPTED", path, flush=True)
    except ValueError as exc:
        print("REFUSED", str(exc).replace(chr(10), " | "), flush=True)
"""


def test_structured_edge_models_out_of_their_own_sizes_are_refused(tmp_path):
    """Each hostile forest is refused with a one-line error naming the file (run in a child
    process: before the checks, OpenCV killed the process with SIGSEGV or looped forever)."""
    import gzip
    import subprocess
    import sys

    from test_landmarks import write_sed_model

    good = tmp_path / "good.yml.gz"
    write_sed_model(good, n_trees=2)
    with gzip.open(good, "rt") as fh:
        text = fh.read()
    paths = []
    for k, (old, new) in enumerate(BAD_FORESTS.values()):
        assert old in text, old
        path = tmp_path / f"bad{k}.yml.gz"
        with gzip.open(path, "wt") as fh:
            fh.write(text.replace(old, new))
        paths.append(str(path))
    run = subprocess.run(
        [sys.executable, "-c", _PROBE, str(good), *paths],
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = run.stdout.splitlines()
    assert run.returncode == 0, (run.returncode, lines, run.stderr[-2000:])
    assert lines[0] == f"ACCEPTED {good}"
    for case, path, line in zip(BAD_FORESTS, paths, lines[1:], strict=True):
        assert line.startswith("REFUSED") and path in line and " | " not in line, (case, line)


def test_dense_edge_maps_are_bounded_and_said(tmp_path, gardens_point_mini_root):
    """A forest that paints a line through every patch marks ~80% of a noise image as edges
    (270 x 480: 49 s in OpenCV's Edge Boxes before the budget, 4 s after); the strongest 25%
    are kept, said once; a natural image is below the budget and untouched."""
    import warnings

    from PIL import Image
    from test_landmarks import write_sed_model

    from vpr_core.landmarks.edge_boxes import MAX_EDGE_DENSITY, edge_boxes
    from vpr_core.notices import VPRWarning

    model = tmp_path / "dense.yml.gz"
    write_sed_model(model, n_trees=2)
    noise = np.random.default_rng(0).integers(0, 255, (135, 240, 3), dtype=np.uint8)
    with pytest.warns(VPRWarning, match=rf"{model}.*keeps the strongest 25%"):
        first = edge_boxes(noise, max_boxes=200, model=model)
    assert MAX_EDGE_DENSITY == 0.25 and len(first) > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", VPRWarning)  # said once per edge map; same boxes again
        np.testing.assert_array_equal(edge_boxes(noise, max_boxes=200, model=model).boxes, first)
        photo = np.asarray(Image.open(gardens_point_mini_root / "query" / "0.jpg").convert("RGB"))
        edge_boxes(photo, max_boxes=50, model="gradient")


# ------------------------------------------------------------------------------------------
# 32.3 the unpickler checks sizes before anything is constructed
# ------------------------------------------------------------------------------------------


def _allocating_pickles() -> dict[str, bytes]:
    """Short pickles asking an allowed callable for a 30M-element array (240 MB)."""
    import pickle

    n = 30_000_000
    proto = b"\x80\x02"
    ndarray = b"cnumpy\nndarray\n"
    shape = b"J" + n.to_bytes(4, "little") + b"\x85"  # BININT n, TUPLE1
    reconstruct = b"cnumpy.core.multiarray\n_reconstruct\n"
    dtype_o = b"cnumpy\ndtype\nX\x02\x00\x00\x00O8\x89\x88\x87R"  # dtype('O8', False, True)
    state = b"(K\x01" + shape + dtype_o + b"\x89]tb"  # (1, shape, dtype, False, [])
    return {
        "ndarray((n,), object)": proto + ndarray + b"(" + shape + b"X\x01\x00\x00\x00OtR.",
        "ndarray((n,), float)": proto + ndarray + shape + b"\x85R.",
        "_reconstruct(ndarray, (n,), b)": proto + reconstruct + ndarray + shape + b"C\x01b\x87R.",
        "__setstate__ to (n,) objects": proto
        + reconstruct
        + ndarray
        + b"K\x00\x85C\x01b\x87R"
        + state
        + b".",
        "plain check": pickle.dumps([1, 2], protocol=2),
    }


@pytest.mark.parametrize("case", list(_allocating_pickles())[:-1])
def test_pickle_asking_for_a_huge_array_is_refused_before_allocating(tmp_path, case):
    import tracemalloc

    from vpr_core.datasets.safe_pickle import _restricted_loads, read_npy

    data = _allocating_pickles()[case]
    assert len(data) < 120
    path = tmp_path / "bomb.npy"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"bomb\.npy .*30,000,000"):
            read_npy(path, "x")
        with pytest.raises(ValueError, match=r"mem .*30,000,000"):
            _restricted_loads(data, "mem")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20_000_000, f"{peak:,} bytes allocated before the refusal"


def test_array_state_that_does_not_fill_its_shape_is_refused():
    """numpy's ``__setstate__`` reads past an object list shorter than the shape (SIGSEGV)."""
    from vpr_core.datasets.safe_pickle import _restricted_loads

    data = (
        b"\x80\x02cnumpy.core.multiarray\n_reconstruct\ncnumpy\nndarray\nK\x00\x85C\x01b\x87R"
        b"(K\x01M\xe8\x03\x85cnumpy\ndtype\nX\x02\x00\x00\x00O8\x89\x88\x87R\x89]K\x07atb."
    )  # an object array of shape (1000,) whose state lists one item
    with pytest.raises(ValueError, match=r"mem holds an array of shape \(1000,\) whose data"):
        _restricted_loads(data, "mem")


# ------------------------------------------------------------------------------------------
# 32.4 downloads: an archive is done only when it opens and its members read
# ------------------------------------------------------------------------------------------


@pytest.fixture()
def archive_server():
    """A server on 127.0.0.1: ``/trunc.zip`` sends the first 50 bytes of ``state["zip"]``
    without a Content-Length and closes; ``/<name>`` sends ``state[name]`` in full."""
    import http.server
    import threading

    state: dict = {}

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            self.send_response(200)
            name = self.path.strip("/").split("?")[0]
            if name == "trunc.zip":
                self.end_headers()  # HTTP/1.0: the body ends when the connection closes
                self.wfile.write(state["zip"][:50])
            else:
                self.send_header("Content-Length", str(len(state[name])))
                self.end_headers()
                self.wfile.write(state[name])

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", state
    finally:
        server.shutdown()
        server.server_close()


def _zip_bytes() -> bytes:
    import io
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("site/query/0.txt", b"0123456789" * 10)
    return buf.getvalue()


def test_truncated_archive_without_length_is_not_marked_done(archive_server, tmp_path):
    from vpr_study.download import download_dataset

    base, state = archive_server
    state["zip"] = _zip_bytes()
    assert len(state["zip"]) > 200
    dest = tmp_path / "data"
    for _ in range(2):  # the second call tries again: nothing was recorded as done
        with pytest.raises(ValueError, match=r"trunc\.zip is not a complete zip archive"):
            download_dataset("x", dest, url=f"{base}/trunc.zip")
        assert list(dest.iterdir()) == []


def test_archive_whose_member_does_not_read_is_removed(archive_server, tmp_path):
    from vpr_study.download import download_dataset

    base, state = archive_server
    good = _zip_bytes()
    k = good.index(b"0123456789")
    state["bad.zip"] = good[:k] + b"X" + good[k + 1 :]  # CRC mismatch in the member
    dest = tmp_path / "data"
    with pytest.raises(ValueError, match=r"bad\.zip could not be extracted .*site/query/0\.txt"):
        download_dataset("x", dest, url=f"{base}/bad.zip")
    assert list(dest.iterdir()) == []
    state["good.zip"] = good
    assert download_dataset("x", dest, url=f"{base}/good.zip") == dest / "site"


def test_url_ending_in_dot_dot_is_a_clear_error(archive_server, tmp_path):
    from vpr_study.download import download_dataset

    base, state = archive_server
    state["%2e%2e"] = b"data"
    dest = tmp_path / "data"
    with pytest.raises(ValueError, match=r"file name '\.\.'.*not a file name"):
        download_dataset("x", dest, url=f"{base}/%2e%2e")
    assert list(dest.iterdir()) == []


# ------------------------------------------------------------------------------------------
# 32.5 soft ground truth: neither right nor wrong wherever a metric is computed
# ------------------------------------------------------------------------------------------


def _utm_soft(root: Path):
    """4 queries on a line, 8 references: query q's hard positive (<= 5 m) is reference 2q,
    reference 2q + 1 (12 m away) is only a soft positive (<= 15 m)."""
    import cv2

    name = "@{:.2f}@4178906.93@10@S@@@@@@@@@@.jpg"
    for q in range(4):
        e = 543000.0 + 100 * q
        for side, k, x in (
            ("queries", q, e),
            ("database", 2 * q, e + 1),
            ("database", 2 * q + 1, e + 12),
        ):
            path = root / side / f"{k}" / name.format(x)
            path.parent.mkdir(parents=True)
            assert cv2.imwrite(str(path), np.full((24, 32, 3), 10 * k, np.uint8))
    return load_dataset("utm", root, positive_dist_threshold=5, soft_dist_threshold=15)


def test_soft_positives_are_neither_right_nor_wrong_in_every_metric(tmp_path):
    from vpr_core.evaluation.queries import per_query

    ds = _utm_soft(tmp_path)
    assert (ds.ground_truth_soft & ~ds.ground_truth).sum() == 4
    sim = np.full((4, 8), 0.1)
    for q in range(4):
        sim[q, 2 * q + 1] = 0.9  # each query's best match: its soft-only reference
        sim[q, 2 * q] = 0.5  # then its hard positive
    result = peer_result(peer_from_matrix(sim, "soft"), ds, n_bootstrap=50)
    assert result.metrics["r@1"] == 1.0  # by the README's rule (utm row), not 0.0
    assert result.intervals["r@1"][1:] == (1.0, 1.0)
    table = compare([result], n_bootstrap=50)
    assert table["R@1"].iloc[0] == 1.0
    assert per_query(result)["top-1 correct"].all()


def test_chance_levels_leave_soft_only_references_out(tmp_path):
    """A random ranking draws each query's top-1 from the 7 references that are not soft-only
    (the evaluation ranks its soft-only one last): R@1 1/7, not 1/8; R@5 5/7, not 5/8."""
    from vpr_core.evaluation import chance
    from vpr_core.evaluation.compare import CHANCE_ROW, compact

    ds = _utm_soft(tmp_path)
    gt, soft = ds.ground_truth, ds.ground_truth_soft
    assert chance(gt)["r@1"] == pytest.approx(1 / 8)  # without soft ground truth: unchanged
    level = chance(gt, soft=soft)
    assert level["r@1"] == pytest.approx(1 / 7) and level["r@5"] == pytest.approx(5 / 7)
    result = peer_result(peer_from_matrix(np.eye(4, 8), "soft"), ds, n_bootstrap=0)
    assert result.soft_only.sum() == 4
    table = compare([result], n_bootstrap=0)
    assert table["R@1 chance"].iloc[0] == pytest.approx(1 / 7)
    assert table["R@5 chance"].iloc[0] == pytest.approx(5 / 7)
    row = compact(table).loc[CHANCE_ROW]
    assert row["R@1"] == "0.143" and row["R@5"] == "0.714"  # the CLI's chance row


# ------------------------------------------------------------------------------------------
# 32.6-32.8 crashes and silent answers that become clear errors
# ------------------------------------------------------------------------------------------


def test_compare_baseline_index_out_of_range_is_a_clear_error(tiny_synthetic):
    ds = tiny_synthetic
    sim = np.eye(8) + np.random.default_rng(0).random((8, 8))
    runs = [peer_result(peer_from_matrix(sim + k, f"m{k}"), ds, n_bootstrap=0) for k in (0, 1)]
    with pytest.raises(ValueError, match=r"baseline=5 .*2 results.*0 to 1") as info:
        compare(runs, baseline=5, n_bootstrap=0)
    assert "\n" not in str(info.value)


def _findings_folder(tmp_path: Path, text: bytes | str) -> Path:
    folder = tmp_path / "results" / "lab"
    folder.mkdir(parents=True)
    path = folder / "fig05_selection.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


COMMITTED_FIG05 = (
    Path(__file__).resolve().parents[1] / "results" / "synthetic" / "fig05_selection.csv"
)


@pytest.mark.parametrize(
    "case, content, message",
    [
        ("no dAUC", "method,run,baseline\nclassical,classical,\n", r"lacks the column.*dAUC"),
        ("binary", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\xff\xfe", r"not a readable CSV"),
        ("empty", b"", r"is empty"),
        ("truncated", None, r"is truncated"),
    ],
)
def test_findings_over_a_bad_table_names_the_file(tmp_path, case, content, message):
    from vpr_study.findings import findings_table

    if content is None:
        full = COMMITTED_FIG05.read_text()
        content = full[: len(full) * 2 // 3]
    path = _findings_folder(tmp_path, content)
    with pytest.raises(ValueError, match=message) as info:
        findings_table(["lab"], out=tmp_path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_findings_for_a_label_without_results_is_refused(tmp_path, capsys):
    from vpr_study import cli
    from vpr_study.findings import findings_table

    _findings_folder(tmp_path, COMMITTED_FIG05.read_text())
    with pytest.raises(
        ValueError, match=r"no results for label 'nosuch' .*labels with results: lab"
    ):
        findings_table(["lab", "nosuch"], out=tmp_path)
    findings = tmp_path / "results" / "findings.md"
    findings.write_text("kept\n")
    rc = cli.main(["findings", "--write", "--labels", "nosuch", "--out", str(tmp_path)])
    assert rc != 0 and findings.read_text() == "kept\n"
    assert "nosuch" in capsys.readouterr().err


def test_huge_n_bootstrap_is_refused_before_the_work(capsys, monkeypatch, tmp_path):
    """The CLI refuses at its argument check, naming the flag (8 GB free pinned: 1e8
    resamples need 9.6 GB, whatever the machine has). Were it not refused, its figure goes to
    ``tmp_path``, never into the study's figures/ (where an earlier version of this test left
    eval_synthetic_dense_n-bootstrap-100000000_n-places-4.png)."""
    import os
    import time

    from vpr_study import cli

    page = os.sysconf("SC_PAGE_SIZE")
    free = {"SC_AVPHYS_PAGES": 8_000_000_000 // page, "SC_PAGE_SIZE": page}
    monkeypatch.setattr(os, "sysconf", lambda name: free[name])
    start = time.monotonic()
    argv = ["eval", "--out", str(tmp_path), "--n-places", "4", "--method", "dense"]
    rc = cli.main([*argv, "--n-bootstrap", "100000000"])
    err = capsys.readouterr().err
    assert rc == 2 and "--n-bootstrap 100000000" in err and "9.6 GB" in err, err
    assert "landmarks/img" not in err  # refused before any method ran
    assert time.monotonic() - start < 20


def test_huge_n_bootstrap_is_refused_by_the_library_before_the_work(tiny_synthetic, monkeypatch):
    """The same estimate as the CLI's (one home: evaluation.spec), at run_method's top: 96 bytes
    per resample, 9.6 GB for 1e8, over half of 8 GB free (pinned: the machine's may differ)."""
    import os
    import time

    from vpr_core.evaluation import Evaluation

    page = os.sysconf("SC_PAGE_SIZE")
    free = {"SC_AVPHYS_PAGES": 8_000_000_000 // page, "SC_PAGE_SIZE": page}
    monkeypatch.setattr(os, "sysconf", lambda name: free[name])
    most = f"{int(free['SC_AVPHYS_PAGES'] * page / 2 / 96):,}"
    start = time.monotonic()
    with pytest.raises(ValueError, match=rf"n_bootstrap 100000000: .*9\.6 GB .*use at most {most}"):
        run_method("dense", tiny_synthetic, backbone="hog", n_bootstrap=100_000_000)
    with pytest.raises(ValueError, match=r"n_bootstrap 100000000: .*9\.6 GB"):
        Evaluation(n_bootstrap=100_000_000)
    assert Evaluation(n_bootstrap=1000).n_bootstrap == 1000
    assert time.monotonic() - start < 3


def test_jpeg_with_random_bytes_in_its_scan_data_is_refused(tmp_path, gardens_point_mini_root):
    """400 random bytes inside the scan data, end marker intact: libjpeg only reports
    extraneous bytes before the end marker, and the image decodes garbled."""
    from vpr_core.datasets.images import read_image

    data = (gardens_point_mini_root / "query" / "0.jpg").read_bytes()
    sos, eoi = data.rfind(b"\xff\xda"), data.rfind(b"\xff\xd9")
    junk = np.random.default_rng(0).integers(0, 255, 400, dtype=np.uint8).tobytes()  # no 0xFF
    at = sos + (eoi - sos) // 2
    bad = tmp_path / "scan.jpg"
    bad.write_bytes(data[:at] + junk + data[at:])
    with pytest.raises(ValueError, match=r"scan\.jpg is a damaged JPEG .*extraneous bytes"):
        read_image(bad)
    assert read_image(gardens_point_mini_root / "query" / "0.jpg").ndim == 3  # clean: kept


def test_two_files_with_one_frame_number_are_named(tmp_path):
    from vpr_core.datasets._layout import check_frame_pairs

    q = [tmp_path / "q" / "Image000_2014.jpg", tmp_path / "q" / "Image2014.jpg"]
    r = [tmp_path / "r" / "Image000.jpg", tmp_path / "r" / "Image001.jpg"]
    with pytest.raises(
        ValueError, match=r"Image000_2014\.jpg and .*Image2014\.jpg both read as frame 2014"
    ):
        check_frame_pairs(q, r, "gardens_point")


def test_folder_pairing_with_one_number_on_two_files_is_refused(tmp_path, gardens_point_mini_root):
    """query/1.jpg, 2.jpg vs reference/1.jpg, 1.png: query 2 was paired with 1.png silently."""
    for side, names in (("query", ("1.jpg", "2.jpg")), ("reference", ("1.jpg", "1.png"))):
        (tmp_path / side).mkdir()
        for k, name in enumerate(names):
            src = gardens_point_mini_root / side / f"{k}.jpg"
            if name.endswith(".png"):
                import cv2

                cv2.imwrite(str(tmp_path / side / name), cv2.imread(str(src)))
            else:
                shutil.copy(src, tmp_path / side / name)
    with pytest.raises(
        ValueError, match=r"1\.jpg and .*1\.png both read as frame 1.*ground-truth file"
    ):
        load_dataset("folder", root=tmp_path)


# ------------------------------------------------------------------------------------------
# 32.8 schedulers: a bad port is a bad port; a cluster without workers says what to check
# ------------------------------------------------------------------------------------------


def test_scheduler_port_out_of_range_is_a_bad_port():
    from vpr_study.cluster.client import get_client

    with pytest.raises(ValueError, match=r"port 99999 .*1 to 65535"):
        get_client("tcp://127.0.0.1:99999", timeout=1)


def test_scheduler_without_workers_says_what_to_check():
    distributed = pytest.importorskip("distributed")
    from vpr_study.cluster.client import get_client

    with (
        distributed.LocalCluster(
            n_workers=0, processes=True, host="127.0.0.1", dashboard_address=None
        ) as cluster,
        pytest.raises(ConnectionError, match=r"no workers.*dask worker tcp://127\.0\.0\.1"),
    ):
        get_client(cluster.scheduler_address, timeout=1)


def test_lost_workers_say_what_to_check():
    from vpr_study.cluster.client import _cluster_lost

    text = str(_cluster_lost(None, "features (dask)", "no worker left for 15 s"))
    assert "check that its `dask worker` processes run" in text


def test_distance_peer_spanning_310_decades_keeps_its_ranking():
    """1e-10 .. 1e300: rescaled by the largest distance, the small ones underflowed into ties."""
    from vpr_core.evaluation import recall_at_k

    d = np.array([[1e-5, 1e-10, 1e300], [1e-5, 1e300, 1e-10], [1e-10, 1e-5, 1e300]])
    gt = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], bool)
    sim = peer_from_matrix(d, "wide", distance=True).similarity
    assert np.isfinite(sim).all() and (sim > 0).all()
    assert recall_at_k(sim, gt, 1) == 1.0  # by hand: every query's smallest distance is right
    np.testing.assert_allclose(np.sort(sim, 1)[:, -2] / sim.max(1), 1e-10 / 1e-5)  # d1 / d2


@pytest.mark.parametrize("limit", [0, -1])
def test_notebook_limit_below_one_is_refused_like_minus_one(limit):
    """papermill -p limit 0 ran the whole set (the notebooks test `if limit:`)."""
    from vpr_study.runner import check_parameters

    match = rf"limit must be None \(all images\) or >= 1, got {limit}$"
    with pytest.raises(ValueError, match=match):
        check_parameters(dataset="synthetic", limit=limit)
    check_parameters(dataset="synthetic", limit=None)
    check_parameters(dataset="synthetic", limit=3)


def test_plot_disagreements_refuses_a_dataset_the_runs_were_not_computed_on():
    from vpr_core import run_method
    from vpr_study.viz import plot_disagreements

    ds = load_dataset("synthetic", n_places=4)
    other = load_dataset("synthetic", n_places=4, seed=1)
    runs = [run_method(m, ds, n_bootstrap=0, keep_descriptors=True) for m in ("dense", "classical")]
    with pytest.raises(ValueError, match=r"plot_disagreements: .*dense.* another dataset"):
        plot_disagreements(other, *runs, n=2)


def test_a_300_character_label_is_blamed_on_the_label():
    from vpr_study.outputs import check_label

    with pytest.raises(ValueError, match=r"label 'aaaa.*' is 300 bytes long; .* at most 100"):
        check_label("a" * 300)
    assert check_label("a" * 100) == "a" * 100


def test_a_nul_in_a_paths_list_names_the_file_and_line(tmp_path):
    import cv2

    for side in ("database", "queries"):
        path = tmp_path / side / "@543000.00@4178906.93@10@S@@.jpg"
        path.parent.mkdir(parents=True)
        assert cv2.imwrite(str(path), np.full((32, 32, 3), 9, np.uint8))
    listing = tmp_path / "queries_images_paths.txt"
    listing.write_text("@543000.00@4178906.93@10@S@@.jpg\nx\0y.jpg\n")
    with pytest.raises(ValueError, match=r"queries_images_paths\.txt line 2 .*NUL") as info:
        load_dataset("utm", tmp_path)
    assert "\n" not in str(info.value)


def test_a_model_archive_that_unpacks_beyond_the_bound_is_refused(tmp_path, monkeypatch):
    import gzip
    import importlib

    eb = importlib.import_module("vpr_core.landmarks.edge_boxes")
    monkeypatch.setattr(eb, "MAX_MODEL_BYTES", 1_000_000)  # the default bound is 1 GiB
    model = tmp_path / "bomb.yml.gz"
    model.write_bytes(gzip.compress(b"%YAML:1.0\n" + b" " * 5_000_000))  # 5 kB packed
    image = np.zeros((40, 40, 3), np.uint8)
    with pytest.raises(ValueError, match=r"bomb\.yml\.gz .*unpacks to more than 1,000,000 bytes"):
        eb.edge_boxes(image, model=model)
