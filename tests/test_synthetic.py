"""The embedded default dataset: the synthetic street generator."""

from __future__ import annotations

import hashlib
import json

import cv2
import numpy as np
import pytest

from vpr_core import datasets as D
from vpr_core.datasets import load_dataset
from vpr_core.datasets import synthetic as S
from vpr_core.datasets.synthetic import _exact as X

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
    r1, q1, h1 = S.render_synthetic_place(0, 3, SMALL)
    r2, q2, h2 = S.render_synthetic_place(0, 3, SMALL)
    r3, q3, _ = S.render_synthetic_place(1, 3, SMALL)
    assert r1.shape == q1.shape == (*SMALL, 3) and r1.dtype == q1.dtype == np.uint8
    assert np.array_equal(r1, r2) and np.array_equal(q1, q2) and np.array_equal(h1, h2)
    assert not np.array_equal(r1, r3) and not np.array_equal(q1, q3)
    assert h1.shape == (3, 3) and h1.dtype == np.float64 and h1[2, 2] == pytest.approx(1.0)
    # night query is darker than the day reference
    assert q1.mean() < 0.6 * r1.mean()


def test_place_independent_of_n_places(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "a"))
    a = load_dataset("synthetic", n_places=3, image_size=SMALL)
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "b"))
    b = load_dataset("synthetic", n_places=5, image_size=SMALL)
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


def test_synthetic_homography_matches_default_dataset(tiny_synthetic):
    ds = tiny_synthetic
    assert json.loads((ds.root / "manifest.json").read_text())["difficulty"] == "default"
    for i in range(len(ds)):
        np.testing.assert_array_equal(ds.homographies[i], S.synthetic_homography(0, i))


@pytest.mark.parametrize("difficulty", ["easy", "default", "hard"])
def test_synthetic_homography_is_the_view_geometry(difficulty):
    """H equals a NumPy (LAPACK) solution for the view corners (query -> canvas -> ref)."""
    from vpr_core.datasets.synthetic._camera import _place_views

    def dlt(src, dst):
        a, b = [], []
        for (x, y), (u, v) in zip(src, dst, strict=False):
            a += [[x, y, 1, 0, 0, 0, -x * u, -y * u], [0, 0, 0, x, y, 1, -x * v, -y * v]]
            b += [u, v]
        return np.append(np.linalg.solve(np.array(a), np.array(b)), 1.0).reshape(3, 3)

    size = (360, 640)
    diff = S.DIFFICULTIES[difficulty]
    img = [(0, 0), (640, 0), (640, 360), (0, 360)]
    for i in range(5):
        ref, qry = _place_views(0, i, size, diff)
        expect = dlt(ref, img) @ dlt(img, qry)
        np.testing.assert_allclose(
            S.synthetic_homography(0, i, size, difficulty),
            expect / expect[2, 2],
            rtol=1e-7,
            atol=1e-9,
        )


def test_synthetic_homography_aligns_views(tmp_path):
    """Warping the night query into the reference frame with H lines up the structures."""
    ds = load_dataset("synthetic", n_places=4, difficulty="easy")
    for i in range(4):
        q, r = ds.load_image("query", i), ds.load_image("reference", i)
        h, w = r.shape[:2]
        hm = ds.homographies[i]
        np.testing.assert_allclose(hm, S.synthetic_homography(0, i, (h, w), "easy"))
        warped = cv2.warpPerspective(q, hm, (w, h))
        valid = cv2.warpPerspective(np.ones((h, w), np.uint8), hm, (w, h)) > 0
        aligned = _ncc(_grad(warped), _grad(r), valid)
        identity = _ncc(_grad(q), _grad(r), np.ones((h, w), bool))
        assert aligned > 0.3 and aligned > identity + 0.25, (i, aligned, identity)


def test_synthetic_tolerance_and_options(tmp_path):
    ds = load_dataset("synthetic", n_places=5, image_size=SMALL, tolerance=1)
    q, r = np.indices((5, 5))
    assert np.array_equal(ds.ground_truth, np.abs(q - r) <= 1)
    assert ds.tolerance == 1
    for bad in (
        {"n_places": 0},
        {"seed": -1},
        {"image_size": (10, 10)},
        {"tolerance": -1},
        {"image_size": "big"},
    ):
        with pytest.raises(ValueError):
            load_dataset("synthetic", **bad)


