"""vpr_core.datasets.synthetic: provenance is verified, not declared. The manifest records each
file's sha256; a folder named with ``root=`` is read only when every file matches and a seeded
place drawn again gives the recorded digests; a cached file that differs is drawn again."""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from vpr_core.datasets import load_dataset

SMALL = {"n_places": 3, "image_size": (32, 48)}


@pytest.fixture()
def made(tmp_path, monkeypatch):
    """A small set generated into a cache of its own (the tests change its files)."""
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    return load_dataset("synthetic", **SMALL)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _photo(path: Path, seed: int) -> None:
    rgb = (np.random.default_rng(seed).random((32, 48, 3)) * 255).astype(np.uint8)
    cv2.imwrite(str(path), rgb)


def _swap_one(root: Path) -> str:
    shutil.copyfile(root / "reference" / "0001.png", root / "reference" / "0000.png")
    return "reference/0000.png"


def _photos(root: Path) -> str:
    for k, f in enumerate(sorted(root.glob("*/0*.png"))):
        _photo(f, k)
    return "query/0000.png"


def _photos_and_their_digests(root: Path) -> str:
    """Other images, and a manifest whose digests were rewritten to match them."""
    _photos(root)
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["sha256"] = {k: _sha256(root / k) for k in manifest["sha256"]}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return r"(query|reference)/000\d.png"


def _no_digests(root: Path) -> str:
    manifest = json.loads((root / "manifest.json").read_text())
    del manifest["sha256"]
    (root / "manifest.json").write_text(json.dumps(manifest))
    return "its manifest.json records no file digests"


@pytest.mark.parametrize(
    "tamper",
    [_swap_one, _photos, _photos_and_their_digests, _no_digests],
    ids=["one image swapped", "every image replaced", "replaced with new digests", "no digests"],
)
def test_a_copied_generated_folder_is_verified_not_trusted(made, tmp_path, tamper):
    copy = tmp_path / "copy"
    shutil.copytree(made.root, copy)
    assert load_dataset("synthetic", root=copy, **SMALL).root == copy  # the copy as made
    named = tamper(copy)
    with pytest.raises(ValueError, match=rf"^synthetic: root=.*: {named}.*drop root="):
        load_dataset("synthetic", root=copy, **SMALL)


def test_a_changed_cached_view_is_drawn_again(made, caplog):
    path = made.root / "query" / "0002.png"
    before = path.read_bytes()
    _photo(path, 7)
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        again = load_dataset("synthetic", **SMALL)
    assert path.read_bytes() == before and again.root == made.root
    assert any("differ from their manifest's digests" in r.getMessage() for r in caplog.records)


def test_a_cache_written_before_digests_is_drawn_again_to_the_same_bytes(made):
    manifest_path = made.root / "manifest.json"
    manifest = json.loads(manifest_path.read_text())
    files = sorted(manifest.pop("sha256"))
    manifest_path.write_text(json.dumps(manifest))
    before = {f: (made.root / f).read_bytes() for f in files}
    load_dataset("synthetic", **SMALL)
    assert {f: (made.root / f).read_bytes() for f in files} == before
    recorded = json.loads(manifest_path.read_text())["sha256"]
    assert recorded == {f: hashlib.sha256(b).hexdigest() for f, b in before.items()}
