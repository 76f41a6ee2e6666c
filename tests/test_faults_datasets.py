"""Fault tests on the data side (issue 11, items 2-4): ground truth that cannot support a metric,
damaged image files, images below the minimum size. Each test fails if its protection is removed."""

from __future__ import annotations

import logging
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import skimage.data

from vpr_core.datasets import load_dataset, read_image
from vpr_core.datasets.ground_truth import check_coverage, check_ground_truth, ground_truth_coverage
from vpr_core.datasets.images import MIN_IMAGE_SIDE

GP_MINI = Path(__file__).resolve().parents[2] / "shared" / "data" / "gardens_point_mini"


def _images(folder: Path, n: int, size=(40, 48)) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(len(str(folder)))
    out = []
    for i in range(n):
        p = folder / f"{i}.png"
        assert cv2.imwrite(str(p), rng.integers(0, 256, (*size, 3), dtype=np.uint8))
        out.append(p)
    return out


# -- item 2: ground truth that cannot support a metric ----------------------------------------


def test_all_false_ground_truth_is_an_error(tmp_path):
    _images(tmp_path / "query", 3)
    _images(tmp_path / "reference", 3)
    np.save(tmp_path / "ground_truth.npy", np.zeros((3, 3), bool))
    with pytest.raises(ValueError, match=r"ground_truth.npy has no positive pair.*tolerance"):
        load_dataset("folder", tmp_path)
    with pytest.raises(ValueError, match="my rule has no positive pair"):
        check_coverage(np.zeros((2, 4), bool), "my rule")


def test_ground_truth_shape_and_values_are_one_rule():
    """check_ground_truth: the shape and 0/1 rule every ground truth meets (dataset, file, run)."""
    ok = check_ground_truth(np.eye(2, 3, dtype=int), (2, 3), "gt.npy")
    assert ok.dtype == bool and ok.tolist() == np.eye(2, 3, dtype=bool).tolist()
    with pytest.raises(ValueError, match=r"gt.npy has shape \(3, 2\) but must be \(2, 3\) for 2"):
        check_ground_truth(np.zeros((3, 2), bool), (2, 3), "gt.npy")
    with pytest.raises(ValueError, match=r"has shape \(3,\) but must be a \(Nq, Nr\) matrix"):
        check_ground_truth(np.zeros(3, bool), (3,), "x")
    with pytest.raises(ValueError, match="must hold bools or 0/1 numbers, got dtype float64"):
        check_ground_truth(np.full((2, 3), 0.5), (2, 3), "x")


def test_partial_csv_coverage_warns_with_the_count(tmp_path, caplog):
    _images(tmp_path / "query", 10)
    _images(tmp_path / "reference", 10)
    (tmp_path / "ground_truth.csv").write_text("0,0\n5,5\n")
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        ds = load_dataset("folder", tmp_path)
    assert "covers 2 of 10 queries; the other 8 are dropped from every metric" in caplog.text
    assert ds.queries_with_ground_truth == 2 and ds.n_query == 10
    assert ground_truth_coverage(ds.ground_truth) == (2, 10)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        full = load_dataset("folder", tmp_path, ground_truth=_full_csv(tmp_path))
    assert full.queries_with_ground_truth == 10 and "covers" not in caplog.text


def _full_csv(tmp_path: Path) -> Path:
    p = tmp_path / "full.csv"
    p.write_text("".join(f"{i},{i}\n" for i in range(10)))
    return p


def test_one_based_csv_warns_how_it_was_read(tmp_path, caplog):
    _images(tmp_path / "query", 10)
    _images(tmp_path / "reference", 10)
    one_based = tmp_path / "gt.csv"
    one_based.write_text("1,1\n2,2\n3,3\n")
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        ds = load_dataset("folder", tmp_path, ground_truth=one_based)
    assert "looks 1-based" in caplog.text and "read as 0-based indices" in caplog.text
    assert "cell '1' = 1.png" in caplog.text
    assert ds.gt_pairs() == [(1, 1), (2, 2), (3, 3)]  # read as documented: 0-based
    all_ten = tmp_path / "gt10.csv"
    all_ten.write_text("".join(f"{i},{i}\n" for i in range(1, 11)))
    with pytest.raises(ValueError, match=r"index 10 out of range.*look 1-based: subtract 1"):
        load_dataset("folder", tmp_path, ground_truth=all_ten)
    caplog.clear()
    zero_based = tmp_path / "gt0.csv"
    zero_based.write_text("0,0\n1,1\n2,2\n")
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        load_dataset("folder", tmp_path, ground_truth=zero_based)
    assert "1-based" not in caplog.text


# -- item 3: damaged images are refused by name -----------------------------------------------


