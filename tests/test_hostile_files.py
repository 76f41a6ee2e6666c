"""Hostile names and files, fourth round (issue 45): no text escapes its CSV cell, a download
never touches what it did not make, the edge model and result cache entries are keyed and
checked by content, a full disk and NaN weights are named with the fix."""

from __future__ import annotations

import csv
import errno
import gzip
import hashlib
import http.server
import logging
import threading
from pathlib import Path

import numpy as np
import pytest
import torch

from vpr_study.rows import csv_safe, read_rows, write_rows

#: Formulas behind what a spreadsheet skips: CR, LF, tab, spaces, NUL, a zero-width space.
HIDDEN_FORMULAS = (
    "\r=1+1",
    "\n=1+1",
    "\r\n+cmd|/C calc!A0",
    "\t@SUM(1)",
    "  =HYPERLINK(1)",
    " \t-2+3",
    "\x00=1",
    "\u200b=1",
    "\uff1d1+1",  # a full-width equals sign
)


def _cells(path: Path) -> list[list[str]]:
    with open(path, newline="") as f:
        return list(csv.reader(f))


def _lead(cell: str) -> str:
    import unicodedata

    return cell.lstrip("".join(c for c in set(cell) if unicodedata.category(c)[0] in "CZ"))


def _assert_no_formula(path: Path) -> None:
    """No cell a spreadsheet would evaluate, whatever precedes its first visible character."""
    for row in _cells(path):
        for cell in row:
            if cell[:1] in ("=", "+", "-", "@", "\t", "\r", "\n") or _lead(cell)[:1] in (
                "=",
                "+",
                "-",
                "@",
            ):
                float(cell)  # a negative number is a number; anything else fails here


# -- 1. cells ----------------------------------------------------------------------------------


@pytest.mark.parametrize("text", HIDDEN_FORMULAS)
def test_csv_safe_escapes_a_formula_behind_control_characters_and_spaces(text):
    assert csv_safe(text) == "'" + text
    assert csv_safe(csv_safe(text)) == "'" + text


@pytest.mark.parametrize("kept", [-0.144, "-0.144", " -3", "1e-3", "plain", "a\rb", "", None])
def test_csv_safe_keeps_numbers_and_plain_text(kept):
    assert csv_safe(kept) == kept


def test_a_cell_holding_cr_is_quoted_and_keeps_its_row(tmp_path):
    import pandas as pd

    from vpr_study.viz.base import save_all

    table = pd.DataFrame({"method": [*HIDDEN_FORMULAS, "a\rb"], "AUC": -0.144})
    (path,) = save_all([("t", table)], "hostile", out=tmp_path)
    rows = _cells(path)
    assert len(rows) == len(HIDDEN_FORMULAS) + 2  # the header and one row per method
    assert [r[0] for r in rows[1:]] == ["'" + t for t in HIDDEN_FORMULAS] + ["a\rb"]
    assert {r[1] for r in rows[1:]} == {"-0.144000"}  # numbers are not escaped
    _assert_no_formula(path)
    assert pd.read_csv(path)["AUC"].dtype == float
    write_rows(tmp_path / "rows.csv", [{"name": t, "v": -0.5} for t in HIDDEN_FORMULAS])
    assert [r["name"] for r in read_rows(tmp_path / "rows.csv")] == [
        "'" + t for t in HIDDEN_FORMULAS
    ]
    _assert_no_formula(tmp_path / "rows.csv")


def test_a_run_label_with_a_hidden_formula_stays_in_its_cell(tmp_path, monkeypatch):
    from vpr_core import run_method
    from vpr_core.datasets import load_dataset
    from vpr_core.evaluation import compare
    from vpr_core.evaluation.queries import per_query
    from vpr_study.viz.base import save_all

    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    ds = load_dataset("synthetic", n_places=4, image_size=(96, 160))
    small = {"dim": 32, "scales": (0.25,), "per_scale": 9, "n_bootstrap": 20}
    result = run_method("dense", ds, label="\r=1+1", **small)
    paths = save_all(
        [("compare", compare([result], n_bootstrap=20)), ("per_query", per_query(result))],
        "hostile",
        out=tmp_path / "out",
    )
    for path in paths:
        _assert_no_formula(path)
        assert any("'\r=1+1" in row for row in _cells(path)), path.name


# -- 2. downloads --------------------------------------------------------------------------------


