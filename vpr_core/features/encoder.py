"""``Encoder`` (a value) and ``LandmarkEncoder`` (built from it): image + landmark boxes -> one
descriptor per box (Sec. 2.1): per-box crops (``crop``, the paper's) or RoIAlign on one feature
map per image (``roi``), then a Gaussian random projection; see docs/DEFINITIONS.md."""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import math
from typing import Any, cast

import numpy as np
import torch
from torch import nn

from ..backbones import (
    Parsed,
    build_backbone,
    canonical_backbone,
    feature_shape,
    parse_backbone,
    weights_sha256,
)
from ..backbones.checkpoint import state_dict_sha256
from ..backbones.module import ModuleBackbone, architecture_sha256
from ..checks import (
    check_boxes,
    check_choice,
    check_device,
    check_image,
    check_int,
    check_options,
    check_range,
)
from ..paper import PROJECTION_DIM
from .crops import crop_boxes, pyramid_levels
from .projection import random_projection
from .roi import (
    DEFAULT_ROI_SAMPLING,
    ROI_VERSION,
    WORKING_SIZE_FACTOR,
    RoiGrid,
    roi_pool,
    working_image,
)

logger = logging.getLogger("vpr_core")

__all__ = [
    "DESCRIPTOR_VERSION",
    "POOLING_MODES",
    "Encoder",
    "LandmarkEncoder",
    "as_encoder",
]

#: Bumped when the descriptor computation changes in a way that invalidates caches.
DESCRIPTOR_VERSION = 2  # 2: fixed batch shape (grouping-invariant descriptors)
#: Accepted ``pooling`` values.
POOLING_MODES = ("crop", "roi")
#: Largest crop side: a batch of 50 crops of 1,024 x 1,024 already takes 600 MB before the
#: backbone runs (100,000 would ask for 120 GB).
MAX_INPUT_SIZE = 1024


