"""AlexNet conv1-conv3 in torchvision's layer layout: the paper's landmark descriptor (64,896-d at
227x227). Weights are never downloaded: ``weights=`` path, ``$VPR_ALEXNET_WEIGHTS``, or the torch
hub cache file ``alexnet-owt-7be5be79.pth``; ``weights="random"`` only on request, flagged."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import torch
from torch import nn

from .. import settings
from ..checks import check_file
from .checkpoint import file_sha256, load_checkpoint, user_weights_label

logger = logging.getLogger("vpr_core")

__all__ = [
    "ALEXNET_ENV",
    "ALEXNET_FILENAME",
    "ALEXNET_URL",
    "CONV3_KEYS",
    "EXPECTED_WEIGHTS",
    "IMAGENET_MEAN",
    "IMAGENET_SHA256_PREFIX",
    "IMAGENET_STD",
    "RANDOM_WEIGHTS_LABEL",
    "AlexNetConv3",
    "resolve_weights",
]

ALEXNET_URL = "https://download.pytorch.org/models/alexnet-owt-7be5be79.pth"
ALEXNET_FILENAME = "alexnet-owt-7be5be79.pth"
ALEXNET_ENV = settings.ALEXNET_ENV
RANDOM_WEIGHTS_LABEL = "random (NOT pretrained)"
#: torch hub names a file by the first hex digits of its sha256: torchvision's ImageNet file.
IMAGENET_SHA256_PREFIX = ALEXNET_FILENAME.split("-")[-1].removesuffix(".pth")
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
#: What a weights file must hold (for error messages).
EXPECTED_WEIGHTS = f"a torchvision AlexNet state dict, e.g. {ALEXNET_FILENAME}"
CONV3_KEYS: dict[str, tuple[int, ...]] = {
    "features.0.weight": (64, 3, 11, 11),
    "features.0.bias": (64,),
    "features.3.weight": (192, 64, 5, 5),
    "features.3.bias": (192,),
    "features.6.weight": (384, 192, 3, 3),
    "features.6.bias": (384,),
}


def _hub_weights_path() -> Path:
    """Where torch hub would cache the torchvision AlexNet weights (may not exist)."""
    return Path(torch.hub.get_dir()) / "checkpoints" / ALEXNET_FILENAME


def _missing_weights_message() -> str:
    return (
        "AlexNet ImageNet weights not found. The 'alexnet_conv3' backbone needs torchvision's "
        f"AlexNet state dict ({ALEXNET_FILENAME}); nothing is downloaded at run time. Either:\n"
        f"  * download {ALEXNET_URL}\n"
        f"    and put it at {_hub_weights_path()} (the torch hub cache), or\n"
        f"  * set the environment variable {ALEXNET_ENV}=/path/to/{ALEXNET_FILENAME}, or\n"
        "  * pass LandmarkEncoder('alexnet_conv3', weights='/path/to/file.pth').\n"
        "For speed tests only, weights='random' builds an untrained network (flagged as such)."
    )


def resolve_weights(weights: str | os.PathLike | None) -> Path | str:
    """Find the AlexNet weights file, or return ``"random"`` when explicitly requested.

    Args:
        weights: a path, ``"random"``, or None (then ``$VPR_ALEXNET_WEIGHTS``, then the hub cache).

    Raises:
        FileNotFoundError: no file found; the message says where to put it and the download URL.
    """
    if isinstance(weights, str) and weights == "random":
        return "random"
    if weights is not None:
        p = Path(weights).expanduser()
        if not check_file(p, "AlexNet weights"):
            raise FileNotFoundError(
                f"AlexNet weights file {p} does not exist.\n" + _missing_weights_message()
            )
        return p
    env = settings.alexnet_weights()
    if env:
        p = Path(env).expanduser()
        if not check_file(p, ALEXNET_ENV):
            raise FileNotFoundError(
                f"{ALEXNET_ENV}={env} does not point to a file.\n" + _missing_weights_message()
            )
        return p
    p = _hub_weights_path()
    if p.is_file():
        return p
    raise FileNotFoundError(_missing_weights_message())


def _extract_conv3_state(
    state: dict[str, torch.Tensor], source: str = ""
) -> dict[str, torch.Tensor]:
    """Pick the conv1-conv3 tensors out of a (full torchvision) AlexNet state dict.

    Classifier and other extra keys are ignored; a ``module.`` prefix (DataParallel) is stripped.

    Raises:
        ValueError: a required key is missing or has the wrong shape.
        TypeError: the file does not hold a dict.
    """
    if isinstance(state, dict) and "state_dict" in state and isinstance(state["state_dict"], dict):
        state = state["state_dict"]
    if not isinstance(state, dict):
        raise TypeError(f"AlexNet weights {source}: expected {EXPECTED_WEIGHTS}, got {type(state)}")
    state = {k.removeprefix("module."): v for k, v in state.items()}
    out, problems = {}, []
    for key, shape in CONV3_KEYS.items():
        if key not in state:
            problems.append(f"missing key {key!r} (expected shape {shape})")
        elif tuple(state[key].shape) != shape:
            problems.append(f"{key!r} has shape {tuple(state[key].shape)}, expected {shape}")
        else:
            out[key] = state[key].float()
    if problems:
        raise ValueError(
            f"AlexNet weights {source} do not match torchvision's AlexNet layout (expected "
            f"{EXPECTED_WEIGHTS}): "
            + "; ".join(problems)
            + f". Found keys: {sorted(state)[:12]}{' ...' if len(state) > 12 else ''}"
        )
    return out


class AlexNetConv3(nn.Module):
    """AlexNet truncated after conv3 + ReLU (torchvision parameter names ``features.N``).

    Its features on the paper's 227-pixel crops (``paper.ALEXNET_INPUT``) are ``(384, 13, 13)``,
    ``paper.ALEXNET_CONV3_DIM`` values.

    Attributes:
        stride: 16, the conv3 output stride (two stride-2 max-pools after the stride-4 conv1).
        feature_offset: 15.5: conv3 cell ``i`` is centred on input pixel ``16 * i + 15``
            (continuous coordinate ``16 * i + 15.5``; conv1 pads 2 with an 11-pixel kernel).
        weights_sha256: sha256 of the weights file's contents, or ``"random"``.
        weights_source: ``"ImageNet (torchvision ...)"`` when the hash is torchvision's file,
            ``"user weights <first 12 hex>"`` otherwise, or ``"random (NOT pretrained)"``.

    ``forward``: ``(B, 3, s, s)`` ImageNet-normalised crops -> ``(B, 384 * h * w)`` float32;
    ``feature_map``: ``(B, 3, H, W)`` -> ``(B, 384, h, w)``.
    """

    mean = IMAGENET_MEAN
    std = IMAGENET_STD
    stride = 16
    feature_offset = 15.5

    def __init__(self, weights: str | os.PathLike | None = None, seed: int = 0) -> None:
        super().__init__()
        self.features = nn.Sequential(
            nn.Conv2d(3, 64, kernel_size=11, stride=4, padding=2),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(64, 192, kernel_size=5, padding=2),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(192, 384, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
        )
        resolved = resolve_weights(weights)
        if resolved == "random":
            gen = torch.Generator().manual_seed(int(seed))
            for m in self.features:
                if isinstance(m, nn.Conv2d):
                    nn.init.kaiming_normal_(
                        m.weight, mode="fan_out", nonlinearity="relu", generator=gen
                    )
                    assert m.bias is not None
                    nn.init.zeros_(m.bias)
            self.weights_sha256 = "random"
            self.weights_source = RANDOM_WEIGHTS_LABEL
            logger.warning(
                "alexnet_conv3 uses RANDOM weights (weights='random'): descriptors are NOT the "
                "paper's pretrained conv3 features; use only for speed/plumbing tests."
            )
        else:
            state = load_checkpoint(resolved, EXPECTED_WEIGHTS)
            self.load_state_dict(_extract_conv3_state(state, str(resolved)), strict=True)
            self.weights_sha256 = file_sha256(resolved)
            self.weights_source = (
                f"ImageNet (torchvision {ALEXNET_FILENAME})"
                if self.weights_sha256.startswith(IMAGENET_SHA256_PREFIX)
                else user_weights_label(self.weights_sha256)
            )
        self.eval()

    def feature_map(self, batch: torch.Tensor) -> torch.Tensor:
        """``(B, 3, H, W)`` normalised images -> conv3 + ReLU ``(B, 384, h, w)``."""
        return self.features(batch)

    def forward(self, batch: torch.Tensor) -> torch.Tensor:
        return self.features(batch).flatten(1)