@pytest.fixture()
def served():
    """A server on 127.0.0.1: ``/half/<name>`` sends the first half of ``state[name]`` with no
    Content-Length (HTTP/1.0: the body ends when the connection closes); ``/<name>`` sends it
    in full with its length. ``state["requests"]`` counts the requests."""
    state: dict = {"requests": 0}

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            state["requests"] += 1
            parts = self.path.strip("/").split("/")
            body = state[parts[-1]]
            self.send_response(200)
            if parts[0] == "half":
                self.end_headers()
                self.wfile.write(body[: len(body) // 2])
            else:
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", state
    finally:
        server.shutdown()
        server.server_close()


def _zip(entries: dict[str, bytes]) -> bytes:
    import io
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in entries.items():
            zf.writestr(name, data)
    return buf.getvalue()


def test_a_download_never_touches_a_users_folder_or_file(served, tmp_path):
    from vpr_study.download import download_dataset

    base, state = served
    state["mine.zip"] = _zip({"mine/query/0.txt": b"archive", "mine/reference/0.txt": b"a"})
    root = tmp_path / "data"
    (root / "mine").mkdir(parents=True)
    (root / "mine" / "notes.txt").write_text("a user's work")
    with pytest.raises(FileExistsError, match=r"mine is in the way.*Move or rename") as err:
        download_dataset("x", root, url=f"{base}/mine.zip")
    assert str(root / "mine") in str(err.value)
    assert sorted(p.name for p in root.rglob("*")) == ["mine", "notes.txt"]  # untouched
    assert (root / "mine" / "notes.txt").read_text() == "a user's work"

    # its own earlier download it may replace, but not once a user's file is inside
    other = tmp_path / "other"
    assert download_dataset("x", other, url=f"{base}/mine.zip") == other / "mine"
    assert download_dataset("x", other, url=f"{base}/mine.zip", overwrite=True) == other / "mine"
    (other / "mine" / "query" / "mine.txt").write_text("added by the user")
    with pytest.raises(FileExistsError, match=r"mine is in the way"):
        download_dataset("x", other, url=f"{base}/mine.zip", overwrite=True)
    assert (other / "mine" / "query" / "mine.txt").read_text() == "added by the user"

    # a user's file of the URL's file name with other content is not replaced
    state["table.csv"] = b"downloaded"
    (root / "table.csv").write_text("a user's table")
    with pytest.raises(FileExistsError, match=r"table\.csv is in the way"):
        download_dataset("y", root, url=f"{base}/table.csv")
    assert (root / "table.csv").read_text() == "a user's table"
    assert not list(root.glob("*.part"))


def test_a_download_of_unknown_completeness_is_not_recorded_as_finished(served, tmp_path, caplog):
    from vpr_study.download import download_dataset

    base, state = served
    state["gt.bin"] = bytes(range(256)) * 40
    root = tmp_path / "data"
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        assert download_dataset("x", root, url=f"{base}/half/gt.bin") == root
    assert (root / "gt.bin").stat().st_size == len(state["gt.bin"]) // 2  # kept, with a notice
    assert any("not recorded as finished" in r.getMessage() for r in caplog.records)
    n = state["requests"]
    download_dataset("x", root, url=f"{base}/half/gt.bin")
    assert state["requests"] == n + 1  # fetched again, not returned as done
    # with its length shown (or its hash given) it is finished: the next call fetches nothing
    full = tmp_path / "full"
    download_dataset("x", full, url=f"{base}/gt.bin")
    n = state["requests"]
    download_dataset("x", full, url=f"{base}/gt.bin")
    sha = hashlib.sha256(state["gt.bin"][: len(state["gt.bin"]) // 2]).hexdigest()
    download_dataset("x", tmp_path / "d2", url=f"{base}/half/gt.bin", sha256=sha)
    download_dataset("x", tmp_path / "d2", url=f"{base}/half/gt.bin", sha256=sha)
    assert state["requests"] == n + 1


# -- 3. the structured-edge model ----------------------------------------------------------------


def _sed_model(path: Path, horizontal: bool) -> None:
    """A valid tiny structured-edge model (tests/test_landmarks.py) painting a vertical or,
    with ``horizontal``, a horizontal line through its patches."""
    from test_landmarks import write_sed_model

    write_sed_model(path, n_trees=1)
    if horizontal:
        with gzip.open(path, "rt") as fh:
            text = fh.read()
        vertical = str([y * 16 + 8 for y in range(16)] * 4)
        assert vertical in text
        with gzip.open(path, "wt") as fh:
            fh.write(text.replace(vertical, str([8 * 16 + x for x in range(16)] * 4)))


def test_an_edge_model_overwritten_in_place_is_loaded_again(tmp_path):
    from vpr_core.landmarks.edge_boxes import _structured_edges, edge_model_id

    rng = np.random.default_rng(0)
    image = np.zeros((96, 128, 3), np.uint8)
    image[20:70, 30:100] = 200
    image = (image + rng.integers(0, 20, image.shape)).astype(np.uint8)
    a, b, path = tmp_path / "a.yml.gz", tmp_path / "b.yml.gz", tmp_path / "model.yml.gz"
    _sed_model(a, horizontal=False)
    _sed_model(b, horizontal=True)
    edges_a, edges_b = _structured_edges(image, a)[0], _structured_edges(image, b)[0]
    assert not np.array_equal(edges_a, edges_b)
    path.write_bytes(a.read_bytes())
    np.testing.assert_array_equal(_structured_edges(image, path)[0], edges_a)
    id_a = edge_model_id(path)
    path.write_bytes(b.read_bytes())  # overwritten in place: the run records B's sha256 ...
    assert edge_model_id(path) != id_a
    # ... and the detector is B's, not the one loaded from this path before
    np.testing.assert_array_equal(_structured_edges(image, path)[0], edges_b)
    from vpr_core.landmarks.edge_boxes import _model_cache_key

    assert edge_model_id(path) == f"sha256:{_model_cache_key(path)[0]}"  # one identity


# -- 4. result cache entries ---------------------------------------------------------------------


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def test_a_cache_entry_edited_by_hand_heals(tmp_path, caplog):
    from vpr_core.cache import atomic_savez, load_npz

    entry = tmp_path / "landmarks.npz"
    boxes = np.array([[1.0, 2.0, 30.0, 40.0]])
    atomic_savez(entry, identity="boxes x", boxes=boxes, seconds=np.array(0.5))
    assert load_npz(entry, ("boxes", "seconds"), identity="boxes x")["boxes"].tolist() == [
        [1.0, 2.0, 30.0, 40.0]
    ]
    np.savez(entry, **{**_arrays(entry), "boxes": np.full((1, 4), 7.0)})  # a valid npz
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        assert load_npz(entry, ("boxes", "seconds"), identity="boxes x") is None
    assert not entry.exists()
    assert any(str(entry) in m and "checksum" in m for m in caplog.messages)
    # an entry without checksums (an older format) heals too
    np.savez(entry, boxes=boxes, seconds=np.array(0.5), _identity=np.array("boxes x"))
    assert load_npz(entry, ("boxes", "seconds"), identity="boxes x") is None


def test_a_similarity_matrix_edited_by_hand_is_recomputed(tmp_path, monkeypatch, caplog):
    from vpr_core import run_method
    from vpr_core.datasets import load_dataset

    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    ds = load_dataset("synthetic", n_places=4, image_size=(96, 160))
    small = {"dim": 32, "scales": (0.25,), "per_scale": 9, "n_bootstrap": 0}
    first = run_method("dense", ds, **small)
    (entry,) = (tmp_path / "cache" / "results").rglob("*.npz")
    a = _arrays(entry)
    np.savez(entry, **{**a, "similarity": np.full_like(a["similarity"], 7.0)})
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        again = run_method("dense", ds, **small)
    assert any("does not match its checksums" in m for m in caplog.messages)
    np.testing.assert_array_equal(again.similarity, first.similarity)
    assert again.metrics == first.metrics


# -- 5. a full disk while the synthetic dataset is generated ---------------------------------------


@pytest.mark.parametrize("what", ["0000.png", "manifest"])
def test_a_full_disk_names_the_path_and_leaves_no_temporary_file(tmp_path, monkeypatch, what):
    from vpr_core.datasets.synthetic import load_synthetic

    write_bytes = Path.write_bytes

    def full(self, data):
        if what not in self.name:
            return write_bytes(self, data)
        write_bytes(self, data[: len(data) // 2])  # what fitted before the disk was full
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_bytes", full)
    monkeypatch.setattr(Path, "write_text", lambda self, text, **kw: full(self, text.encode()))
    root = tmp_path / "syn"
    monkeypatch.setenv("VPR_CACHE_DIR", str(root))
    with pytest.raises(OSError) as err:
        load_synthetic(n_places=1, image_size=(32, 48))
    assert err.value.errno == errno.ENOSPC
    assert str(root) in str(err.value) and what.split(".")[0] in str(err.value)
    assert "VPR_CACHE_DIR" in str(err.value) and "free space" in str(err.value)
    assert not [p for p in root.rglob("*") if p.name.endswith(".tmp")]


# -- 6. weights whose values became NaN ------------------------------------------------------------


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), 1e300])
def test_weights_holding_nan_are_refused_at_load_naming_the_file_and_the_fix(tmp_path, bad):
    from vpr_core.backbones import build_backbone
    from vpr_core.backbones.alexnet import CONV3_KEYS
    from vpr_core.backbones.checkpoint import WeightsFileError

    gen = torch.Generator().manual_seed(0)
    state = {k: torch.randn(s, generator=gen, dtype=torch.float64) for k, s in CONV3_KEYS.items()}
    state["features.3.weight"][0, 0, 0, 0] = bad  # 1e300: finite in float64, inf in float32
    path = tmp_path / "diverged.pth"
    torch.save(state, path)
    with pytest.raises(WeightsFileError) as err:
        build_backbone("alexnet_conv3", weights=path)
    msg = str(err.value)
    assert str(path) in msg and "features.3.weight" in msg
    assert "download it again" in msg and "re-create" in msg
