"""vpr_core.executor: what an ``executor=`` returns is checked before any cache keeps it (shape,
dtype, finite, width, count, timings, a sample recomputed in-process); every refusal names the
executor and the fix, and a refused run leaves nothing that changes a later in-process run."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import torch

from vpr_core import run_method
from vpr_core.datasets import load_dataset
from vpr_core.features import LandmarkEncoder
from vpr_core.matching import similarity_matrix, similarity_pairs

#: Fast settings: HOG descriptors of 9 dense landmarks per image.
FAST = {
    "backbone": "hog",
    "dim": 32,
    "batch_size": 9,
    "scales": (0.25,),
    "per_scale": 9,
    "n_bootstrap": 0,
}


class InProcess:
    """An honest executor: the in-process computations, returned as an executor would (the
    descriptors memoised between tests: they are the tests' main cost)."""

    memo: dict = {}

    def encode(self, dataset, side, encoder_kwargs, indices, boxes):
        enc = LandmarkEncoder(**encoder_kwargs)
        descs = []
        for i, b in zip(indices, boxes, strict=True):
            key = (dataset.image_key(side, i), np.asarray(b).tobytes())
            if key not in self.memo:
                self.memo[key] = enc.encode(dataset.load_image(side, i), b)
            descs.append(self.memo[key].copy())
        return descs, [0.01] * len(indices)

    def similarity_matrix(self, qd, qb, rd, rb, matching):
        return similarity_matrix(qd, qb, rd, rb, matching=matching)

    def similarity_pairs(self, qd, qb, rd, rb, pairs, matching):
        return similarity_pairs(qd, qb, rd, rb, pairs, matching)

    def __repr__(self) -> str:
        return "Hostile()"


def _descs(change):
    def encode(self, dataset, side, kwargs, indices, boxes):
        descs, secs = InProcess.encode(self, dataset, side, kwargs, indices, boxes)
        return change(descs, secs)

    return encode


def _matrix(change):
    def matrix(self, qd, qb, rd, rb, matching):
        return change(InProcess.similarity_matrix(self, qd, qb, rd, rb, matching))

    return matrix


def _pairs(change):
    def pairs(self, qd, qb, rd, rb, pairs, matching):
        return change(InProcess.similarity_pairs(self, qd, qb, rd, rb, pairs, matching))

    return pairs


def _nan_first(d):
    d = [x.copy() for x in d]
    d[0][0, 0] = np.nan
    return d


def _drop_row(d):
    return [x[:-1] for x in d]


def _with_inf(s):
    s = s.copy()
    s[0, 1] = np.inf
    return s


_RNG = np.random.default_rng(1)


def _random(d):
    return [_RNG.random(x.shape) for x in d]


def _torch(d):
    return [torch.from_numpy(x) for x in d]


#: (what it returns wrong, which method, the change, the words of the refusal)
HOSTILE = [
    ("transposed matrix", "similarity_matrix", _matrix(lambda s: s.T.copy()), "differs"),
    ("negated scores", "similarity_matrix", _matrix(lambda s: -s), "differs"),
    ("another dataset", "similarity_matrix", _matrix(lambda s: _RNG.random(s.shape)), "differs"),
    ("integer matrix", "similarity_matrix", _matrix(lambda s: (s * 100).astype(int)), "dtype"),
    ("inf entry", "similarity_matrix", _matrix(_with_inf), "NaN or inf"),
    ("strings", "similarity_matrix", _matrix(lambda s: s.astype(str)), "dtype"),
    ("torch tensor", "similarity_matrix", _matrix(torch.from_numpy), "not a numpy array"),
    ("a row short", "similarity_matrix", _matrix(lambda s: s[:-1]), "shape"),
    ("reversed pairs", "similarity_pairs", _pairs(lambda v: v[::-1].copy()), "differs"),
    ("pairs as a list", "similarity_pairs", _pairs(list), "not a numpy array"),
    ("random descriptors", "encode", _descs(lambda d, s: (_random(d), s)), "differs"),
    ("torch descriptors", "encode", _descs(lambda d, s: (_torch(d), s)), "not a numpy array"),
    ("NaN descriptors", "encode", _descs(lambda d, s: (_nan_first(d), s)), "NaN or inf"),
    ("K-1 rows", "encode", _descs(lambda d, s: (_drop_row(d), s)), "shape"),
    ("one image too few", "encode", _descs(lambda d, s: (d[:-1], s)), "descriptors of"),
    ("1-d rows", "encode", _descs(lambda d, s: ([x[0] for x in d], s)), "shape"),
    ("string descriptors", "encode", _descs(lambda d, s: (["abc"] * len(d), s)), "str"),
    ("negative timings", "encode", _descs(lambda d, s: (d, [-1.0] * len(s))), "finite number >= 0"),
    ("NaN timings", "encode", _descs(lambda d, s: (d, [np.nan] * len(s))), "finite number >= 0"),
    ("no tuple", "encode", _descs(lambda d, s: d), "not \\(descriptors, seconds\\)"),
]  # fmt: skip


@pytest.fixture(scope="module")
def five():
    return load_dataset("synthetic", n_places=5, image_size=(64, 112))


@pytest.fixture(scope="module")
def fresh(five, tmp_path_factory):
    """The in-process similarity of both paths on an empty cache of their own, and that cache."""
    cache = tmp_path_factory.mktemp("fresh")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("VPR_CACHE_DIR", str(cache))
        sims = {k: run_method("dense", five, shortlist=k, **FAST).similarity for k in (None, 3)}
    return sims, cache


@pytest.fixture()
def isolated_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_an_honest_executor_passes_and_equals_in_process(five, fresh, isolated_cache):
    for k in (None, 3):
        res = run_method("dense", five, shortlist=k, executor=InProcess(), **FAST)
        np.testing.assert_array_equal(res.similarity, fresh[0][k])


@pytest.mark.parametrize(
    ("what", "method", "change", "words"), HOSTILE, ids=[h[0] for h in HOSTILE]
)
def test_what_an_executor_returns_is_checked_before_the_cache_keeps_it(
    five, fresh, isolated_cache, what, method, change, words
):
    hostile = type("Hostile", (InProcess,), {method: change})()
    k = 3 if method == "similarity_pairs" else None
    sims, warm = fresh
    if method != "encode":  # the features in the cache already: the executor scores pairs
        shutil.copytree(warm / "features", isolated_cache / "features")
    with pytest.raises(ValueError, match=rf"^executor=Hostile\(\): .*{words}.*executor=None"):
        run_method("dense", five, shortlist=k, executor=hostile, **FAST)
    # nothing it returned was kept: a later in-process run gives a fresh cache's numbers
    again = run_method("dense", five, shortlist=k, **FAST)
    np.testing.assert_array_equal(again.similarity, sims[k])


@pytest.mark.parametrize(
    "value",
    ["tcp://127.0.0.1:8786", object(), InProcess.similarity_matrix],
    ids=["an address", "an object", "a function"],
)
def test_a_value_that_is_no_executor_is_refused_before_any_work(five, isolated_cache, value):
    with pytest.raises(ValueError, match=r"executor=.* without callable .*executor=None"):
        run_method("dense", five, executor=value, **FAST)
    assert not isolated_cache.exists() or not any(isolated_cache.rglob("*.npz"))


def test_a_weighted_matrix_is_spot_checked_with_its_statistics_over_every_reference(
    five, isolated_cache
):
    plain = run_method("dense", five, weighting="contrast", **FAST)
    res = run_method("dense", five, weighting="contrast", executor=InProcess(), **FAST)
    np.testing.assert_allclose(res.similarity, plain.similarity, rtol=0, atol=1e-12)
