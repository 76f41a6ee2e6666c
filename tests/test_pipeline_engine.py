"""run_method's fast paths (shortlist, roi, Dask), intervals, peers, cache healing, Ctrl-C."""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest

from vpr_core import run_method
from vpr_core.datasets import load_dataset
from vpr_core.features import get_encoder
from vpr_study import cli
from vpr_study.peers import peer_result

#: A small encoder so the tests stay fast (16 dense landmarks per image).
SMALL = {"dim": 64, "scales": (0.25,), "per_scale": 16}


@pytest.fixture(scope="module")
def small():
    return load_dataset("synthetic", n_places=6, image_size=(96, 160))


@pytest.fixture()
def isolated_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _run(ds, **kw):
    opts = {**SMALL, **kw}
    return run_method("dense", ds, **opts)


def test_shortlist_covering_every_reference_is_exhaustive(small):
    full = _run(small)
    same = _run(small, shortlist=len(small.reference_paths))
    np.testing.assert_array_equal(full.similarity, same.similarity)
    assert same.shortlist is None and full.timings["pairs"] == 36


def test_shortlist_scores_k_pairs_per_query_and_keeps_their_values(small):
    full = _run(small)
    res = _run(small, shortlist=3)
    ranked = ~np.isnan(res.similarity)
    assert (ranked.sum(axis=1) == 3).all() and res.timings["pairs"] == 18
    # inside the shortlist the Eq. (1) values are the exhaustive ones
    np.testing.assert_allclose(res.similarity[ranked], full.similarity[ranked], atol=1e-6)
    assert res.row()["pairs scored"] == 18 and res.shortlist == 3


def test_bad_shortlist_is_refused(small):
    for bad in (0, -2, 2.5, True, "5"):
        with pytest.raises(ValueError, match="shortlist must be a positive integer"):
            _run(small, shortlist=bad)


def test_every_row_carries_its_interval(small):
    res = _run(small)
    row = res.row()
    for value, prefix in (("AUC", "AUC"), ("R@100P", "R@100P"), ("R@1", "R@1")):
        lo, hi = row[f"{prefix} lo"], row[f"{prefix} hi"]
        assert lo <= row[value] + 1e-12 and row[value] <= hi + 1e-12
        assert lo < hi  # 6 queries with mixed outcomes cannot give a zero-width interval
    assert row["queries"] == 6
    assert res.intervals["auc"][0] == pytest.approx(res.metrics["auc"])


def test_roi_pooling_runs_end_to_end_and_is_deterministic(small, isolated_cache):
    a = _run(small, pooling="roi")
    get_encoder.cache_clear()
    b = _run(small, pooling="roi")
    np.testing.assert_array_equal(a.similarity, b.similarity)
    assert a.encoder["pooling"] == "roi"
    assert not np.array_equal(a.similarity, _run(small).similarity)


def test_run_method_on_a_local_cluster_equals_in_process(small, isolated_cache):
    """``run_method(..., executor=DaskExecutor(address))``: features, the shortlist's pairs and
    the exhaustive matrix computed on the cluster equal the in-process run."""
    distributed = pytest.importorskip("distributed")
    from vpr_study import DaskExecutor

    local = [_run(small, shortlist=3), _run(small)]
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        import shutil

        shutil.rmtree(isolated_cache)  # features and matrices are recomputed on the cluster
        with DaskExecutor(cluster.scheduler_address) as executor:
            remote = [_run(small, shortlist=3, executor=executor), _run(small, executor=executor)]
    for a, b in zip(local, remote, strict=True):
        np.testing.assert_array_equal(a.similarity, b.similarity)


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])


def test_truncated_cache_entries_heal(small, isolated_cache, caplog):
    """Entries of every stage cut short at once: each is named in a warning and recomputed."""
    ref = run_method("classical", small, dim=64)
    cut = {}
    for kind in ("landmarks", "features", "results"):
        files = sorted((isolated_cache / kind).rglob("*.npz"))
        assert files, f"no {kind} cache entries were written"
        for f in files[:3]:
            _truncate(f)
        cut[kind] = files[0]
    get_encoder.cache_clear()
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        again = run_method("classical", small, dim=64)
    np.testing.assert_array_equal(ref.similarity, again.similarity)
    msgs = [r.getMessage() for r in caplog.records if "unreadable" in r.getMessage()]
    for kind, f in cut.items():
        assert any(str(f) in m for m in msgs), (kind, msgs)
    # healed: a third run reads everything without warnings
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        run_method("classical", small, dim=64)
    assert not [r for r in caplog.records if "unreadable" in r.getMessage()]


