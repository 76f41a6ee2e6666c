"""Cache keys from content (issue 31): an edited scheme, a changed global, a backbone module whose
``forward`` reads a changed global, or weights overwritten in place never return old numbers:
after each change the numbers equal a run on an empty cache and differ from the first run."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from vpr_core import run_method, settings
from vpr_core.backbones.efficientnet_lite import load_state_dict
from vpr_core.datasets import load_dataset

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def ds():
    return load_dataset("synthetic", n_places=4, image_size=(64, 112))


@pytest.fixture()
def caches(tmp_path, monkeypatch):
    """``use(name)`` points ``VPR_CACHE_DIR`` at ``tmp_path/name`` (a new name: an empty cache)."""

    def use(name: str) -> Path:
        path = tmp_path / name
        monkeypatch.setenv("VPR_CACHE_DIR", str(path))
        return path

    use("cache")
    return use


def _sim(method, ds, **kw) -> np.ndarray:
    kw.setdefault("backbone", "hog")
    return run_method(method, ds, n_bootstrap=0, **kw).similarity


def _same_as_fresh_and_new(first, second, fresh) -> None:
    np.testing.assert_array_equal(second, fresh)
    assert not np.array_equal(first, second)


# ------------------------------------------------------------------------- a user's landmark scheme
CELL = """
import dataclasses
import numpy as np

SHIFT = 0.0

def helper(w):
    return w / 4

@dataclasses.dataclass(frozen=True)
class Rows:
    ROWS = {rows}
    g: int = 2

    def boxes(self, image):
        h, w = image.shape[:2]
        return np.array(
            [[SHIFT + helper(w) * (r % 2), h * r / (2 * self.ROWS), w / 2, h / 3]
             for r in range(self.ROWS)]
        )
"""


def _cell(rows: int, ns: dict | None = None) -> dict:
    """Run the notebook cell (a fresh namespace, or ``ns`` again: the cell re-run)."""
    ns = {"__name__": "__main__"} if ns is None else ns
    exec(textwrap.dedent(CELL.format(rows=rows)), ns)
    return ns


def test_an_edited_class_constant_gives_the_new_numbers(ds, caches):
    ns = _cell(8)
    first = _sim(ns["Rows"](), ds)
    _cell(6, ns)  # the cell edited (8 boxes per row -> 6) and run again
    second = run_method(ns["Rows"](), ds, backbone="hog", n_bootstrap=0)
    assert {len(b) for b in second.boxes["query"]} == {6}
    caches("empty")
    _same_as_fresh_and_new(first, second.similarity, _sim(ns["Rows"](), ds))


@pytest.mark.parametrize(
    "change",
    [
        lambda ns: ns.__setitem__("SHIFT", 7.0),  # a module global the scheme reads
        lambda ns: ns.__setitem__("helper", lambda w: w / 3),  # a helper it calls
    ],
    ids=["global", "helper"],
)
def test_a_changed_global_or_helper_gives_new_boxes(ds, caches, change):
    ns = _cell(4)
    first = run_method(ns["Rows"](), ds, backbone="hog", n_bootstrap=0)
    change(ns)
    second = run_method(ns["Rows"](), ds, backbone="hog", n_bootstrap=0)
    assert not np.array_equal(first.boxes["query"][0], second.boxes["query"][0])
    caches("empty")
    _same_as_fresh_and_new(first.similarity, second.similarity, _sim(ns["Rows"](), ds))


def test_a_user_scheme_is_stored_only_with_a_declared_version(ds, caches):
    ns = _cell(4)
    calls = []
    cls = ns["Rows"]
    plain = cls.boxes

    def counted(self, image):
        calls.append(1)
        return plain(self, image)

    cls.boxes = counted
    cache = caches("plain")
    _sim(cls(), ds)
    _sim(cls(), ds)
    assert len(calls) == 16  # recomputed on every run (4 + 4 images, twice)
    assert not (cache / "landmarks").exists()
    cls.version = "1"  # the user's promise: same version, same boxes
    cache = caches("versioned")
    _sim(cls(), ds)
    _sim(cls(), ds)
    assert len(calls) == 24  # computed once, then read from disk
    assert len(list((cache / "landmarks").iterdir())) == 1


# ------------------------------------------------------------------------- a user's backbone module
GAIN = 1.0


class GlobalNet(nn.Module):
    """A user backbone whose ``forward`` reads the module global ``GAIN``."""

    def __init__(self) -> None:
        super().__init__()
        self.conv = nn.Conv2d(3, 4, 3, stride=4, padding=1)
        g = torch.Generator().manual_seed(0)
        with torch.no_grad():
            self.conv.weight.copy_(torch.randn(self.conv.weight.shape, generator=g) * 0.2)
            self.conv.bias.copy_(torch.randn(self.conv.bias.shape, generator=g) * 0.1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.conv(x)) ** GAIN


def test_a_module_forward_reading_a_changed_global_is_a_new_encoder(ds, caches, monkeypatch):
    net = GlobalNet()
    kw = {"backbone": net, "input_size": 32, "dim": 16}
    first = _sim("dense", ds, scales=(0.25,), per_scale=4, **kw)
    monkeypatch.setattr(sys.modules[__name__], "GAIN", 2.0)
    second = _sim("dense", ds, scales=(0.25,), per_scale=4, **kw)
    caches("empty")
    _same_as_fresh_and_new(first, second, _sim("dense", ds, scales=(0.25,), per_scale=4, **kw))


# ---------------------------------------------------------------- weights overwritten in place
def _save_lite0(path: Path, seed: int) -> None:
    """The shipped Lite0 state dict, conv weights scaled by 1 + 5% noise (same size each seed)."""
    g = torch.Generator().manual_seed(seed)
    state = {
        k: v * (1 + 0.05 * torch.randn(v.shape, generator=g)) if "conv" in k else v
        for k, v in load_state_dict(variant="lite0").items()
    }
    torch.save(state, path)


LITE = {"backbone": "efficientnet_lite0", "input_size": 64, "dim": 32}
DENSE = {"scales": (0.25,), "per_scale": 4, **LITE}
SCRIPT = """
import os, sys
import numpy as np
from test_cache_identity import DENSE, _overwrite_keeping_stamp
from vpr_core.datasets import load_dataset
from vpr_core import run_method
weights, out = sys.argv[1], sys.argv[2]
ds = load_dataset("synthetic", n_places=4, image_size=(64, 112))
for i, step in enumerate(sys.argv[3:]):
    if step == "overwrite":
        _overwrite_keeping_stamp(weights, 1)
    else:
        r = run_method("dense", ds, n_bootstrap=0, weights=weights, **DENSE)
        np.save(f"{out}-{i}.npy", r.similarity)
