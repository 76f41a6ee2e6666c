"""Small shared helpers: logging, seeding, cache locations, config slugs, progress bars."""

from __future__ import annotations

import hashlib
import json
import logging
import os
import random
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

logger = logging.getLogger("vpr_core")
if not logger.handlers:
    _h = logging.StreamHandler()
    _h.setFormatter(logging.Formatter("[vpr_core %(levelname)s] %(message)s"))
    logger.addHandler(_h)
    logger.setLevel(logging.INFO)
    logger.propagate = False

PACKAGE_DIR = Path(__file__).resolve().parent
REPO_DIR = PACKAGE_DIR.parent


def make_deterministic(seed: int = 0) -> None:
    """Seed python, numpy and torch and ask torch for deterministic kernels."""
    random.seed(seed)
    np.random.seed(seed)
    try:
        import torch

        torch.manual_seed(seed)
        torch.use_deterministic_algorithms(True, warn_only=True)
    except ImportError:  # pragma: no cover - torch is a hard dependency
        pass


def cache_root() -> Path:
    """Root folder of on-disk caches (datasets, landmarks, features, results).

    ``$VPR_CACHE_DIR`` if set, else ``<repo>/.cache`` when running from a source checkout,
    else ``~/.cache/vpr-landmarks``.
    """
    env = os.environ.get("VPR_CACHE_DIR")
    if env:
        root = Path(env).expanduser()
    elif (REPO_DIR / "pyproject.toml").exists():
        root = REPO_DIR / ".cache"
    else:
        root = Path.home() / ".cache" / "vpr-landmarks"
    root.mkdir(parents=True, exist_ok=True)
    return root


def cache_dir(*parts: str) -> Path:
    """``cache_root()/parts...``, created."""
    p = cache_root().joinpath(*parts)
    p.mkdir(parents=True, exist_ok=True)
    return p


def short_hash(obj: Any, n: int = 10) -> str:
    """Stable short hex hash of a JSON-serialisable object (dict keys sorted)."""
    blob = json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha1(blob).hexdigest()[:n]


def config_slug(name: str, conf: Mapping[str, Any]) -> str:
    """Readable slug + short hash for a named config, used in cache and figure names."""
    safe = "".join(c if c.isalnum() or c in "-_." else "-" for c in str(name))
    return f"{safe}-{short_hash(dict(conf))}"


def progress(iterable: Iterable, **kwargs: Any):
    """``tqdm.auto`` progress bar (disabled by ``TQDM_DISABLE=1``)."""
    from tqdm.auto import tqdm

    kwargs.setdefault("disable", bool(os.environ.get("TQDM_DISABLE")))
    kwargs.setdefault("leave", False)
    return tqdm(iterable, **kwargs)


def file_fingerprint(path: str | os.PathLike) -> str:
    """Content hash (sha1, 16 hex) of a file, for cache keys that survive moves and touch."""
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]