def test_peer_result_sits_beside_ours(small, tmp_path):
    from test_baselines import _write

    from vpr_study.peers import load_vprbench_precomputed

    gt = np.asarray(small.ground_truth)
    sim = np.where(gt, 0.9, 0.1) + np.random.default_rng(0).random(gt.shape) * 0.01
    peer = load_vprbench_precomputed(_write(tmp_path / "NetVLAD" / "x.npy", sim))
    res = peer_result(peer, small)
    assert res.metrics["r@1"] == 1.0 and res.intervals["auc"][1] <= 1.0
    assert res.row()["method"].startswith("NetVLAD")


def test_cli_shortlist_roi_and_paired_differences(small, tmp_path, capsys):
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "6",
            "--method",
            "dense",
            "global",
            "--pooling",
            "roi",
            "--shortlist",
            "3",
            "--dim",
            "64",
            "--n-bootstrap",
            "200",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "shortlist k=3" in out and "paired bootstrap" in out and "- dense" in out
    rows = [ln for ln in out.splitlines() if ln.startswith("global ")]  # one per wrapped block
    assert any(re.search(r"\b(higher|lower|inconclusive)\b", row) for row in rows)
    assert list((tmp_path / "results" / "synthetic").glob("eval_synthetic_dense+global_*.csv"))


def test_ctrl_c_prints_one_line_and_exits_130(monkeypatch, capsys):
    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "cmd_eval", interrupted)  # build_parser binds it at each call
    assert cli.main(["eval", "--dataset", "synthetic", "--method", "dense"]) == 130
    assert capsys.readouterr().err.strip().splitlines() == [cli.INTERRUPTED]


def test_image_without_landmarks_is_excluded_and_named(tmp_path, isolated_cache, caplog):
    """A blank image gets no Edge Box: it is named and excluded from ranking, never scored 0."""
    import cv2
    from skimage import data

    tex = data.astronaut()[::4, ::4][:96, :128]
    for side in ("query", "reference"):
        (tmp_path / "ds" / side).mkdir(parents=True)
        for i in range(3):
            img = np.roll(tex, 9 * i, axis=1).copy()
            if side == "query" and i == 1:
                img[:] = 128  # blank: no edges, no proposals
            assert cv2.imwrite(str(tmp_path / "ds" / side / f"{i:03d}.png"), img[..., ::-1])
    ds = load_dataset("folder", tmp_path / "ds")
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        res = run_method("classical", ds, dim=32, n_bootstrap=0)
    text = " ".join(r.getMessage() for r in caplog.records)
    assert "001.png" in text and "excluded from ranking" in text
    # one warning for the run, the image with the fewest landmarks named first
    short = [r.getMessage() for r in caplog.records if "gave fewer than the 100" in r.getMessage()]
    assert len(short) == 1 and "001.png): 0" in short[0].split(": ", 1)[1].split(";")[0], short
    assert np.isnan(res.similarity[1]).all() and not np.isnan(res.similarity[0]).any()


def test_cli_adds_vprbench_peers_to_table_and_figure(tmp_path, capsys):
    from test_baselines import _write

    from vpr_study.peers import PRECOMPUTED_FILE

    gt = np.eye(6, dtype=bool)
    sim = np.where(gt, 0.8, 0.2) + np.random.default_rng(1).random((6, 6)) * 0.05
    _write(tmp_path / "vb" / "precomputed_matches" / "Synth" / "NetVLAD" / PRECOMPUTED_FILE, sim)
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "6",
            "--method",
            "dense",
            "--dim",
            "64",
            "--n-bootstrap",
            "100",
            "--peers",
            str(tmp_path / "vb"),
            "--peer-dataset",
            "Synth",
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if ln.startswith("NetVLAD (VPR-Bench)")]
    assert any(re.search(r"\b(higher|lower|inconclusive)\b", row) for row in rows)  # vs dense
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "6",
            "--method",
            "dense",
            "--peers",
            str(tmp_path / "vb"),
        ]
    )
    assert rc == 2 and "--peer-dataset" in capsys.readouterr().err


def _npz(path):
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _foreign_run(small, caplog, what):
    get_encoder.cache_clear()
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        again = _run(small)
    msgs = [r.getMessage() for r in caplog.records if "does not hold" in r.getMessage()]
    assert msgs and what in msgs[0], msgs
    return again


def test_a_store_under_another_images_name_is_not_used(small, isolated_cache, caplog):
    ref = _run(small)
    stores = sorted((isolated_cache / "features").rglob("*.npz"))
    stores[1].write_bytes(stores[0].read_bytes())  # a valid store, of another image
    for f in (isolated_cache / "results").rglob("*.npz"):
        f.unlink()
    again = _foreign_run(small, caplog, str(stores[1]))
    np.testing.assert_array_equal(ref.similarity, again.similarity)


