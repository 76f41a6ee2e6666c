"""Argument check shared by the landmark generators and the selection algorithms."""

from __future__ import annotations

from typing import Any


def check_count(n: Any, name: str = "n") -> int:
    """Return ``n`` as a non-negative int; raise a ValueError naming ``name`` otherwise."""
    if isinstance(n, bool) or int(n) != n or n < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {n!r}")
    return int(n)