def _real_jpeg(tmp_path: Path) -> Path:
    src = GP_MINI / "query" / "0.jpg"
    p = tmp_path / "photo.jpg"
    if src.is_file():
        p.write_bytes(src.read_bytes())
    else:
        assert cv2.imwrite(str(p), cv2.cvtColor(skimage.data.chelsea(), cv2.COLOR_RGB2BGR))
    return p


def test_truncated_jpeg_is_refused_by_name(tmp_path):
    good = _real_jpeg(tmp_path)
    img = read_image(good)
    expected = cv2.cvtColor(cv2.imread(str(good)), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(img, expected)  # good files: OpenCV's pixels, unchanged
    data = good.read_bytes()
    bad = tmp_path / "cut.jpg"
    bad.write_bytes(data[: len(data) * 2 // 3])
    assert cv2.imread(str(bad)) is not None  # OpenCV alone would decode it (partly grey)
    with pytest.raises(
        ValueError,
        match=r"cut\.jpg is a truncated JPEG.*Re-download the file or "
        r"remove it",
    ):
        read_image(bad)
    header_only = tmp_path / "header.jpg"
    header_only.write_bytes(data[:200])
    with pytest.raises(ValueError, match=r"header\.jpg is a JPEG without image data"):
        read_image(header_only)


def test_truncated_png_is_refused_by_name(tmp_path):
    good = tmp_path / "ok.png"
    assert cv2.imwrite(str(good), cv2.cvtColor(skimage.data.astronaut(), cv2.COLOR_RGB2BGR))
    data = good.read_bytes()
    no_end = tmp_path / "no_iend.png"
    no_end.write_bytes(data[:-12])  # the IEND chunk is cut off: the pixel data is complete
    with pytest.raises(ValueError, match=r"no_iend\.png is a truncated PNG.*Re-download"):
        read_image(no_end)
    half = tmp_path / "half.png"
    half.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=r"half\.png is a truncated PNG"):
        read_image(half)


def test_damaged_image_in_a_dataset_is_named(tmp_path):
    _images(tmp_path / "query", 2)
    _images(tmp_path / "reference", 2)
    p = tmp_path / "query" / "1.png"
    p.write_bytes(p.read_bytes()[:-12])
    ds = load_dataset("folder", tmp_path)
    ds.load_image("query", 0)
    with pytest.raises(ValueError, match=r"query/1\.png is a truncated PNG"):
        ds.load_image("query", 1)


# -- item 4: images below the minimum size ----------------------------------------------------


def test_images_below_min_side_are_refused(tmp_path):
    assert MIN_IMAGE_SIDE == 32
    ok = _images(tmp_path / "ok", 1, size=(32, 64))[0]  # Nordland's 64x32 frames load
    assert read_image(ok).shape == (32, 64, 3)
    tiny = _images(tmp_path / "tiny", 1, size=(8, 8))[0]
    with pytest.raises(
        ValueError,
        match=r"tiny/0\.png is too small: 8x8 pixels.*at least 32 "
        r"pixels on the short side",
    ):
        read_image(tiny)
    thin = _images(tmp_path / "thin", 1, size=(31, 200))[0]
    with pytest.raises(ValueError, match=r"200x31 pixels"):
        read_image(thin)
    assert read_image(thin, min_side=1).shape == (31, 200, 3)
    _images(tmp_path / "ds" / "query", 2, size=(8, 8))
    _images(tmp_path / "ds" / "reference", 2)
    ds = load_dataset("folder", tmp_path / "ds")
    with pytest.raises(ValueError, match=r"query/1\.png is too small"):
        ds.load_image("query", 1)


# -- issue 25 item 6: damaged JPEGs whose end marker is intact; folders named like images -----


def _jpeg_bytes(seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    ok, buf = cv2.imencode(".jpg", rng.integers(0, 256, (96, 128, 3), dtype=np.uint8))
    assert ok
    return buf.tobytes()


def test_jpeg_with_corrupted_scan_data_is_refused_by_name(tmp_path):
    data = bytearray(_jpeg_bytes())
    sos = data.rfind(b"\xff\xda")
    for i in range(sos + 200, sos + 400, 7):  # stray markers in the entropy-coded data
        data[i] = 0xFF if data[i] != 0xFF else 0x00
    bad = tmp_path / "corrupt.jpg"
    bad.write_bytes(bytes(data))
    assert cv2.imread(str(bad)) is not None  # OpenCV alone decodes it with garbled areas
    with pytest.raises(ValueError, match=r"corrupt\.jpg is a damaged JPEG .*Corrupt JPEG data"):
        read_image(bad)


def test_truncated_jpeg_with_end_marker_appended_is_refused(tmp_path):
    data = _jpeg_bytes(1)
    bad = tmp_path / "cut_eoi.jpg"
    bad.write_bytes(data[: data.rfind(b"\xff\xda") + 300] + b"\xff\xd9")
    assert cv2.imread(str(bad)) is not None
    with pytest.raises(ValueError, match=r"cut_eoi\.jpg is a damaged JPEG"):
        read_image(bad)
    good = tmp_path / "good.jpg"  # a clean JPEG decodes to OpenCV's pixels, nothing printed
    good.write_bytes(data)
    expected = cv2.cvtColor(cv2.imread(str(good)), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(read_image(good), expected)


def test_folder_named_like_an_image_is_reported_with_skipped_files(tmp_path, caplog):
    _images(tmp_path / "query", 2)
    _images(tmp_path / "reference", 2)
    (tmp_path / "query" / "7.jpg").mkdir()
    (tmp_path / "query" / "notes.txt").write_text("x")
    (tmp_path / "ground_truth.csv").write_text("0,0\n1,1\n")
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        ds = load_dataset("folder", tmp_path)
    assert len(ds.query_paths) == 2
    assert "skipped 2 file(s)" in caplog.text and "7.jpg" in caplog.text


# -- issue 25 item 9: header bombs are refused before anything is allocated -------------------


def _png_claiming(path: Path, width: int, height: int) -> None:
    """A tiny PNG whose IHDR claims ``width x height`` (the pixel data is one deflate stream)."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + body))
        return struct.pack(">I", len(body)) + kind + body + crc

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(b"\x00" * 100))
        + chunk(b"IEND", b"")
    )


@pytest.mark.parametrize("size", [(40_000, 40_000), (100_000, 2_000)])
def test_png_header_bomb_is_refused_by_name(tmp_path, size):
    bomb = tmp_path / "bomb.png"
    _png_claiming(bomb, *size)
    with pytest.raises(ValueError, match=rf"bomb\.png claims {size[0]} x {size[1]} pixels"):
        read_image(bomb)


def test_jpeg_header_bomb_is_refused_by_name(tmp_path):
    data = bytearray(_jpeg_bytes(2))
    sof = data.find(b"\xff\xc0")
    data[sof + 5 : sof + 9] = (60_000).to_bytes(2, "big") + (60_000).to_bytes(2, "big")
    bomb = tmp_path / "bomb.jpg"
    bomb.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"bomb\.jpg claims 60000 x 60000 pixels"):
        read_image(bomb)


# -- issue 25 errors: one line naming the file and line, never a raw int() error -------------


@pytest.mark.parametrize(
    ("cell", "match"),
    [
        ("\u00b2", r"line 2: query image '\u00b2' is not in the query folder"),
        ("9" * 5000, r"line 2: query index 9{20}\.\.\. out of range"),
        ("\u0663", r"line 2: query image '\u0663' is not in the query folder"),  # Arabic-Indic 3
    ],
)
def test_csv_cells_that_int_refuses_name_file_and_line(tmp_path, cell, match):
    _images(tmp_path / "query", 2)
    _images(tmp_path / "reference", 2)
    (tmp_path / "ground_truth.csv").write_text(f"0,0\n{cell},1\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"ground_truth\.csv, " + match) as exc:
        load_dataset("folder", tmp_path)
    assert "\n" not in str(exc.value) and len(str(exc.value)) < 400


@pytest.mark.parametrize("root", ["", "  "])
def test_empty_root_is_refused_not_the_current_folder(tmp_path, monkeypatch, root):
    _images(tmp_path / "query", 2)  # a valid dataset in the current folder must not be used
    _images(tmp_path / "reference", 2)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"needs root=<folder> \(got an empty string; use '\.'"):
        load_dataset("folder", root)
    assert load_dataset("folder", ".").n_query == 2


def test_root_of_the_wrong_type_is_one_line(tmp_path):
    with pytest.raises(ValueError, match=r"root must be a folder path \(str or Path\), got int"):
        load_dataset("folder", 123)


def test_other_format_header_bomb_is_named(tmp_path):
    """Every format Pillow's lazy open reads gets the header check (issue 31 item 5), BMP too."""
    bomb = tmp_path / "bomb.bmp"
    info = struct.pack("<IiiHHIIiiII", 40, 40_000, 40_000, 1, 24, 0, 100, 0, 0, 0, 0)
    bomb.write_bytes(b"BM" + struct.pack("<IHHI", 154, 0, 0, 54) + info + b"\0" * 100)
    with pytest.raises(ValueError, match=r"bomb\.bmp claims 40000 x 40000 pixels") as exc:
        read_image(bomb)
    assert "\n" not in str(exc.value)