def test_synthetic_cache_reuse_and_regeneration(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    ds = load_dataset("synthetic", n_places=2, image_size=SMALL)
    assert str(ds.root).startswith(str(tmp_path / "cache" / "datasets" / "synthetic-"))
    before = ds.query_paths[1].read_bytes()
    ds.query_paths[1].unlink()
    calls = []
    real = S.render_synthetic_place

    def spy(seed, i, size, difficulty="default"):
        calls.append(i)
        return real(seed, i, size, difficulty)

    monkeypatch.setattr(D.synthetic._loader, "render_place", spy)
    ds2 = load_dataset("synthetic", n_places=2, image_size=SMALL)
    assert calls == [1]  # only the missing place is regenerated
    assert ds2.query_paths[1].read_bytes() == before  # byte-identical
    load_dataset("synthetic", n_places=2, image_size=SMALL)
    assert calls == [1]  # nothing missing: nothing generated
    # a different seed gets another cache folder
    assert load_dataset("synthetic", n_places=1, seed=5, image_size=SMALL).root != ds.root


# ----------------------------------------------------------------------------------------------
# Exactness: the same pixels on every machine (issue 11 item 7)
# ----------------------------------------------------------------------------------------------

#: SHA-256 of the raw pixel bytes (reference, query) of ``render_synthetic_place(0, i, size, d)``.
#: Any change of these means the embedded default changed: bump SYNTHETIC_VERSION and update.
PIXEL_SHA256 = {
    ("easy", (64, 112), 0): (
        "c4e2bfcd449024d6041aa20dc93a28bd596d40d007eaa407d3af47fdb83ef6f4",
        "fac7acf83f3ac76257be2ba2e9881ea2e1f6abc3dbde449a16175e73f1cfab35",
    ),
    ("easy", (64, 112), 3): (
        "f09ed815cf8055b914ab395edbdbe66db7abb5a8f8f0b558db229a8ab1961ba0",
        "3bd450d30f091f383193592134a2a1d822d05311fd69f3e55cd0696468aaa5e7",
    ),
    ("easy", (360, 640), 1): (
        "5d79f1abcf5336a57b2ee9e2197ae7d4633563c8192b5b07f9ad0993c61c1ee2",
        "a12070c81b0aa0fdb6b72f5ba274cebbf4ee3485bf6995d2d16ee5ae7521fed7",
    ),
    # the study's default (calibrated for issue 9) and the hard preset
    ("default", (64, 112), 0): (
        "e5bf5a6040d5f29b5e1ff2b2aeab16aa90dd1609b58c5f8c88c6438e29e556c1",
        "9c64e992eb9c64cd33e7a2ee9dd30d1fb280992e1cb1e6aac184ecb0f2cc0eb1",
    ),
    ("default", (360, 640), 2): (
        "7326bcb373b5d8054efa85838bc7646ca80b078da9e1f40083c9e126ba375d2e",
        "6ba12b87e5ca7e254bf5eb8e6f9775babcc12de03dd66bf716a53f3591f920a7",
    ),
    ("hard", (64, 112), 1): (
        "c10a721796bc24778604897acec42b38bab8ebd35169e22ec0e47c206f6e1dff",
        "98ebe7587d5e37973af9f29fdc07a6bcb0998b83658b3b76bca286f36e77f33d",
    ),
}


@pytest.mark.parametrize(
    "key", list(PIXEL_SHA256), ids=lambda k: f"{k[0]}-{k[1][0]}x{k[1][1]}-{k[2]}"
)
def test_pixels_match_committed_hashes(key):
    difficulty, size, i = key
    ref, qry, _ = S.render_synthetic_place(0, i, size, difficulty)
    got = (hashlib.sha256(ref.tobytes()).hexdigest(), hashlib.sha256(qry.tobytes()).hexdigest())
    assert got == PIXEL_SHA256[key], (
        f"synthetic place {key} changed pixels: {got}. If intended, bump SYNTHETIC_VERSION and "
        "update PIXEL_SHA256; if not, a non-exact operation crept into the generator "
        "(docs/SYNTHETIC.md)."
    )


def test_generator_independent_of_opencv_threads():
    """No threaded / SIMD OpenCV path is used: pixels do not depend on cv2's thread count."""
    n = cv2.getNumThreads()
    try:
        cv2.setNumThreads(1)
        a = S.render_synthetic_place(0, 2, SMALL, "hard")
        cv2.setNumThreads(4)
        b = S.render_synthetic_place(0, 2, SMALL, "hard")
    finally:
        cv2.setNumThreads(n)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=False))