@dataclasses.dataclass(frozen=True)
class Encoder:
    """How landmarks are described (a value; :class:`LandmarkEncoder` builds it): the backbone
    (a name or spec, or a ``torch.nn.Module`` with its ``input_size``), its ``weights`` (a path,
    ``"random"`` for AlexNet, None: the default lookup), ``pooling`` (``"crop"``, the paper's, or
    ``"roi"``), the square crop side ``input_size`` (None: the backbone's), the torch ``device``,
    and the Gaussian random projection to ``dim`` (None: raw features) from ``seed``; then
    ``crop``/``roi`` details (``batch_size``, ``antialias``, ``working_size``, ``roi_sampling``;
    see :class:`LandmarkEncoder`). Checked once, here; :attr:`parsed_backbone` holds the parsed
    spec."""

    backbone: str | nn.Module = "efficientnet_lite0"
    weights: str | None = None
    pooling: str = "crop"
    input_size: int | None = None
    device: str = "cpu"
    dim: int | None = PROJECTION_DIM
    seed: int = 0
    batch_size: int = 50
    antialias: bool = True
    working_size: int | None = None
    roi_sampling: int = DEFAULT_ROI_SAMPLING

    def __post_init__(self) -> None:
        module = isinstance(self.backbone, nn.Module)
        if not isinstance(self.backbone, nn.Module):
            given = self.parsed_backbone[1]["input_size"]  # parsed once, or a clear error
            explicit = "input_size" in self.backbone.partition(":")[2]
            if explicit and self.input_size not in (None, given):
                raise ValueError(
                    f"input_size={self.input_size} conflicts with the backbone spec "
                    f"{self.backbone!r}; give the crop size once"
                )
        if self.weights is not None:
            if module:
                raise ValueError("a backbone module carries its own weights; pass weights=None")
            _set(self, "weights", str(self.weights))
        check_choice(self.pooling, "pooling", POOLING_MODES)
        if self.input_size is not None:
            least = 1 if module else 16
            _set(self, "input_size", check_int(self.input_size, "input_size (crop side)", least))
        elif module:
            raise ValueError(
                f"backbone={type(self.backbone).__name__}(...) needs its crop size: pass "
                "input_size=S (the side of the square (B, 3, S, S) crops it takes)"
            )
        side = (
            self.input_size
            if self.input_size is not None
            else self.parsed_backbone[1]["input_size"]
        )
        check_range(
            side, "input_size (crop side, what the machine's memory holds)", 1, MAX_INPUT_SIZE
        )
        check_device(self.device)
        _set(self, "device", str(self.device))
        if self.dim is not None:
            _set(self, "dim", check_int(self.dim, "dim (None: raw features)", 1))
        _set(self, "seed", check_int(self.seed, "seed", 0))
        _set(self, "batch_size", check_int(self.batch_size, "batch_size", 1))
        _set(self, "antialias", bool(self.antialias))
        if self.working_size is not None:
            _set(self, "working_size", check_int(self.working_size, "working_size", 32))
        _set(self, "roi_sampling", check_int(self.roi_sampling, "roi_sampling", 1))

    @functools.cached_property
    def parsed_backbone(self) -> Parsed:
        """:func:`~vpr_core.backbones.parse_backbone` of a named backbone, parsed once (when the
        value is made); the backbone functions take it as is. Not for a module backbone."""
        assert isinstance(self.backbone, str), "a module backbone has no spec"
        return parse_backbone(self.backbone)

    def identity(self) -> str:
        """Its identity as JSON: its fields, a module backbone named by its class, state and
        architecture (the module itself travels beside it), named weights by the sha256 of their
        file's bytes (what an executor's workers build the same encoder from)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        if isinstance(self.backbone, nn.Module):
            cls = type(self.backbone)
            fields["backbone"] = (
                f"module {cls.__module__}.{cls.__qualname__} "
                f"{state_dict_sha256(self.backbone.state_dict())} "
                f"{architecture_sha256(self.backbone)}"
            )
        else:
            fields["weights_sha256"] = weights_sha256(self.parsed_backbone, self.weights)
        return json.dumps(fields, sort_keys=True, default=str)


def as_encoder(encoder: Encoder | str | nn.Module | None = None, **options: Any) -> Encoder:
    """An :class:`Encoder` from a value, or a backbone (name, spec or module) with options."""
    given = list(options) + (["backbone"] if encoder is not None else [])
    check_options(given, [f.name for f in dataclasses.fields(Encoder)], "encoder")
    if isinstance(encoder, Encoder):
        return dataclasses.replace(encoder, **options) if options else encoder
    if encoder is not None:
        options["backbone"] = encoder
    return Encoder(**options)


def _set(obj: object, key: str, value: Any) -> None:
    object.__setattr__(obj, key, value)  # frozen dataclass: store the parsed value


class LandmarkEncoder:
    """Describe landmark boxes with a CNN (or handcrafted) backbone + Gaussian random projection.

    ``crop``: each box is cropped and resized to the backbone's square input (kornia, anti-alias
    pyramid) and run in batches of exactly ``batch_size``. ``roi``: the backbone runs once per
    image at ``working_size`` and boxes are pooled to the crop mode's ``(C, n, n)`` layout. Both
    normalise with the backbone's mean/std and project with ``P (raw_dim, dim) ~ N(0, 1/dim)``
    from ``numpy.random.default_rng(seed)``; descriptors are float32, not normalised.

    Args:
        encoder: an :class:`Encoder`, or its backbone (a name in :func:`available_backbones`,
            optionally with options, ``"efficientnet_lite0:stage=4,input_size=96"``, see
            :mod:`vpr_core.backbones`; or a ``torch.nn.Module`` mapping ``(B, 3, S, S)``
            ImageNet-normalised crops to ``(B, C, h, w)`` or ``(B, C)``, with ``input_size=S``).
        **options: the other :class:`Encoder` fields (``dim``: None or ``>= raw_dim`` gives raw
            features; ``seed`` also seeds ``weights="random"``; ``input_size`` None: the spec's
            or backbone's default, ``efficientnet_lite0`` 128, ``alexnet_conv3`` 227, ``hog`` 64;
            in ``roi`` mode it fixes the pooled grid ``n = ceil(input_size / stride)``;
            ``batch_size``: crops per forward pass and rows per projection matmul;
            ``antialias``: crop large boxes from an average-pooled pyramid; ``working_size``:
            ``roi`` mode's long image side, None: 4 x ``input_size``; ``roi_sampling``: ``roi``
            mode's bilinear samples per cell and axis).

    Attributes:
        spec: the :class:`Encoder` value.
        input_size: the crop side; feature_shape: the backbone's output on one crop.
        raw_dim: backbone feature length before projection.
        dim: descriptor length actually produced.
        config: dict describing everything that determines the descriptors (cache key),
            including ``pooling`` and ``weights_sha256`` (the weights' identity by content:
            file sha256, ``"random"``, ``"none"``, or a module's state-dict sha256).
        kwargs: the :class:`Encoder` fields (rebuild the encoder, e.g. on a Dask worker).

    Raises:
        ValueError: unknown backbone (lists valid names), unknown pooling, bad arguments,
            ``roi`` with a backbone that has no feature map (``hog``).
        FileNotFoundError: required weights are missing (message says how to get them).
        WeightsFileError: a weights file cannot be read or does not fit the backbone.
    """

    def __init__(self, encoder: Encoder | str | nn.Module | None = None, **options: Any) -> None:
        spec = as_encoder(encoder, **options)
        self.spec = spec
        self.kwargs: dict[str, Any] = {
            f.name: getattr(spec, f.name) for f in dataclasses.fields(spec)
        }
        module = isinstance(spec.backbone, nn.Module)
        name = type(spec.backbone).__name__ if module else canonical_backbone(spec.parsed_backbone)
        self.device = torch.device(spec.device)  # checked by the Encoder
        self.backbone_name = name
        self.seed = spec.seed
        self.pooling = spec.pooling
        self.batch_size = spec.batch_size
        self.antialias = spec.antialias
        self.roi_sampling = spec.roi_sampling
        if module:
            model: Any = ModuleBackbone(cast(nn.Module, spec.backbone), cast(int, spec.input_size))
            self.input_size, shape = model.input_size, model.feature_shape
        else:
            model = build_backbone(spec.parsed_backbone, spec.weights, self.seed)
            size = spec.input_size or spec.parsed_backbone[1]["input_size"]
            self.input_size, shape = size, feature_shape(model, size)
        self.model = model.to(self.device)
        if self.pooling == "roi" and getattr(self.model, "stride", None) is None:
            raise ValueError(
                f"pooling='roi' needs a backbone with a spatial feature map of known stride; "
                f"{name!r} has none: use pooling='crop' (a module may set a `stride` attribute)"
            )
        self.feature_shape: tuple[int, ...] = shape
        self.roi_grid = (
            RoiGrid(
                self.input_size,
                shape[-1],  # AlexNet conv3: 13, not ceil(227 / 16)
                int(self.model.stride),
                float(self.model.feature_offset),
                self.roi_sampling,
            )
            if self.pooling == "roi"
            else None
        )
        self.working_size = (
            WORKING_SIZE_FACTOR * self.input_size
            if spec.working_size is None
            else spec.working_size
        )
        self.raw_dim = math.prod(shape)
        self.weights_source = str(self.model.weights_source)
        self._mean = torch.tensor(self.model.mean, dtype=torch.float32, device=self.device)
        self._std = torch.tensor(self.model.std, dtype=torch.float32, device=self.device)
        self.dim_requested = spec.dim
        if self.dim_requested is None or self.dim_requested >= self.raw_dim:
            self.projection: torch.Tensor | None = None
            self.dim = self.raw_dim
        else:
            self.projection = random_projection(self.raw_dim, self.dim_requested, self.seed).to(
                self.device
            )
            self.dim = self.dim_requested
        self.config = self._make_config()
        logger.debug("LandmarkEncoder %s", self.config)

    def _make_config(self) -> dict[str, Any]:
        config: dict[str, Any] = {
            "backbone": self.backbone_name,
            "input_size": self.input_size,
            "raw_dim": self.raw_dim,
            "feature_shape": list(self.feature_shape),
            "dim": self.dim,
            "projection": (
                "none"
                if self.projection is None
                else "gaussian N(0, 1/dim), numpy default_rng(seed)"
            ),
            "seed": self.seed,
            "weights": self.weights_source,
            "weights_sha256": str(self.model.weights_sha256),
            "normalisation": {"mean": list(self.model.mean), "std": list(self.model.std)},
            "antialias": self.antialias,
            "pooling": self.pooling,
            "version": DESCRIPTOR_VERSION,
        }
        if self.pooling == "roi":
            config["working_size"] = self.working_size
            config["roi_sampling"] = self.roi_sampling
            config["roi_version"] = ROI_VERSION
            config.pop("antialias")  # crop-mode option
        if hasattr(self.model, "stage"):
            config["stage"] = int(self.model.stage)
        if isinstance(self.model, ModuleBackbone):
            config["module"] = self.model.qualname
            config["architecture_sha256"] = self.model.architecture_sha256
            config["probe_sha256"] = self.model.probe_sha256
        return config

    # ------------------------------------------------------------------ description
    def describe(self) -> dict[str, Any]:
        """A copy of :attr:`config` (backbone, pooling, input size, dims, seed, weights, ...)."""
        return dict(self.config)

    def __repr__(self) -> str:
        c = self.config
        return (
            f"LandmarkEncoder(backbone={c['backbone']!r}, pooling={c['pooling']!r}, "
            f"input_size={c['input_size']}, raw_dim={c['raw_dim']}, dim={c['dim']}, "
            f"seed={c['seed']}, weights={c['weights']!r})"
        )

    # ------------------------------------------------------------------ inputs
    def _levels(self, boxes: np.ndarray, image_size: tuple[int, int] | None = None) -> np.ndarray:
        """Pyramid level per box (see :func:`~vpr_core.features.crops.pyramid_levels`)."""
        return pyramid_levels(boxes, self.input_size, image_size, self.antialias)

    def _image_tensor(self, image: np.ndarray) -> torch.Tensor:
        """``(H, W, 3)`` uint8 -> ``(1, 3, H, W)`` float32 normalised, on the device."""
        x = torch.from_numpy(np.ascontiguousarray(image)).to(self.device)
        x = x.permute(2, 0, 1).unsqueeze(0).float().div_(255.0)
        return (x - self._mean[:, None, None]) / self._std[:, None, None]

    def crops(self, image: np.ndarray, boxes: np.ndarray) -> torch.Tensor:
        """Normalised crops of ``boxes`` (``crop`` mode's network input).

        Args:
            image: ``(H, W, 3)`` uint8 RGB.
            boxes: ``(K, 4)`` float ``(x, y, w, h)`` pixels.

        Returns:
            ``(K, 3, s, s)`` float32 tensor on the device, ``s = input_size``.
        """
        image = check_image(image)
        boxes = check_boxes(boxes, positive=True)
        return crop_boxes(
            self._image_tensor(image), boxes, self.input_size, self.batch_size, self.antialias
        )

    # ------------------------------------------------------------------ encode
    def encode(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """Describe each landmark box.

        Args:
            image: ``(H, W, 3)`` uint8 RGB.
            boxes: ``(K, 4)`` float ``(x, y, w, h)`` pixels (clipped to the image).

        Returns:
            ``(K, dim)`` float32 descriptors (``(0, dim)`` for no boxes); row k describes box k
            independently of the other boxes (bit for bit, in both pooling modes).

        Raises:
            TypeError / ValueError: wrong image type/shape/dtype or boxes shape.
        """
        return self._encode(check_image(image), check_boxes(boxes, positive=True))

    def _encode(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """:meth:`encode` of a checked image and boxes."""
        if len(boxes) == 0:
            return np.zeros((0, self.dim), dtype=np.float32)
        if self.pooling == "crop":
            return self.encode_crops(
                crop_boxes(
                    self._image_tensor(image),
                    boxes,
                    self.input_size,
                    self.batch_size,
                    self.antialias,
                )
            )
        with torch.inference_mode():
            raw = self._roi_raw(image, boxes)
            outs = [
                self._project_fixed(raw[start : start + self.batch_size]).cpu()
                for start in range(0, len(boxes), self.batch_size)
            ]
        return torch.cat(outs).numpy().astype(np.float32, copy=False)

    def encode_crops(self, crops: torch.Tensor) -> np.ndarray:
        """``crop`` mode's network + projection on ready-made crops (from :meth:`crops`).

        Crops go through in batches of exactly ``batch_size`` (the last padded), so a crop's
        descriptor does not depend on which crops share its batch: crops of *several* images
        can be batched together and give the same bits as :meth:`encode` of each image (the
        feature stage does this to avoid padding every image's last batch).

        Args:
            crops: ``(K, 3, s, s)`` float32 normalised crops.

        Returns:
            ``(K, dim)`` float32 descriptors.
        """
        if len(crops) == 0:
            return np.zeros((0, self.dim), dtype=np.float32)
        outs = []
        with torch.inference_mode():
            for start in range(0, len(crops), self.batch_size):
                chunk = crops[start : start + self.batch_size].to(self.device)
                feats = self._forward_fixed(chunk, keep_padding=True)
                if self.projection is not None:
                    feats = feats @ self.projection
                outs.append(feats[: len(chunk)].cpu())
        return torch.cat(outs).numpy().astype(np.float32, copy=False)

    def encode_global(self, image: np.ndarray) -> np.ndarray:
        """Whole-image descriptor: :meth:`encode` of the box ``(0, 0, W, H)``.

        Same backbone, pooling mode and projection as the landmark descriptors (the ``global``
        method). Args: ``image`` ``(H, W, 3)`` uint8 RGB. Returns: ``(dim,)`` float32.
        """
        h, w = check_image(image).shape[:2]
        return self._encode(image, np.array([[0.0, 0.0, w, h]]))[0]

    def _roi_raw(self, image: np.ndarray, boxes: np.ndarray) -> torch.Tensor:
        """``roi`` mode raw features ``(K, raw_dim)`` on the device (one backbone pass)."""
        x = working_image(self._image_tensor(image), self.working_size)
        fmap, work = self.model.feature_map(x), (int(x.shape[-2]), int(x.shape[-1]))
        assert self.roi_grid is not None  # roi mode
        return roi_pool(fmap, boxes, image.shape[:2], work, self.roi_grid, self.batch_size)

    def _project_fixed(self, raw: torch.Tensor) -> torch.Tensor:
        """Project ``(B, raw_dim)`` rows in a matmul of fixed shape ``(batch_size, raw_dim)``."""
        if self.projection is None:
            return raw
        n = raw.shape[0]
        if n < self.batch_size:
            raw = torch.cat([raw, raw[-1:].expand(self.batch_size - n, -1)])
        return (raw @ self.projection)[:n]

    def _forward_fixed(self, batch: torch.Tensor, keep_padding: bool = False) -> torch.Tensor:
        """Backbone on a batch padded to ``batch_size`` rows (repeating the last crop): CPU
        kernels are chosen by shape, so a fixed shape makes a descriptor independent of how boxes
        were grouped. ``(B, C, S, S)`` -> ``(B, raw_dim)`` (``keep_padding``: all rows)."""
        n = batch.shape[0]
        if n < self.batch_size:
            pad = batch[-1:].expand(self.batch_size - n, *batch.shape[1:])
            batch = torch.cat([batch, pad])
        out = self.model(batch).float()
        return out if keep_padding else out[:n]

    def encode_raw(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """Backbone features before projection: ``(K, raw_dim)`` float32 (either pooling)."""
        image = check_image(image)
        boxes = check_boxes(boxes, positive=True)
        if len(boxes) == 0:
            return np.zeros((0, self.raw_dim), dtype=np.float32)
        with torch.inference_mode():
            if self.pooling == "roi":
                return self._roi_raw(image, boxes).cpu().numpy()
            crops = crop_boxes(
                self._image_tensor(image), boxes, self.input_size, self.batch_size, self.antialias
            )
            feats = [
                self._forward_fixed(crops[i : i + self.batch_size]).cpu()
                for i in range(0, len(boxes), self.batch_size)
            ]
        return torch.cat(feats).numpy()
