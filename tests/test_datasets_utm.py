"""The UTM-named layout (issue 19 item 2) and skipped files said (issue 17 item 6)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from vpr_core.datasets import load_dataset
from vpr_core.notices import VPRWarning


def _img(path: Path, value: int = 50) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.full((32, 40, 3), value, np.uint8))


def _name(e: float, n: float) -> str:
    return f"@{e:.2f}@{n:.2f}@10@S@037.75@-122.51@@@@@@@@.jpg"


def _utm_tree(root: Path) -> None:
    for k, (e, n) in enumerate([(543256.96, 4178906.93), (543300.0, 4178906.93), (0.0, 0.0)]):
        _img(root / "database" / _name(e, n), 10 * k)
    _img(root / "queries" / "sub" / _name(543256.96 + 20, 4178906.93), 1)  # 20 m / 23 m away
    _img(root / "queries" / _name(543256.96 + 60, 4178906.93), 2)  # 60 m / 17 m away


def test_utm_hard_and_soft_ground_truth(tmp_path):
    _utm_tree(tmp_path)
    ds = load_dataset("utm", tmp_path, positive_dist_threshold=25)
    assert ds.tolerance == "25 m" and f"tolerance {ds.tolerance}" == "tolerance 25 m"
    # recursive search sorted by path string (as sorted(glob)): queries/@... before queries/sub/@
    assert [p.parent.name for p in ds.query_paths] == ["queries", "sub"]
    assert [p.name.split("@")[1] for p in ds.reference_paths] == ["0.00", "543256.96", "543300.00"]
    assert ds.ground_truth.tolist() == [[False, False, True], [False, True, True]]
    assert ds.ground_truth_soft is None
    ds = load_dataset("utm", tmp_path, positive_dist_threshold=18, soft_dist_threshold=30)
    assert ds.ground_truth.tolist() == [[False, False, True], [False, False, False]]
    assert ds.ground_truth_soft.tolist() == [[False, False, True], [False, True, True]]
    sim = np.array([[0.1, 0.5, 0.2], [0.9, 0.3, 0.4]])
    assert ds.ignore_soft(sim).tolist() == [[0.1, 0.5, 0.2], [0.9, 0.1, 0.1]]
    with pytest.raises(ValueError, match="soft_dist_threshold .* must be >= "):
        load_dataset("utm", tmp_path, positive_dist_threshold=25, soft_dist_threshold=5)
    with pytest.raises(ValueError, match="positive_dist_threshold must be a number of metres"):
        load_dataset("utm", tmp_path, positive_dist_threshold="25")


def test_utm_paths_list_sets_the_order(tmp_path):
    _utm_tree(tmp_path)
    names = sorted(p.name for p in (tmp_path / "database").iterdir())[::-1]
    (tmp_path / "database_images_paths.txt").write_text("\n".join(names) + "\n")
    ds = load_dataset("utm", tmp_path)
    assert [p.name for p in ds.reference_paths] == names
    (tmp_path / "database_images_paths.txt").write_text("missing.jpg\n")
    with pytest.raises(
        FileNotFoundError,
        match=r"database_images_paths.txt lists 1 file\(s\) that "
        r"do not exist .*missing.jpg",
    ):
        load_dataset("utm", tmp_path)


def test_utm_paths_list_stays_inside_its_folder(tmp_path):
    _utm_tree(tmp_path)
    _img(tmp_path / "outside.jpg")
    listing = tmp_path / "database_images_paths.txt"
    for line in ("../outside.jpg", str(tmp_path / "outside.jpg"), "sub/../../outside.jpg"):
        listing.write_text(_name(543256.96, 4178906.93) + "\n" + line + "\n")
        with pytest.raises(ValueError, match=r"paths.txt line 2 names .* which is outside"):
            load_dataset("utm", tmp_path)


def _zone_tree(root: Path, query_zone: str, database_zone: str, extra: str | None = None) -> None:
    for side, zone in (("queries", query_zone), ("database", database_zone)):
        z, band = zone[:-1], zone[-1]
        _img(root / side / f"@543256.96@4178906.93@{z}@{band}@@@.jpg")
    if extra is not None:
        _img(root / "database" / f"@543300.00@4178906.93@{extra[:-1]}@{extra[-1]}@@@.jpg")


@pytest.mark.parametrize(
    ("query", "database", "extra"),
    [("32T", "33T", None), ("33H", "33T", None), ("33T", "33T", "32T")],
)
def test_utm_mixed_zones_are_refused(tmp_path, query, database, extra):
    _zone_tree(tmp_path, query, database, extra)
    with pytest.raises(ValueError, match=r"different UTM zones or hemispheres .*not comparable"):
        load_dataset("utm", tmp_path)


def test_utm_one_zone_and_bands_of_one_hemisphere_load(tmp_path):
    _zone_tree(tmp_path, "33T", "33U")  # T and U: both north of the equator, one grid
    ds = load_dataset("utm", tmp_path)
    assert ds.meta["utm_zone"] == "33N" and ds.ground_truth.tolist() == [[True]]
    _img(tmp_path / "database" / "@543256.96@4178906.93@99@T@@@.jpg")
    with pytest.raises(ValueError, match=r"'99', 'T'\) are not a UTM zone"):
        load_dataset("utm", tmp_path)


def test_utm_names_without_coordinates(tmp_path):
    _utm_tree(tmp_path)
    _img(tmp_path / "database" / "0001.jpg")
    with pytest.raises(
        ValueError,
        match=r"0001.jpg has no UTM coordinates in its name; names must "
        r"be @<utm_easting>@<utm_northing>@",
    ):
        load_dataset("utm", tmp_path)
    with pytest.raises(FileNotFoundError, match="traverse folder .*queries"):
        load_dataset("utm", tmp_path / "database")


def test_webp_read_and_unknown_files_named(tmp_path):
    for i, ext in enumerate(["jpg", "webp", "jpg", "jpg"]):
        _img(tmp_path / "query" / f"{i}.{ext}", 40 * i)
    for i in range(4):
        _img(tmp_path / "reference" / f"{i}.png", 40 * i)
    ds = load_dataset("folder", tmp_path)
    assert [p.name for p in ds.query_paths] == ["0.jpg", "1.webp", "2.jpg", "3.jpg"]
    assert ds.load_image("query", 1).shape == (32, 40, 3)
    (tmp_path / "query" / "1.webp").rename(tmp_path / "query" / "1.heic")
    (tmp_path / "reference" / "3.png").unlink()  # counts now match: 3 and 3
    with (
        pytest.warns(VPRWarning, match=r"skipped 1 file\(s\) .*1.heic"),
        pytest.raises(
            ValueError,
            match=r"1.heic\), so query i <-> reference i would pair .*"
            "give a ground-truth file .* or remove those files",
        ),
    ):
        load_dataset("folder", tmp_path)
    (tmp_path / "ground_truth.csv").write_text("0.jpg,0.png\n2.jpg,2.png\n")
    with pytest.warns(VPRWarning, match="1.heic"):
        ds = load_dataset("folder", tmp_path)
    assert ds.gt_pairs() == [(0, 0), (1, 2)]


@pytest.mark.skipif(os.name == "nt", reason="symlinks")
def test_broken_symlinks_named(tmp_path):
    for side in ("query", "reference"):
        for i in range(2):
            _img(tmp_path / side / f"{i}.jpg")
    (tmp_path / "query" / "2.jpg").symlink_to(tmp_path / "gone.jpg")
    with pytest.raises(ValueError, match=r"2.jpg is a dangling symlink \(it points to .*gone.jpg"):
        load_dataset("folder", tmp_path)
    (tmp_path / "query" / "2.jpg").unlink()
    (tmp_path / "query" / "2.jpg").symlink_to(tmp_path / "query" / "2.jpg")
    with pytest.raises(ValueError, match=r"2.jpg is a symlink loop"):
        load_dataset("folder", tmp_path)


def test_partial_ground_truth_warns_to_python_users(tmp_path):
    for side in ("query", "reference"):
        for i in range(3):
            _img(tmp_path / side / f"{i}.jpg")
    (tmp_path / "ground_truth.csv").write_text("0,0\n1,1\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_dataset("folder", tmp_path)
    assert next(str(w.message) for w in caught if w.category is VPRWarning).endswith(
        "covers 2 of 3 queries; the other 1 are dropped from every metric"
    )
