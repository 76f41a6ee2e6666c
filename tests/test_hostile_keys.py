"""Keys see every input (issue 45): a user module checked on its first real batch as well as its
probe, a probe of several crops, the notice on a constant similarity matrix, ``feature_map``
under autograd, and the study memo hashing every file a notebook can read."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import torch
from PIL import Image
from torch import nn

from vpr_core import run_method
from vpr_core.backbones import build_backbone
from vpr_core.datasets import load_dataset
from vpr_core.features import LandmarkEncoder
from vpr_core.notices import VPRWarning
from vpr_study import memo

BOXES = np.array([[0, 0, 50, 40], [10, 20, 60, 30], [40, 8, 30, 50]], dtype=float)


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return load_dataset("synthetic", n_places=2, image_size=(64, 112)).load_image("query", 0)


class LateFault(nn.Module):
    """A user backbone fine on its probe (its first two calls: the probe batch, then one probe
    crop alone), faulty afterwards (``kind``): ``(B, 3, S, S) -> (B, 8, S/4, S/4)``."""

    def __init__(self, kind: str) -> None:
        super().__init__()
        self.kind, self.calls = kind, 0
        self.conv = nn.Conv2d(3, 8, 3, stride=4, padding=1)
        g = torch.Generator().manual_seed(0)
        with torch.no_grad():
            self.conv.weight.copy_(torch.randn(self.conv.weight.shape, generator=g) * 0.2)
            self.conv.bias.zero_()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        self.calls += 1
        out = torch.relu(self.conv(x))
        if self.kind == "ok" or (self.calls <= 2 and self.kind != "constant_always"):
            return out
        if self.kind in ("constant", "constant_always"):
            return torch.ones_like(out)
        if self.kind == "zeros":
            return out * 0
        if self.kind == "nan":
            return out * float("nan")
        return torch.cat([out, out])  # "batch2": two items for each


FIX = {
    "zeros": r"returns all zeros on a real .*torch\.randn\(4, 3, 32, 32\)",
    "constant": r"returns the same (features for every crop|value in every cell).*torch\.randn",
    "constant_always": r"returns the same features for every crop on a random \(2, 3, 32, 32\)",
    "nan": r"returns NaN or inf .*(check it on real crops|use pooling='crop')",
    "batch2": r"returned \(2, 8, \d+, \d+\) for a \(1, 3, \d+, \d+\) image|keep the batch dim",
}


@pytest.mark.parametrize("pooling", ["crop", "roi"])
@pytest.mark.parametrize("kind", list(FIX))
def test_a_module_faulty_on_real_batches_is_refused_naming_it_and_the_fix(image, pooling, kind):
    with pytest.raises(ValueError, match=f"backbone module LateFault {FIX[kind]}"):
        LandmarkEncoder(LateFault(kind), dim=16, input_size=32, pooling=pooling).encode(
            image, BOXES
        )


def test_a_sound_module_passes_and_a_batch_of_one_crop_proves_nothing(image):
    enc = LandmarkEncoder(LateFault("ok"), dim=16, input_size=32)
    enc.encode(image, BOXES[:1])  # one crop padded with copies of itself: alike inputs
    enc.encode(image, BOXES)
    # a constant module on one crop (padded with copies of itself) is not refused for it
    one = LandmarkEncoder(LateFault("constant"), dim=16, input_size=32)
    assert one.encode(image, BOXES[:1]).shape == (1, 16)


SCALE = 1.0


class BatchGlobal(nn.Module):
    """A user backbone whose ``forward`` reads the global ``SCALE`` (issue 53: for any batch size;
    one reading it only for several crops is refused, tests/test_hostile_fifth.py)."""

    def __init__(self) -> None:
        super().__init__()
        self.conv = nn.Conv2d(3, 4, 3, stride=4, padding=1)
        g = torch.Generator().manual_seed(0)
        with torch.no_grad():
            self.conv.weight.copy_(torch.randn(self.conv.weight.shape, generator=g) * 0.2)
            self.conv.bias.zero_()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = torch.relu(self.conv(x))
        return out * SCALE


def test_a_forward_reading_a_global_changes_the_key(monkeypatch):
    from vpr_core.features.stage import encoder_slug

    before = LandmarkEncoder(BatchGlobal(), dim=16, input_size=32)
    monkeypatch.setattr(sys.modules[__name__], "SCALE", 2.0)
    after = LandmarkEncoder(BatchGlobal(), dim=16, input_size=32)
    assert after.config["weights_sha256"] == before.config["weights_sha256"]
    assert after.config["probe_sha256"] != before.config["probe_sha256"]
    assert encoder_slug(after) != encoder_slug(before)


@pytest.fixture(scope="module")
def uniform_images(tmp_path_factory):
    """A folder dataset of 4 + 4 images of one grey: every descriptor equal, whatever the net."""
    root = tmp_path_factory.mktemp("uniform")
    for side in ("query", "reference"):
        (root / side).mkdir()
        for i in range(4):
            Image.fromarray(np.full((48, 64, 3), 120, np.uint8)).save(root / side / f"{i}.png")
    return load_dataset("folder", root=root)


# identical descriptors: cosine 1 in float32 (1 - 2**-23 on an AVX-512 Xeon's reduction order)
@pytest.mark.parametrize(
    ("weighting", "value"), [(None, r"(1\.0|0\.9999998807907104)"), ("contrast", "0.0")]
)
def test_a_constant_similarity_matrix_gets_the_chance_notice(uniform_images, weighting, value):
    with pytest.warns(VPRWarning, match=rf"similarity matrix is constant \(every value {value}\)"):
        result = run_method(
            "global", uniform_images, n_bootstrap=0, input_size=32, dim=16, weighting=weighting
        )
    assert any("metrics are chance levels" in w for w in result.warnings)


def test_roi_nan_names_the_module_not_the_matcher(image):
    class NanOnImages(LateFault):
        """Finite on crops (the probe), NaN on a whole image (roi's input)."""

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            out = torch.relu(self.conv(x))
            return out if x.shape[-1] == 32 else out / 0 * 0

    enc = LandmarkEncoder(NanOnImages("ok"), dim=16, input_size=32, pooling="roi")
    with pytest.raises(ValueError, match=r"module NanOnImages returns NaN.*pooling='crop'"):
        enc.encode(image, BOXES)


def test_feature_map_under_autograd_is_the_module_path():
    net = build_backbone("efficientnet_lite0")
    x = torch.randn(2, 3, 64, 64, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        want = net._module_path(x.contiguous(memory_format=torch.channels_last))
        assert torch.equal(net.feature_map(x), want)
    got = net.feature_map(x)  # parameters require grad
    assert torch.equal(got.detach(), want)
    got.square().mean().backward()
    assert net.net._conv_stem.weight.grad is not None
    xg = x.clone().requires_grad_(True)
    with torch.no_grad():
        for p in net.parameters():
            p.requires_grad_(False)
    assert torch.equal(net.feature_map(xg).detach(), want)


# ------------------------------------------------------------------ the study memo
def _write(path, text: str | bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)


def test_memo_follows_a_symlinked_image_folder_and_survives_a_loop(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "out"))
    elsewhere = tmp_path / "elsewhere"
    _write(elsewhere / "0.png", b"first")
    root = tmp_path / "data"
    root.mkdir()
    (root / "query").symlink_to(elsewhere, target_is_directory=True)
    (elsewhere / "loop").symlink_to(root, target_is_directory=True)  # data/query/loop/query/...
    params = {"dataset": "folder", "root": str(root)}
    key = memo.inputs_key(params)
    _write(elsewhere / "0.png", b"other")
    assert memo.inputs_key(params) != key


@pytest.mark.parametrize("name", ["helpers/util.py", "places.csv", "scripts/01_x.py"])
def test_memo_sees_every_file_of_the_notebooks_folder_tree(tmp_path, name):
    nb = tmp_path / "notebooks" / "01_x.ipynb"
    _write(nb, "{}")
    _write(nb.parent / name, "a = 1\n")
    _write(nb.parent / ".ipynb_checkpoints" / "01_x-checkpoint.ipynb", "{}")
    key = memo.notebook_key(nb, "inputs")
    _write(nb.parent / ".ipynb_checkpoints" / "01_x-checkpoint.ipynb", '{"cells": []}')
    assert memo.notebook_key(nb, "inputs") == key  # editor litter is not an input
    _write(nb.parent / name, "a = 2\n")
    assert memo.notebook_key(nb, "inputs") != key


def test_memo_hashes_a_file_or_folder_given_as_an_option(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_OUTPUT_DIR", str(tmp_path / "out"))
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    gt = tmp_path / "outside" / "gt.csv"
    extra = tmp_path / "outside" / "masks"
    _write(gt, "0,0\n")
    _write(extra / "m.png", b"1")
    params = {
        "dataset": "synthetic",
        "root": None,
        "label": "x",
        "options": {"ground_truth": str(gt), "masks": [str(extra)]},
    }
    keys = [memo.inputs_key(params)]
    _write(gt, "0,1\n")
    keys.append(memo.inputs_key(params))
    _write(extra / "m.png", b"2")
    keys.append(memo.inputs_key(params))
    assert len(set(keys)) == 3
