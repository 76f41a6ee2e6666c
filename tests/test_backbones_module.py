"""vpr_core.backbones.module: a user's module is checked on the batches it really sees (a few
crops of real batches, at their positions, against the same crops alone) and an output that
requires grad is refused in a sentence naming the module and the fix."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from vpr_core.features import LandmarkEncoder


class Pooled(nn.Module):
    """An honest module: a 1x1 convolution and a global average, per crop."""

    def __init__(self) -> None:
        super().__init__()
        torch.manual_seed(0)
        self.conv = nn.Conv2d(3, 8, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.conv(x).mean((2, 3))


class MeanOnLargeBatches(Pooled):
    """Subtracts the batch mean, only on batches of more than 2 crops (the probe has 2)."""

    def forward(self, x):
        out = super().forward(x)
        return out - out.mean(0, keepdim=True) if len(x) > 2 else out


class PositionTerm(Pooled):
    """Adds a term that grows with a crop's position in the batch (0 at the first)."""

    def forward(self, x):
        return super().forward(x) + 0.1 * torch.arange(len(x), dtype=x.dtype)[:, None]


class ReversedOnLargeBatches(Pooled):
    """Returns the rows of batches of more than 2 crops in reverse order."""

    def forward(self, x):
        out = super().forward(x)
        return out.flip(0) if len(x) > 2 else out


class EnablesGrad(Pooled):
    """Turns autograd back on inside its forward."""

    def forward(self, x):
        with torch.inference_mode(False), torch.enable_grad():
            return self.conv(x.clone()).mean((2, 3))


def _street(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    image = (rng.random((64, 96, 3)) * 255).astype(np.uint8)
    boxes = np.array([[x, y, 24.0, 20.0] for x in (0, 30, 60) for y in (0, 30)])
    return image, boxes


def test_an_honest_module_passes_on_real_batches():
    image, boxes = _street()
    enc = LandmarkEncoder(Pooled(), input_size=16, dim=None, batch_size=4)
    for _ in range(4):  # batches 1..8 (checked: 1, 2, 4, 8)
        assert np.isfinite(enc.encode(image, boxes)).all()


@pytest.mark.parametrize("module", [MeanOnLargeBatches, PositionTerm, ReversedOnLargeBatches])
def test_a_module_that_depends_on_its_real_batch_is_refused(module):
    image, boxes = _street()
    enc = LandmarkEncoder(module(), input_size=16, dim=None)  # the probe passes (2 crops)
    with pytest.raises(
        ValueError,
        match=rf"^backbone module {module.__name__} returns other features for crop \d+ of a "
        r"real batch of 50 crops than for the same crop alone .*must not depend on the batch",
    ):
        enc.encode(image, boxes)


def test_a_module_seen_late_is_checked_on_later_batches():
    """A module that reverses its batches after the first real one: batch 2 is checked."""

    class LateReversal(Pooled):
        calls = 0

        def forward(self, x):
            LateReversal.calls += len(x) > 1
            out = super().forward(x)
            return out.flip(0) if LateReversal.calls > 2 else out  # the probe, then batch 1

    image, boxes = _street()
    boxes = np.concatenate([boxes, boxes[:2] + 1.0])  # 8 crops: two full batches of 4
    enc = LandmarkEncoder(LateReversal(), input_size=16, dim=None, batch_size=4)
    with pytest.raises(ValueError, match=r"real batch 2 \(its forward\)"):
        enc.encode(image, boxes)


@pytest.mark.parametrize("pooling", ["crop", "roi"])
def test_a_module_whose_output_requires_grad_gets_a_sentence(pooling):
    class Spatial(EnablesGrad):
        stride = 1

        def forward(self, x):
            with torch.inference_mode(False), torch.enable_grad():
                return self.conv(x.clone())

    module = EnablesGrad() if pooling == "crop" else Spatial()
    with pytest.raises(
        ValueError,
        match=rf"^backbone module {type(module).__name__} returns a tensor that requires grad "
        r".*torch.inference_mode\(\).*return out.detach\(\)$",
    ):
        LandmarkEncoder(module, input_size=16, dim=None, pooling=pooling)
