"""Tests for vpr_core.datasets (loaders, PlaceDataset, synthetic generator, downloads) and
viz.plot_examples."""

from __future__ import annotations

import functools
import hashlib
import http.server
import io
import threading
import time
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest

from vpr_core import datasets as D
from vpr_core.datasets import DATASETS, PlaceDataset, load_dataset
from vpr_core.datasets._layout import DOWNLOADABLE
from vpr_core.datasets.freiburg import load_freiburg_across_seasons
from vpr_core.datasets.ground_truth import ground_truth_references, sample_irrelevant_references
from vpr_study.download import DOWNLOADS, download_dataset

SMALL = (64, 112)  # (H, W) for fast generator tests


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------


def _write_images(folder: Path, names, size=(32, 40), seed=0) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    out = []
    for n in names:
        img = rng.integers(0, 256, (*size, 3), dtype=np.uint8)
        p = folder / n
        assert cv2.imwrite(str(p), img)
        out.append(p)
    return out


def _grad(img: np.ndarray) -> np.ndarray:
    """Illumination-robust structure map: gradient magnitude of a locally normalised grey image."""
    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    g = g / (cv2.GaussianBlur(g, (0, 0), 8) + 5.0)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1)
    return cv2.GaussianBlur(np.hypot(gx, gy), (0, 0), 2)


