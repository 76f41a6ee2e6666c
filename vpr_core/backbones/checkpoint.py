"""Weight files: reading a torch checkpoint (errors name the file) and identity by content."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from pathlib import Path

import torch

from ..utils import file_sha256

__all__ = [
    "WeightsFileError",
    "file_sha256",
    "load_checkpoint",
    "state_dict_sha256",
    "user_weights_label",
]


class WeightsFileError(ValueError):
    """A weights file exists but is not the checkpoint the backbone needs (unreadable or wrong)."""


def state_dict_sha256(state: Mapping[str, torch.Tensor]) -> str:
    """Hex sha256 over a state dict's names, dtypes, shapes and tensor bytes (in key order)."""
    digest = hashlib.sha256()
    for name, tensor in state.items():
        t = tensor.detach().cpu().contiguous().reshape(-1)
        digest.update(f"{name}|{tensor.dtype}|{tuple(tensor.shape)}|".encode())
        digest.update(t.view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def user_weights_label(sha256: str) -> str:
    """What tables print for weights that are not a known published file."""
    return f"user weights {sha256[:12]}"


def load_checkpoint(path: str | os.PathLike, expected: str) -> dict[str, torch.Tensor]:
    """``torch.load`` a state dict on CPU (``weights_only=True``), naming the file on failure.

    Args:
        path: the checkpoint file (a ``{"state_dict": {...}}`` wrapper is unwrapped).
        expected: what the file should hold, for the message.

    Raises:
        WeightsFileError: not a torch checkpoint (truncated, other format), not a dict of
            tensors, or NaN / inf in a tensor (:func:`_nonfinite_tensors`; the message names the
            file, the tensors and the fix).
    """
    p = Path(path)
    try:
        state = torch.load(p, map_location="cpu", weights_only=True)
    except OSError:
        raise  # missing / unreadable file: the OS error already names it
    except Exception as exc:  # torch's unpickler raises anything on garbage
        raise WeightsFileError(
            f"cannot read weights file {p} ({p.stat().st_size if p.exists() else 0} bytes): "
            f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}. Expected "
            f"{expected}, saved with torch.save. The file may be truncated (an interrupted "
            "download) or a different format: download it again or point to the right file."
        ) from exc
    if isinstance(state, dict) and isinstance(state.get("state_dict"), dict):
        state = state["state_dict"]
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise WeightsFileError(
            f"weights file {p} holds a {type(state).__name__}, not a state dict of tensors; "
            f"expected {expected}."
        )
    bad = _nonfinite_tensors(state)
    if bad:
        raise WeightsFileError(
            f"weights file {p} holds NaN or inf in {', '.join(bad[:3])}"
            f"{' ...' if len(bad) > 3 else ''} ({len(bad)} tensor(s); a float64 value beyond "
            "float32's range counts: it becomes inf); every descriptor computed with it would "
            "be NaN. The file is damaged or was saved from a diverged training run: download "
            "it again, or re-create it "
            "(torch.save(model.state_dict(), path) from a model whose weights are finite)."
        )
    return state


#: Largest finite float32 value: a float64 weight beyond it becomes inf in the float32 network.
_F32_MAX = float(torch.finfo(torch.float32).max)


def _nonfinite_tensors(state: Mapping[str, torch.Tensor]) -> list[str]:
    """Names of the floating-point (or complex) tensors of ``state`` holding NaN or inf, or a
    value beyond float32's range (the backbones compute in float32: it becomes inf there)."""
    bad = []
    for name, t in state.items():
        if not (t.is_floating_point() or t.is_complex()) or t.numel() == 0:
            continue
        if not bool(t.isfinite().all()) or (
            t.dtype == torch.float64 and float(t.abs().max()) > _F32_MAX
        ):
            bad.append(name)
    return bad