def test_exact_primitives_agree_with_opencv():
    """Own warp / blur / resize give what OpenCV gives, up to OpenCV's fixed-point rounding."""
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (40, 50, 3)).astype(np.uint8)
    h = ((1.02, 0.05, -3.0), (-0.03, 0.98, 2.0), (1e-4, -2e-4, 1.0))
    ours = X.warp_perspective(img, h, (30, 40))
    ref = cv2.warpPerspective(
        img.astype(np.float32),
        np.array(h),
        (40, 30),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_REFLECT101,
    )
    assert np.abs(ours - ref).max() < 0.2
    f = img.astype(np.float64)
    blur = cv2.GaussianBlur(f, (2 * 6 + 1, 2 * 6 + 1), 2.0, borderType=cv2.BORDER_REFLECT101)
    assert np.abs(X.gaussian_blur(f, 2.0) - blur).max() < 0.5
    up = cv2.resize(f, (80, 64), interpolation=cv2.INTER_LINEAR)
    assert np.abs(X.resize_bilinear(f, (64, 80)) - up).max() < 1e-6
    down = cv2.resize(img, (25, 20), interpolation=cv2.INTER_AREA).astype(np.float64)
    assert np.abs(X.resize_area(img, (20, 25)) - down).max() <= 0.5
    with pytest.raises(AssertionError, match="integer"):  # an internal contract
        X.resize_area(f, (20, 25))


def test_solve_homography_roundtrip_and_degenerate():
    src = [(0, 0), (10, 0), (10, 8), (0, 8)]
    dst = [(1.5, 2.0), (12.0, 1.0), (11.0, 9.5), (0.5, 8.0)]
    hm = X.normalise_h(X.solve_homography(src, dst))
    for (x, y), (u, v) in zip(src, dst, strict=False):
        p = hm @ [x, y, 1.0]
        assert p[0] / p[2] == pytest.approx(u) and p[1] / p[2] == pytest.approx(v)
    with pytest.raises(AssertionError, match="degenerate"):  # an internal contract
        X.solve_homography([(0, 0), (1, 1), (2, 2), (3, 3)], dst)


# ----------------------------------------------------------------------------------------------
# Difficulty settings (issue 9 item 3)
# ----------------------------------------------------------------------------------------------


def test_difficulty_presets_and_errors(tmp_path):
    assert {"easy", "default", "hard"} <= set(S.DIFFICULTIES)
    assert S.resolve_difficulty("Hard") == ("hard", S.DIFFICULTIES["hard"])
    custom = S.SyntheticDifficulty(zoom=(0.9, 1.1))
    assert S.resolve_difficulty(custom) == ("custom", custom)
    assert S.resolve_difficulty(S.SyntheticDifficulty()) == ("easy", S.DIFFICULTIES["easy"])
    with pytest.raises(ValueError, match="easy, default, hard"):
        load_dataset("synthetic", n_places=1, image_size=SMALL, difficulty="brutal")
    with pytest.raises(TypeError, match="SyntheticDifficulty"):
        S.resolve_difficulty(3)
    with pytest.raises(ValueError, match="zoom"):
        S.SyntheticDifficulty(zoom=(1.2, 0.9))
    with pytest.raises(ValueError, match=r"SyntheticDifficulty.repeat_facades must be in \[0, 1\]"):
        S.SyntheticDifficulty(repeat_facades=1.5)
    with pytest.raises(ValueError, match=r"SyntheticDifficulty.glow must be in \[0, inf\]"):
        S.SyntheticDifficulty(glow=-0.1)
    with pytest.raises(ValueError, match="facade_pool must be a positive integer"):
        S.SyntheticDifficulty(facade_pool=0)
    with pytest.raises(ValueError, match=r"night_gamma must be in \(0, inf\]"):
        S.SyntheticDifficulty(night_gamma=0.0)
    for bad in ({"n_places": 0}, {"n_places": 2.5}, {"seed": -1}, {"seed": True}):
        with pytest.raises(ValueError, match=r"synthetic: (n_places|seed) must be"):
            load_dataset("synthetic", image_size=SMALL, **bad)