"""


def _overwrite_keeping_stamp(path: str | Path, seed: int) -> None:
    path = Path(path)
    st = path.stat()
    _save_lite0(path, seed)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (path.stat().st_size, path.stat().st_mtime_ns) == (st.st_size, st.st_mtime_ns)


def test_weights_overwritten_with_the_same_size_and_mtime_give_new_numbers(
    ds, caches, tmp_path, monkeypatch
):
    monkeypatch.delenv(settings.efficientnet_weights_env("lite0"), raising=False)
    weights = tmp_path / "w.pth"
    _save_lite0(weights, 0)
    first = _sim("dense", ds, weights=str(weights), **DENSE)
    _overwrite_keeping_stamp(weights, 1)
    second = run_method("dense", ds, n_bootstrap=0, weights=str(weights), **DENSE)
    caches("empty")
    fresh = run_method("dense", ds, n_bootstrap=0, weights=str(weights), **DENSE)
    _same_as_fresh_and_new(first, second.similarity, fresh.similarity)
    assert second.weights_sha256 == fresh.weights_sha256


def test_weights_overwritten_in_place_across_processes(ds, caches, tmp_path, monkeypatch):
    """One process runs, overwrites the file (same size and mtime) and runs again; a second
    process on the same cache then reads no old-weight features."""
    monkeypatch.delenv(settings.efficientnet_weights_env("lite0"), raising=False)
    cache = caches("cache")
    weights, script = tmp_path / "w.pth", tmp_path / "run.py"
    script.write_text(SCRIPT)
    _save_lite0(weights, 0)
    env = {**os.environ, "PYTHONPATH": f"{REPO}:{REPO / 'tests'}"}

    def run(out: str, *steps: str, cache: Path = cache) -> list[np.ndarray]:
        args = [sys.executable, str(script), str(weights), str(tmp_path / out), *steps]
        subprocess.run(args, env={**env, "VPR_CACHE_DIR": str(cache)}, check=True)
        return [np.load(p) for p in sorted(tmp_path.glob(f"{out}-*.npy"))]

    first, second = run("one", "run", "overwrite", "run")
    (third,) = run("two", "run")
    # the oracle is a fresh process on an empty cache too: a test process's torch state (its
    # thread count, what earlier tests in it set) may change the last bits of its descriptors
    (fresh,) = run("fresh", "run", cache=caches("empty"))
    _same_as_fresh_and_new(first, second, fresh)
    np.testing.assert_array_equal(third, fresh)


# ------------------------------------------------------------------------- the matching cache
def test_the_results_cache_is_keyed_by_its_inputs(ds, caches, monkeypatch):
    """Descriptors that changed under the same configuration give a new matrix."""
    from vpr_core import run as run_module

    first = _sim("dense", ds, scales=(0.25,), per_scale=4)
    real = run_module.extract_features

    def doubled(*args, **kwargs):
        out = real(*args, **kwargs)
        for side in ("query", "reference"):
            out[side] = [np.sqrt(np.abs(d)) for d in out[side]]
        return out

    monkeypatch.setattr(run_module, "extract_features", doubled)
    second = _sim("dense", ds, scales=(0.25,), per_scale=4)
    caches("empty")
    _same_as_fresh_and_new(first, second, _sim("dense", ds, scales=(0.25,), per_scale=4))