def test_a_store_of_another_seed_or_dimension_is_not_used(small, isolated_cache, caplog):
    ref = _run(small)
    for f in (isolated_cache / "results").rglob("*.npz"):
        f.unlink()
    store = min((isolated_cache / "features").rglob("*.npz"))
    a = _npz(store)
    np.savez(
        store, boxes=a["boxes"], desc=a["desc"][:, :7], cost=a["cost"], _identity=a["_identity"]
    )  # 7-column descriptors under the right name
    again = _foreign_run(small, caplog, "descriptors of shape")
    np.testing.assert_array_equal(ref.similarity, again.similarity)
    seed1 = _run(small, seed=1)  # another encoder folder; copy its store into seed 0's
    for f in (isolated_cache / "results").rglob("*.npz"):
        f.unlink()
    folders = sorted({p.parent for p in (isolated_cache / "features").rglob("*.npz")})
    assert len(folders) == 2
    src = (
        next(folders[1].glob("*.npz"))
        if folders[0] in store.parents
        else next(folders[0].glob("*.npz"))
    )
    dst = store.parent / src.name
    dst.write_bytes(src.read_bytes())
    caplog.clear()
    again = _foreign_run(small, caplog, "not 'features")
    np.testing.assert_array_equal(ref.similarity, again.similarity)
    assert not np.array_equal(seed1.similarity, ref.similarity)


def test_a_results_entry_of_the_wrong_shape_is_recomputed(small, isolated_cache, caplog):
    ref = _run(small)
    entry = next((isolated_cache / "results").rglob("*.npz"))
    a = _npz(entry)
    np.savez(entry, **{**a, "similarity": a["similarity"][:, :3]})
    again = _foreign_run(small, caplog, "expected (6, 6)")
    np.testing.assert_array_equal(ref.similarity, again.similarity)


def test_an_unwritable_cache_folder_is_named_with_the_fix(small, tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("VPR_CACHE_DIR", str(blocker / "cache"))
    with pytest.raises(OSError, match=r"VPR_CACHE_DIR.*writable"):
        _run(small)


def test_an_unwritable_output_folder_is_named_with_the_fix(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "3",
            "--method",
            "global",
            "--backbone",
            "hog",
            "--out",
            str(blocker / "out"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "--out / VPR_OUTPUT_DIR" in err and "a file is in the way" in err
    assert str(blocker) in err and "Traceback" not in err


def test_mapped_arrays_equal_eager_reads(tmp_path):
    from vpr_core.cache import atomic_savez, load_npz

    rng = np.random.default_rng(0)
    arrays = {
        "c": rng.random((50, 9), dtype=np.float32),
        "f": np.asfortranarray(rng.random((7, 5))),
        "empty": np.zeros((0, 4), np.float32),
    }
    path = tmp_path / "entry.npz"
    atomic_savez(path, identity="x", **arrays)
    got = load_npz(path, tuple(arrays), identity="x", mapped=tuple(arrays))
    assert got is not None and isinstance(got["c"], np.memmap)
    for key, value in arrays.items():
        np.testing.assert_array_equal(got[key], value)
        assert got[key].shape == value.shape and got[key].dtype == value.dtype


def _short_desc_store(store):
    """The store with a ``desc.npy`` member whose header promises more rows than it holds."""
    import io
    import zipfile

    a = _npz(store)
    buf = io.BytesIO()
    np.lib.format.write_array(buf, a["desc"])
    with zipfile.ZipFile(store, "w", zipfile.ZIP_STORED) as z:
        for key, value in a.items():
            if key == "desc":
                z.writestr("desc.npy", buf.getvalue()[: -a["desc"].itemsize * 3])
            else:
                member = io.BytesIO()
                np.lib.format.write_array(member, value)
                z.writestr(f"{key}.npy", member.getvalue())


@pytest.mark.parametrize("damage", ["compressed", "short"])
def test_a_store_that_cannot_be_mapped_heals(damage, small, isolated_cache, caplog):
    """Descriptors are memory-mapped from the store: a compressed member or one shorter than its
    header says is named, removed and recomputed, and the numbers do not change."""
    ref = _run(small)
    for f in (isolated_cache / "results").rglob("*.npz"):
        f.unlink()
    store = min((isolated_cache / "features").rglob("*.npz"))
    if damage == "compressed":
        np.savez_compressed(store, **_npz(store))
    else:
        _short_desc_store(store)
    get_encoder.cache_clear()
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        again = _run(small)
    msgs = [r.getMessage() for r in caplog.records if "unreadable" in r.getMessage()]
    assert any(str(store) in m and "desc" in m for m in msgs), msgs
    np.testing.assert_array_equal(ref.similarity, again.similarity)