def _ncc(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    a, b = a[mask] - a[mask].mean(), b[mask] - b[mask].mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


# ----------------------------------------------------------------------------------------------
# synthetic generator
# ----------------------------------------------------------------------------------------------


def test_place_dataset_access_and_errors(tmp_path):
    qp = _write_images(tmp_path / "q", ["a.png", "b.png"])
    rp = _write_images(tmp_path / "r", ["c.png", "d.png", "e.png"], seed=1)
    gt = np.zeros((2, 3), bool)
    gt[0, 1] = gt[1, 2] = True
    ds = PlaceDataset("t", qp, rp, gt, None)
    assert len(ds) == 2 and ds.gt_pairs() == [(0, 1), (1, 2)]
    assert ds.image_size("query", 1) == (32, 40)
    key = ds.image_key("reference", 0)
    assert key == ds.image_key("reference", 0) and len(key) == 16
    assert key != ds.image_key("reference", 1)
    assert ds.load_image("reference", 2).shape == (32, 40, 3)
    with pytest.raises(ValueError, match="unknown side 'ref'; valid: query, reference"):
        ds.load_image("ref", 0)
    with pytest.raises(IndexError, match="out of range"):
        ds.load_image("query", 2)
    with pytest.raises(IndexError, match="out of range"):
        ds.load_image("reference", -1)
    with pytest.raises(
        ValueError, match=r"of PlaceDataset 't' has shape \(3, 2\).*must be \(2, 3\)"
    ):
        PlaceDataset("t", qp, rp, np.zeros((3, 2), bool), None)
    with pytest.raises(ValueError, match="must hold bools or 0/1 numbers, got dtype int64"):
        PlaceDataset("t", qp, rp, np.full((2, 3), 2), None)
    as_int = PlaceDataset("t", qp, rp, gt.astype(int), None)  # 0/1 numbers are read as bools
    assert as_int.ground_truth.dtype == bool and as_int.gt_pairs() == [(0, 1), (1, 2)]
    with pytest.raises(ValueError, match="ground_truth_soft must hold every ground_truth pair"):
        PlaceDataset("t", qp, rp, gt, None, ground_truth_soft=np.zeros((2, 3), bool))
    with pytest.raises(ValueError, match="homographies"):
        PlaceDataset("t", qp, rp, gt, None, homographies=np.zeros((3, 3, 3)))


def test_image_key_is_content_based(tmp_path):
    (p,) = _write_images(tmp_path / "q", ["x.png"])
    copy = tmp_path / "copy.png"
    copy.write_bytes(p.read_bytes())
    a = PlaceDataset("a", [p], [p], np.ones((1, 1), bool), 0)
    b = PlaceDataset("b", [copy], [copy], np.ones((1, 1), bool), 0)
    assert a.image_key("query", 0) == b.image_key("reference", 0)


def test_unreadable_image_is_a_clear_error(tmp_path):
    _write_images(tmp_path / "query", ["0.png"])
    _write_images(tmp_path / "reference", ["0.png"])
    bad = tmp_path / "query" / "1.jpg"
    bad.write_bytes(b"this is not a jpeg at all \x00\x01\x02")
    _write_images(tmp_path / "reference", ["1.png"])
    ds = load_dataset("folder", root=tmp_path)
    with pytest.raises(ValueError, match=r"1\.jpg is not a readable image"):
        ds.load_image("query", 1)
    ds.query_paths[0].unlink()
    with pytest.raises(FileNotFoundError, match="not found"):
        ds.load_image("query", 0)


# ----------------------------------------------------------------------------------------------
# load_dataset: names and options
# ----------------------------------------------------------------------------------------------


def test_registry_and_unknown_name():
    assert set(DATASETS) == {
        "synthetic",
        "gardens_point",
        "mapillary_berlin",
        "freiburg_across_seasons",
        "folder",
        "nordland",
        "vpr_bench",
        "utm",
    }
    with pytest.raises(ValueError) as e:
        load_dataset("oxford")
    for n in DATASETS:
        assert n in str(e.value)


def test_unknown_option_lists_valid_ones(tmp_path):
    with pytest.raises(
        ValueError, match=r"unknown dataset 'synthetic' option\(s\) 'n_place'; valid: .*n_places"
    ):
        load_dataset("synthetic", n_place=3)


@pytest.mark.parametrize(
    "name",
    [
        "gardens_point",
        "mapillary_berlin",
        "freiburg_across_seasons",
        "folder",
        "nordland",
        "vpr_bench",
    ],
)
def test_missing_root(name, tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_dataset(name, root=tmp_path / "nowhere")
    (tmp_path / "a_file").write_text("")
    with pytest.raises(FileNotFoundError, match=rf"dataset '{name}': root .*a_file' is a file"):
        load_dataset(name, root=tmp_path / "a_file")
    with pytest.raises(ValueError, match="needs root="):
        load_dataset(name)


# ----------------------------------------------------------------------------------------------
# real-data loaders on small fake trees
# ----------------------------------------------------------------------------------------------


def test_gardens_point_layout(tmp_path):
    names = [f"Image{i:03d}.jpg" for i in range(6)]
    for t in ("day_left", "day_right", "night_right"):
        _write_images(tmp_path / t, names)
    ds = load_dataset("gardens_point", root=tmp_path)
    assert ds.tolerance == 2 and ds.query_paths[0].parent.name == "day_left"
    assert ds.reference_paths[5].name == "Image005.jpg"
    assert ds.reference_paths[0].parent.name == "night_right"
    q, r = np.indices((6, 6))
    assert np.array_equal(ds.ground_truth, np.abs(q - r) <= 2)
    ds0 = load_dataset("gardens_point", root=tmp_path, query="day_right", tolerance=0)
    assert np.array_equal(ds0.ground_truth, np.eye(6, dtype=bool))
    with pytest.raises(ValueError, match="valid: day_left"):
        load_dataset("gardens_point", root=tmp_path, query="dusk")


def test_gardens_point_archive_folder_and_errors(tmp_path):
    base = tmp_path / "GardensPointWalking"
    _write_images(base / "day_left", ["Image000.jpg", "Image001.jpg"])
    _write_images(base / "night_right", ["Image000.jpg"])
    with pytest.raises(ValueError, match=r"reference side lacks frame\(s\) 1 \(Image001.jpg\)"):
        load_dataset("gardens_point", root=tmp_path)
    _write_images(base / "night_right", ["Image001.jpg"])
    assert load_dataset("gardens_point", root=tmp_path).root == base
    other = tmp_path / "other"
    _write_images(other / "day_left", ["Image000.jpg"])
    with pytest.raises(FileNotFoundError, match="night_right"):
        load_dataset("gardens_point", root=other)


def test_gardens_point_pairs_by_frame_number(tmp_path):
    # one frame missing on each side: the counts agree, positions would pair 2 with 3
    _write_images(tmp_path / "day_left", [f"Image{i:03d}.jpg" for i in (0, 1, 3, 4)])
    _write_images(tmp_path / "night_right", [f"Image{i:03d}.jpg" for i in (0, 1, 2, 4)])
    with pytest.raises(
        ValueError,
        match=r"query side lacks frame\(s\) 2 \(Image002.jpg\); the reference side lacks "
        r"frame\(s\) 3 \(Image003.jpg\)",
    ):
        load_dataset("gardens_point", root=tmp_path)
    _write_images(tmp_path / "night_right", ["Image003.jpg"])
    _write_images(tmp_path / "day_left", ["Image002.jpg"])
    ds = load_dataset("gardens_point", root=tmp_path)
    assert [p.name for p in ds.query_paths] == [p.name for p in ds.reference_paths]
    (tmp_path / "night_right" / "renamed.jpg").write_bytes(b"")
    with pytest.raises(ValueError, match=r"renamed\.jpg has none"):
        load_dataset("gardens_point", root=tmp_path)


def test_folder_refuses_a_frame_missing_on_each_side(tmp_path):
    _write_images(tmp_path / "query", ["0.jpg", "1.jpg", "3.jpg"])
    _write_images(tmp_path / "reference", ["0.jpg", "1.jpg", "2.jpg"])
    with pytest.raises(ValueError, match=r"folder: .*query side lacks frame\(s\) 2 \(2.jpg\)"):
        load_dataset("folder", root=tmp_path)
    # numbers that never meet (e.g. per-traverse timestamps) keep pairing by position
    _write_images(tmp_path / "t" / "query", ["1000.jpg", "1001.jpg"])
    _write_images(tmp_path / "t" / "reference", ["5.jpg", "6.jpg"])
    assert load_dataset("folder", root=tmp_path / "t").gt_pairs() == [(0, 0), (1, 1)]


def test_file_based_datasets_are_named_by_their_data_folder(tmp_path):
    """Issue 26 item 3: outputs and titles name the data (``corridor``), not the loader."""
    for side in ("query", "reference", "ref"):
        _write_images(tmp_path / "corridor" / side, ["0.png", "1.png"])
    np.save(
        tmp_path / "corridor" / "ground_truth_new.npy", np.array([[0, [0]], [1, [1]]], dtype=object)
    )
    (tmp_path / "corridor" / "ground_truth.csv").write_text("0,0\n1,1\n")
    for t in ("day_left", "night_right"):
        _write_images(tmp_path / "gp" / "GardensPointWalking" / t, ["Image000.jpg", "Image001.jpg"])
    for loader, root, name in [
        ("folder", tmp_path / "corridor", "corridor"),
        ("vpr_bench", tmp_path / "corridor", "corridor"),
        ("mapillary_berlin", tmp_path / "corridor", "corridor"),
        ("gardens_point", tmp_path / "gp", "GardensPointWalking"),
        ("folder", tmp_path / "corridor" / "query" / "..", "corridor"),
    ]:
        ds = load_dataset(loader, root)
        assert (ds.name, ds.meta["loader"]) == (name, loader)
    assert load_dataset("synthetic", n_places=2, image_size=SMALL).name == "synthetic"


def test_mapillary_berlin_layout(tmp_path):
    _write_images(tmp_path / "query", [f"q{i}.jpg" for i in range(4)])
    _write_images(tmp_path / "reference", [f"r{i}.jpg" for i in range(3)])
    (tmp_path / "ground_truth.csv").write_text(
        "query,reference\n# many-to-one correspondences\nq0.jpg,r0.jpg\nq1.jpg,r0.jpg\n2,1\n"
        "q3,r2.jpg\n"
    )
    ds = load_dataset("mapillary_berlin", root=tmp_path)
    assert ds.gt_pairs() == [(0, 0), (1, 0), (2, 1), (3, 2)]
    assert ds.tolerance == 0 and ds.homographies is None
    wide = load_dataset("mapillary_berlin", root=tmp_path, tolerance=1)
    assert wide.ground_truth[2].tolist() == [True, True, True]
    # one sequence in a sub-folder
    seq = tmp_path / "Kudamm"
    _write_images(seq / "query", ["a.jpg", "b.jpg"])
    _write_images(seq / "reference", ["c.jpg"])
    (seq / "ground_truth.csv").write_text("a.jpg,c.jpg\nb.jpg,c.jpg\n")
    ds2 = load_dataset("mapillary_berlin", root=tmp_path, sequence="Kudamm")
    assert ds2.ground_truth.tolist() == [[True], [True]]
    (tmp_path / "ground_truth.csv").unlink()
    with pytest.raises(FileNotFoundError, match="ground-truth file not found"):
        load_dataset("mapillary_berlin", root=tmp_path)


def test_freiburg_layout(tmp_path):
    _write_images(tmp_path / "summer2015", ["s1.png", "s2.png", "s3.png"])
    _write_images(tmp_path / "winter2012", ["w1.png", "w2.png", "w3.png"])
    (tmp_path / "ground_truth.csv").write_text("s1.png,w1.png\ns2.png,w3.png\ns3.png,w2.png\n")
    ds = load_dataset("freiburg_across_seasons", root=tmp_path)
    assert ds.gt_pairs() == [(0, 0), (1, 2), (2, 1)]
    assert ds.meta["layout_verified"] is False
    assert "UNVERIFIED" in load_freiburg_across_seasons.__doc__


def test_folder_frame_aligned_natural_sort_and_extensions(tmp_path):
    _write_images(tmp_path / "query", ["10.png", "2.PNG", "1.JPEG", "3.bmp"])
    (tmp_path / "query" / "notes.txt").write_text("not an image")
    (tmp_path / "query" / ".hidden.png").write_bytes(b"x")
    _write_images(tmp_path / "reference", ["r1.tif", "r2.png", "r3.ppm", "r10.jpg"])
    ds = load_dataset("folder", root=tmp_path, tolerance=1)
    assert [p.name for p in ds.query_paths] == ["1.JPEG", "2.PNG", "3.bmp", "10.png"]
    assert [p.name for p in ds.reference_paths] == ["r1.tif", "r2.png", "r3.ppm", "r10.jpg"]
    q, r = np.indices((4, 4))
    assert np.array_equal(ds.ground_truth, np.abs(q - r) <= 1)
    assert ds.load_image("reference", 0).shape == (32, 40, 3)


def test_folder_ground_truth_files(tmp_path):
    _write_images(tmp_path / "query", ["0.png", "1.png"])
    _write_images(tmp_path / "reference", ["0.png", "1.png", "2.png"])
    with pytest.raises(ValueError, match="supply a ground-\\s*truth file"):
        load_dataset("folder", root=tmp_path)
    gt = np.array([[0, 0, 1], [1, 0, 0]], np.uint8)
    np.save(tmp_path / "ground_truth.npy", gt)
    ds = load_dataset("folder", root=tmp_path)
    assert np.array_equal(ds.ground_truth, gt.astype(bool))
    (tmp_path / "ground_truth.csv").write_text("0,1\n")
    with pytest.raises(ValueError, match="remove one"):
        load_dataset("folder", root=tmp_path)
    ds = load_dataset("folder", root=tmp_path, ground_truth="ground_truth.csv")
    assert ds.gt_pairs() == [(0, 1)]
    # explicit absolute path
    other = tmp_path / "elsewhere.npy"
    np.save(other, np.ones((2, 3), bool))
    assert load_dataset("folder", root=tmp_path, ground_truth=other).ground_truth.all()


def test_ground_truth_shape_mismatch_and_bad_files(tmp_path):
    _write_images(tmp_path / "query", ["0.png", "1.png"])
    _write_images(tmp_path / "reference", ["0.png", "1.png"])
    bad = tmp_path / "bad.npy"
    np.save(bad, np.ones((3, 2), bool))
    with pytest.raises(ValueError, match=r"shape \(3, 2\).*must be \(2, 2\)"):
        load_dataset("folder", root=tmp_path, ground_truth=bad)
    np.save(bad, np.full((2, 2), 0.5))
    with pytest.raises(ValueError, match="0/1"):
        load_dataset("folder", root=tmp_path, ground_truth=bad)
    bad.write_bytes(b"garbage")
    with pytest.raises(ValueError, match="not a readable .npy"):
        load_dataset("folder", root=tmp_path, ground_truth=bad)
    csv_ = tmp_path / "gt.csv"
    for text, msg in (
        ("0,5\n", "reference index 5 out of range"),
        ("nope.png,0\n", "'nope.png' is not in the query folder"),
        ("0,1,2\n", "expected 2 columns"),
        ("query,reference\n", "no query,reference rows"),
    ):
        csv_.write_text(text)
        with pytest.raises(ValueError, match=msg):
            load_dataset("folder", root=tmp_path, ground_truth=csv_)
    txt = tmp_path / "gt.txt"
    txt.write_text("0 0\n")
    with pytest.raises(ValueError, match="unsupported ground-truth file"):
        load_dataset("folder", root=tmp_path, ground_truth=txt)


def test_empty_and_missing_traverse_folders(tmp_path):
    (tmp_path / "query").mkdir()
    _write_images(tmp_path / "reference", ["0.png"])
    with pytest.raises(ValueError, match="contains no images"):
        load_dataset("folder", root=tmp_path)
    _write_images(tmp_path / "query", ["0.png"])
    with pytest.raises(
        FileNotFoundError, match=r"traverse folder .*refs not found: .*beside it: query, reference"
    ):
        load_dataset("folder", root=tmp_path, reference="refs")
    (tmp_path / "gone").symlink_to(tmp_path / "nowhere")  # one rule for the loaders and images
    with pytest.raises(FileNotFoundError, match="gone not found: it is a dangling symlink"):
        load_dataset("folder", root=tmp_path, reference="gone")
    with pytest.raises(FileNotFoundError, match="gone not found: it is a dangling symlink"):
        D.list_images(tmp_path / "gone")


def test_folder_on_gardens_point_mini(gardens_point_mini_root):
    ds = load_dataset("folder", root=gardens_point_mini_root)
    assert len(ds) == 10 and len(ds.reference_paths) == 10
    assert np.array_equal(ds.ground_truth, np.eye(10, dtype=bool))
    assert [p.name for p in ds.query_paths][:3] == ["0.jpg", "1.jpg", "2.jpg"]
    assert ds.load_image("query", 0).shape == (540, 960, 3)
    assert ds.image_size("reference", 9) == (360, 640)


# ----------------------------------------------------------------------------------------------
# download_dataset against a local HTTP server
# ----------------------------------------------------------------------------------------------


@pytest.fixture()
def local_server(tmp_path):
    served = tmp_path / "served"
    served.mkdir()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for t in ("day_left", "night_right"):
            for i in range(2):
                _, png = cv2.imencode(".png", np.full((32, 32, 3), 40 * i, np.uint8))
                zf.writestr(f"GardensPointWalking/{t}/Image{i:03d}.png", png.tobytes())
    (served / "gp.zip").write_bytes(buf.getvalue())
    requests = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):  # keep test output quiet
            requests.append(self.path)

    handler = functools.partial(Handler, directory=str(served))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{server.server_address[1]}/gp.zip"
        yield url, hashlib.sha256(buf.getvalue()).hexdigest(), requests
    finally:
        server.shutdown()
        server.server_close()


def test_download_dataset_local_server(local_server, tmp_path):
    url, sha, requests = local_server
    dest = tmp_path / "data"
    root = download_dataset("gardens_point", dest, url=url, sha256=sha)
    assert root == dest / "GardensPointWalking"
    assert not (dest / "gp.zip").exists() and not list(dest.glob("*.part"))
    ds = load_dataset("gardens_point", root=root, tolerance=0)
    assert len(ds) == 2 and ds.load_image("query", 1).shape == (32, 32, 3)
    n = len(requests)
    assert download_dataset("gardens_point", dest, url=url, sha256=sha) == root
    assert len(requests) == n  # recorded as done: no second request
    download_dataset("gardens_point", dest, url=url, sha256=sha.upper(), overwrite=True)
    assert len(requests) == n + 1


def test_download_dataset_wrong_sha(local_server, tmp_path):
    url, _, _ = local_server
    dest = tmp_path / "data"
    with pytest.raises(ValueError, match="SHA-256 mismatch.*removed"):
        download_dataset("gardens_point", dest, url=url, sha256="0" * 64)
    assert list(dest.iterdir()) == []


def test_download_dataset_unknown_and_registry():
    with pytest.raises(ValueError, match="downloadable: gardens_point"):
        download_dataset("mapillary_berlin", "/tmp/unused-vpr-download")
    entry = DOWNLOADS["gardens_point"]
    assert "4590133" in entry["url"]
    assert entry["sha256"] is None or len(entry["sha256"]) == 64
    # the loaders' missing-root hint names exactly the datasets the download knows
    assert set(DOWNLOADABLE) == set(DOWNLOADS)


# ----------------------------------------------------------------------------------------------
# viz
# ----------------------------------------------------------------------------------------------


def test_plot_examples(tiny_synthetic, tmp_path):
    import matplotlib.pyplot as plt

    from vpr_study.viz import plot_examples

    seen = []

    def boxes(side, i, size):
        seen.append((side, i, size))
        return np.array([[10.0, 10.0, 50.0, 40.0]])

    fig = plot_examples(tiny_synthetic, indices=(0, 3), boxes=boxes, title="t")
    assert len(fig.axes) == 4
    assert [a.get_title() for a in fig.axes] == ["reference 0", "query 0", "reference 3", "query 3"]
    assert ("query", 3, (360, 640)) in seen and len(fig.axes[0].patches) == 1
    paths = []
    for k in range(2):
        p = tmp_path / f"ex{k}.png"
        fig.savefig(p, dpi=40, metadata={"Software": None})
        paths.append(p.read_bytes())
    assert paths[0] == paths[1]
    plt.close(fig)
    with pytest.raises(IndexError):
        plot_examples(tiny_synthetic, indices=(99,))


def test_irrelevant_sampling_and_gt_references():
    gt = np.zeros((6, 8), dtype=bool)
    for i in range(6):
        gt[i, max(0, i - 1) : i + 2] = True
    a = sample_irrelevant_references(gt, 5, seed=1)
    assert a == sample_irrelevant_references(gt, 5, seed=1)
    for q, rs in a.items():
        assert len(rs) == 5 and len(set(rs)) == 5 and not gt[q, rs].any()
    assert len(sample_irrelevant_references(gt, 50, seed=0)[0]) == 6  # all non-gt references
    assert ground_truth_references(gt, 3) == [3]
    assert ground_truth_references(gt, 3, "all") == [2, 3, 4]
    g2 = np.zeros((2, 5), dtype=bool)
    g2[0, [1, 2, 4]] = True
    assert ground_truth_references(g2, 0) == [2] and ground_truth_references(g2, 1) == []
    with pytest.raises(ValueError, match="unknown gt_pairs 'middle'; valid: center, all"):
        ground_truth_references(g2, 1, "middle")  # refused even for a query without truth


# -- issue 25 item 10: short bodies, slow servers, archive bombs -------------------------------


@pytest.fixture()
def hostile_server():
    """A local server (127.0.0.1 only) whose paths misbehave: ``/short`` announces 1,000 bytes
    and sends 10, ``/slow`` sends a byte every 0.2 s for ever, others serve ``state["zip"]``."""
    state: dict = {"zip": b"", "stop": threading.Event()}

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            self.send_response(200)
            if self.path.startswith("/short"):
                self.send_header("Content-Length", "1000")
                self.end_headers()
                self.wfile.write(b"x" * 10)
            elif self.path.startswith("/slow"):
                self.end_headers()
                while not state["stop"].wait(0.2):
                    try:
                        self.wfile.write(b"x")
                        self.wfile.flush()
                    except OSError:
                        return
            else:
                self.send_header("Content-Length", str(len(state["zip"])))
                self.end_headers()
                self.wfile.write(state["zip"])

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", state
    finally:
        state["stop"].set()
        server.shutdown()
        server.server_close()


def test_download_closed_early_is_not_recorded_as_done(hostile_server, tmp_path):
    base, _ = hostile_server
    dest = tmp_path / "data"
    for _ in range(2):  # the second call must try again, not say "already downloaded"
        with pytest.raises(OSError, match=r"sent 10 of the 1,000 bytes it announced"):
            download_dataset("x", dest, url=f"{base}/short.zip")
        assert sorted(p.name for p in dest.iterdir()) == []


def test_download_has_an_overall_deadline(hostile_server, tmp_path):
    base, _ = hostile_server
    dest = tmp_path / "data"
    start = time.monotonic()
    with pytest.raises(OSError, match=r"not finished after 1 s"):
        download_dataset("x", dest, url=f"{base}/slow.zip", deadline_s=1)
    assert time.monotonic() - start < 10
    assert list(dest.iterdir()) == []


def test_download_archive_bomb_is_refused_and_nothing_is_kept(hostile_server, tmp_path):
    base, state = hostile_server
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("big/zeros.bin", b"\0" * 2_000_000)  # ~2 kB compressed
        zf.writestr("big/ok.txt", b"fine")
    state["zip"] = buf.getvalue()
    dest = tmp_path / "data"
    with pytest.raises(ValueError, match=r"expands to 2,000,004 bytes, more than max_extract"):
        download_dataset("x", dest, url=f"{base}/b.zip", max_extract_bytes=1_000_000)
    assert [p.name for p in dest.iterdir()] == ["b.zip"]  # the archive, no marker, no files
    root = download_dataset("x", dest, url=f"{base}/b.zip", max_extract_bytes=3_000_000)
    assert root == dest / "big" and (root / "zeros.bin").stat().st_size == 2_000_000
    assert not list(dest.glob(".extract-*")) and (dest / ".vpr_download.json").is_file()


def test_download_deadline_must_be_finite(tmp_path):
    with pytest.raises(ValueError, match=r"deadline_s \(seconds\) must be in \(0, inf\), got inf"):
        download_dataset("x", tmp_path, url="http://127.0.0.1:9/x.zip", deadline_s=float("inf"))


def test_a_folder_layout_root_given_to_a_traverse_loader_is_pointed_to_folder(tmp_path):
    """Issue 54: Gardens Point mini has the query/ + reference/ layout; the gardens_point loader
    says so and gives the 'folder' call, which then loads it."""
    for side in ("query", "reference"):
        (tmp_path / side).mkdir()
        for i in range(2):
            cv2.imwrite(
                str(tmp_path / side / f"{i:03d}.png"), np.full((40, 60, 3), 30 * i, np.uint8)
            )
    with pytest.raises(FileNotFoundError) as err:
        load_dataset("gardens_point", root=tmp_path)
    call = f"load_dataset('folder', root={str(tmp_path)!r})"
    assert call in str(err.value) and "traverse names" not in str(err.value)
    assert len(eval(call, {"load_dataset": load_dataset})) == 2  # the hint works as written
