"""Fault tests for the encoder's inputs (issue 11, item 5): unreadable weights, unknown names.

Each test fails if its protection is removed: a raw torch/pickle error (or a silent load) would
not carry the file name and the expected content that the tests look for.
"""

from __future__ import annotations

import pytest
import torch

from vpr_core.backbones import alexnet as alexnet_mod
from vpr_core.backbones.checkpoint import WeightsFileError
from vpr_core.features import LandmarkEncoder, available_backbones


@pytest.fixture()
def no_alexnet_env(monkeypatch, tmp_path):
    monkeypatch.delenv(alexnet_mod.ALEXNET_ENV, raising=False)
    monkeypatch.setattr(torch.hub, "get_dir", lambda: str(tmp_path / "hub"))
    return tmp_path


def _valid_alexnet(path):
    g = torch.Generator().manual_seed(0)
    torch.save({k: torch.randn(s, generator=g) for k, s in alexnet_mod.CONV3_KEYS.items()}, path)


def _assert_names_file_and_expectation(err, path):
    msg = str(err.value)
    assert str(path) in msg, msg
    assert "torchvision AlexNet state dict" in msg and alexnet_mod.ALEXNET_FILENAME in msg, msg


def test_alexnet_weights_not_a_checkpoint(no_alexnet_env):
    bad = no_alexnet_env / "notes.pth"
    bad.write_text("this is not a torch checkpoint\n")
    with pytest.raises(WeightsFileError) as err:
        LandmarkEncoder("alexnet_conv3", weights=str(bad))
    _assert_names_file_and_expectation(err, bad)
    assert err.value.__cause__ is not None  # the original torch error is chained


def test_alexnet_weights_truncated(no_alexnet_env):
    good = no_alexnet_env / "alexnet.pth"
    _valid_alexnet(good)
    LandmarkEncoder("alexnet_conv3", weights=str(good), dim=8)  # the intact file loads
    bad = no_alexnet_env / "alexnet-truncated.pth"
    bad.write_bytes(good.read_bytes()[: good.stat().st_size // 3])
    with pytest.raises(WeightsFileError) as err:
        LandmarkEncoder("alexnet_conv3", weights=str(bad))
    _assert_names_file_and_expectation(err, bad)
    assert "truncated" in str(err.value)


def test_alexnet_weights_wrong_keys_and_not_a_dict(no_alexnet_env):
    bad = no_alexnet_env / "resnet.pth"
    torch.save({"conv1.weight": torch.zeros(64, 3, 7, 7)}, bad)
    with pytest.raises(ValueError) as err:
        LandmarkEncoder("alexnet_conv3", weights=str(bad))
    _assert_names_file_and_expectation(err, bad)
    assert "features.0.weight" in str(err.value)
    torch.save([torch.zeros(3)], bad)
    with pytest.raises(WeightsFileError) as err:
        LandmarkEncoder("alexnet_conv3", weights=str(bad))
    _assert_names_file_and_expectation(err, bad)


def test_alexnet_weights_from_env_unreadable(no_alexnet_env, monkeypatch):
    bad = no_alexnet_env / "env.pth"
    bad.write_bytes(b"\x00" * 100)
    monkeypatch.setenv(alexnet_mod.ALEXNET_ENV, str(bad))
    with pytest.raises(WeightsFileError) as err:
        LandmarkEncoder("alexnet_conv3")
    _assert_names_file_and_expectation(err, bad)


def test_efficientnet_weights_unreadable_or_wrong(tmp_path):
    bad = tmp_path / "lite0.pth"
    bad.write_text("garbage")
    with pytest.raises(WeightsFileError, match="EfficientNet-Lite0 state dict") as err:
        LandmarkEncoder(weights=str(bad))
    assert str(bad) in str(err.value)
    torch.save({"_conv_stem.weight": torch.zeros(32, 3, 3, 3)}, bad)
    with pytest.raises(WeightsFileError, match="does not fit EfficientNet-Lite0") as err:
        LandmarkEncoder(weights=str(bad))
    assert str(bad) in str(err.value)


def test_unknown_backbone_lists_valid_names():
    with pytest.raises(ValueError) as err:
        LandmarkEncoder("resnet50")
    msg = str(err.value)
    assert "resnet50" in msg
    for name in available_backbones():
        assert name in msg
