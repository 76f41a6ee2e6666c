"""The embedded default dataset: the synthetic street generator."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from vpr_core import datasets as D
from vpr_core.datasets import load_dataset

SMALL = (64, 112)  # (H, W) for fast generator tests


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


def test_generator_deterministic_and_seed_dependent():
    r1, q1, h1 = D.render_synthetic_place(0, 3, SMALL)
    r2, q2, h2 = D.render_synthetic_place(0, 3, SMALL)
    r3, q3, _ = D.render_synthetic_place(1, 3, SMALL)
    assert r1.shape == q1.shape == (*SMALL, 3) and r1.dtype == q1.dtype == np.uint8
    assert np.array_equal(r1, r2) and np.array_equal(q1, q2) and np.array_equal(h1, h2)
    assert not np.array_equal(r1, r3) and not np.array_equal(q1, q3)
    assert h1.shape == (3, 3) and h1.dtype == np.float64 and h1[2, 2] == pytest.approx(1.0)
    # night query is darker than the day reference
    assert q1.mean() < 0.6 * r1.mean()


def test_place_independent_of_n_places(tmp_path):
    a = load_dataset("synthetic", root=tmp_path / "a", n_places=3, image_size=SMALL)
    b = load_dataset("synthetic", root=tmp_path / "b", n_places=5, image_size=SMALL)
    for i in range(3):
        for side in ("query", "reference"):
            assert np.array_equal(a.load_image(side, i), b.load_image(side, i))
        np.testing.assert_array_equal(a.homographies[i], b.homographies[i])
    # and distinct places differ
    assert not np.array_equal(b.load_image("reference", 0), b.load_image("reference", 1))


def test_synthetic_dataset_fields(tiny_synthetic):
    ds = tiny_synthetic
    assert ds.name == "synthetic" and len(ds) == 8 and ds.tolerance == 0
    assert ds.ground_truth.dtype == bool and ds.ground_truth.shape == (8, 8)
    assert np.array_equal(ds.ground_truth, np.eye(8, dtype=bool))
    assert ds.gt_pairs() == [(i, i) for i in range(8)]
    assert ds.homographies.shape == (8, 3, 3)
    img = ds.load_image("query", 0)
    assert img.shape == (360, 640, 3) and img.dtype == np.uint8
    assert ds.image_size("reference", 7) == (360, 640)
    assert (ds.root / "manifest.json").is_file()
    man = json.loads((ds.root / "manifest.json").read_text())
    assert man["seed"] == 0 and man["image_size"] == [360, 640]
    assert "synthetic" in repr(ds) and "n_query=8" in repr(ds)


def test_synthetic_homography_aligns_views(tiny_synthetic):
    """Warping the night query into the reference frame with H lines up the structures."""
    ds = tiny_synthetic
    for i in range(4):
        q, r = ds.load_image("query", i), ds.load_image("reference", i)
        h, w = r.shape[:2]
        hm = ds.homographies[i]
        np.testing.assert_allclose(hm, D.synthetic_homography(0, i, (h, w)))
        warped = cv2.warpPerspective(q, hm, (w, h))
        valid = cv2.warpPerspective(np.ones((h, w), np.uint8), hm, (w, h)) > 0
        aligned = _ncc(_grad(warped), _grad(r), valid)
        identity = _ncc(_grad(q), _grad(r), np.ones((h, w), bool))
        assert aligned > 0.3 and aligned > identity + 0.25, (i, aligned, identity)


def test_synthetic_tolerance_and_options(tmp_path):
    ds = load_dataset("synthetic", root=tmp_path, n_places=5, image_size=SMALL, tolerance=1)
    q, r = np.indices((5, 5))
    assert np.array_equal(ds.ground_truth, np.abs(q - r) <= 1)
    assert ds.tolerance == 1
    for bad in ({"n_places": 0}, {"seed": -1}, {"image_size": (10, 10)}, {"tolerance": -1},
                {"image_size": "big"}):
        with pytest.raises(ValueError):
            load_dataset("synthetic", root=tmp_path, **bad)


def test_synthetic_cache_reuse_and_regeneration(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    ds = load_dataset("synthetic", n_places=2, image_size=SMALL)
    assert str(ds.root).startswith(str(tmp_path / "cache" / "datasets" / "synthetic-"))
    before = ds.query_paths[1].read_bytes()
    ds.query_paths[1].unlink()
    calls = []
    real = D.render_synthetic_place

    def spy(seed, i, size):
        calls.append(i)
        return real(seed, i, size)

    monkeypatch.setattr(D.synthetic, "render_synthetic_place", spy)
    ds2 = load_dataset("synthetic", n_places=2, image_size=SMALL)
    assert calls == [1]  # only the missing place is regenerated
    assert ds2.query_paths[1].read_bytes() == before  # byte-identical
    load_dataset("synthetic", n_places=2, image_size=SMALL)
    assert calls == [1]  # nothing missing: nothing generated
    # a different seed gets another cache folder
    assert load_dataset("synthetic", n_places=1, seed=5, image_size=SMALL).root != ds.root


# ----------------------------------------------------------------------------------------------
# PlaceDataset
# ----------------------------------------------------------------------------------------------