def test_difficulty_in_cache_key_and_manifest(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    a = load_dataset("synthetic", n_places=1, image_size=SMALL, difficulty="easy")
    b = load_dataset("synthetic", n_places=1, image_size=SMALL, difficulty="hard")
    c = load_dataset(
        "synthetic",
        n_places=1,
        image_size=SMALL,
        difficulty=S.SyntheticDifficulty(noise=(0.0, 0.0)),
    )
    assert len({a.root, b.root, c.root}) == 3
    man = json.loads((c.root / "manifest.json").read_text())
    assert man["difficulty"] == "custom" and man["difficulty_settings"]["noise"] == [0.0, 0.0]
    assert man["version"] == S.SYNTHETIC_VERSION
    assert not np.array_equal(a.load_image("query", 0), b.load_image("query", 0))


def test_repeated_facades_alias_places():
    """With repeat_facades=1 every building comes from the shared pool: places share facades."""
    from vpr_core.datasets.synthetic._world import render_world

    alias = S.SyntheticDifficulty(repeat_facades=1.0, facade_pool=1, style_share=1.0)
    w0 = render_world(0, 0, 93, 202, 64.0, alias)
    w1 = render_world(0, 1, 93, 202, 64.0, alias)
    e0 = render_world(0, 0, 93, 202, 64.0, S.DIFFICULTIES["easy"])
    e1 = render_world(0, 1, 93, 202, 64.0, S.DIFFICULTIES["easy"])
    band = slice(10, 60)  # facades, above the street furniture
    same_alias = (w0.img[band] == w1.img[band]).all(axis=2).mean()
    same_easy = (e0.img[band] == e1.img[band]).all(axis=2).mean()
    assert same_alias > same_easy + 0.2, (same_alias, same_easy)


def test_repetition_setting_off_by_default_and_repeats_the_route(tmp_path):
    """(Not in the paper) ``repetition``: 0 is the default route (same folder, same pixels);
    0.9 repeats a few shared buildings along the route, so different places look more alike."""
    plain = load_dataset("synthetic", n_places=2, image_size=SMALL)
    zero = load_dataset("synthetic", n_places=2, image_size=SMALL, repetition=0)
    assert zero.root == plain.root and "repetition" not in zero.meta
    rep = load_dataset("synthetic", n_places=6, image_size=SMALL, repetition=0.9)
    assert rep.root != plain.root and rep.meta["repetition"] == 0.9
    assert json.loads((rep.root / "manifest.json").read_text())["repetition"] == 0.9
    assert not np.array_equal(rep.load_image("reference", 0), plain.load_image("reference", 0))
    base = load_dataset("synthetic", n_places=6, image_size=SMALL)

    def alike(ds) -> float:  # mean structure correlation of different places' references
        g = [_grad(ds.load_image("reference", i)) for i in range(6)]
        full = np.ones(g[0].shape, dtype=bool)
        return float(np.mean([_ncc(g[i], g[j], full) for i in range(6) for j in range(i)]))

    assert alike(rep) > alike(base) + 0.02
    for bad in (-0.1, 1.5, True, "high"):
        with pytest.raises(ValueError, match="repetition must be a number in"):
            load_dataset("synthetic", n_places=1, image_size=SMALL, repetition=bad)
