"""Reading weight files: a torch checkpoint that cannot be read is named, with what was expected."""

from __future__ import annotations

import os
from pathlib import Path

import torch

__all__ = ["WeightsFileError", "load_checkpoint"]


class WeightsFileError(ValueError):
    """A weights file exists but is not the checkpoint the backbone needs (unreadable or wrong)."""


def load_checkpoint(path: str | os.PathLike, expected: str) -> dict[str, torch.Tensor]:
    """``torch.load`` a state dict on CPU (``weights_only=True``), naming the file on failure.

    A ``{"state_dict": {...}}`` wrapper is unwrapped.

    Args:
        path: the checkpoint file.
        expected: what the file should hold, for the message (e.g. "a torchvision AlexNet state
            dict, e.g. alexnet-owt-7be5be79.pth").

    Returns:
        The state dict (``name -> tensor``).

    Raises:
        WeightsFileError: the file is not a torch checkpoint (not a pickle/zip, truncated, a
            different format) or does not hold a dict of tensors.
    """
    p = Path(path)
    try:
        state = torch.load(p, map_location="cpu", weights_only=True)
    except OSError:
        raise  # missing / unreadable file: the OS error already names it
    except Exception as exc:  # torch's unpickler raises anything on garbage
        # (UnpicklingError, EOFError, BadZipFile, RuntimeError, IndexError, ...)
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
    return state
