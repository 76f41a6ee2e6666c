"""compare() given arguments of the wrong kind (issue 45): one meaning per argument, and an
error that names the argument and the fix instead of a bare numpy or Python error."""

from __future__ import annotations

import re

import numpy as np
import pytest

from vpr_core import run_method
from vpr_core.evaluation import compare


@pytest.fixture(scope="module")
def runs(tiny_synthetic):
    return [
        run_method(m, tiny_synthetic, backbone="hog", n_bootstrap=20)
        for m in ("dense", "classical")
    ]


def test_baseline_true_is_refused_not_read_as_index_1(runs):
    with pytest.raises(TypeError, match=r"baseline=True is neither a label nor a position") as e:
        compare(runs, baseline=True, n_bootstrap=20)
    assert "dense, classical" in str(e.value) and "index 0 to 1" in str(e.value)
    with pytest.raises(TypeError, match="baseline=False"):
        compare(runs, baseline=False, n_bootstrap=20)
    with pytest.raises(TypeError, match=r"baseline=1\.0"):
        compare(runs, baseline=1.0, n_bootstrap=20)
    # the accepted forms still work: a label, an index (numpy's too), None
    for base in ("classical", 1, np.int64(1), -1):
        assert compare(runs, baseline=base, n_bootstrap=20)["baseline"].iloc[0] == "classical"
    assert compare(runs, n_bootstrap=20)["baseline"].iloc[1] == "dense"


def test_one_result_instead_of_a_list_says_to_pass_a_list(runs):
    one = r"results is one result \('dense'\).*compare\(\[result\]\)"
    with pytest.raises(TypeError, match=one):
        compare(runs[0])
    with pytest.raises(TypeError, match=r"pass the results as one list, compare\(\[a, b"):
        compare(runs[0], runs[1])
    with pytest.raises(TypeError, match=r"results\[1\] is a str, not a result"):
        compare([runs[0], "classical"])
    with pytest.raises(TypeError, match="must be a list of results.*got str"):
        compare("dense")
    assert list(compare([runs[0]], n_bootstrap=20).index) == ["dense"]


def test_compare_and_per_query_share_one_rule_for_what_results_are(runs):
    # check_results: one wording, the caller named, for compare, per_query (and plots)
    from vpr_core.evaluation.compare import check_results
    from vpr_core.evaluation.queries import per_query

    for fn, name in ((compare, "compare"), (per_query, "per_query")):
        with pytest.raises(ValueError, match=rf"{name}\(\) needs at least one result"):
            fn([])
        with pytest.raises(TypeError, match=rf"{name}\(\): results\[1\] is a str, not a result"):
            fn([runs[0], "classical"])
        with pytest.raises(ValueError, match=rf"{name}\(\): labels must be unique.*'dense'"):
            fn([runs[0], runs[0]])
    assert check_results(iter(runs), "plot") == runs  # any iterable of results
    assert check_results([runs[0], runs[0]], "plot") == [runs[0], runs[0]]  # labels not asked
    with pytest.raises(TypeError, match=r"plot\(\): results is one result \('dense'\)"):
        check_results(runs[0], "plot")


@pytest.mark.parametrize("seed", ["x", 1.5, -1, True, None])
def test_a_bad_seed_names_seed(runs, seed):
    # checks.check_int's one wording
    got = re.escape(repr(seed))
    want = rf"compare\(\): seed \(of the resampling\) must be a non-negative integer, got {got}"
    with pytest.raises(ValueError, match=want):
        compare(runs, seed=seed, n_bootstrap=20)
    with pytest.raises(ValueError, match=r"n_bootstrap \(resamples; 0: no intervals\) must be"):
        compare(runs, n_bootstrap=1.5)


def test_the_verdict_column_uses_the_three_words(runs):
    table = compare(runs, n_bootstrap=20)
    for name in ("dAUC", "dR@1", "dR@100P"):
        verdict = table[f"{name} verdict"].iloc[1]
        lo, hi = table[f"{name} lo"].iloc[1], table[f"{name} hi"].iloc[1]
        want = "higher" if lo > 0 else "lower" if hi < 0 else "inconclusive"
        assert verdict == want, (name, lo, hi, verdict)
    assert compare(runs, n_bootstrap=0)["dAUC verdict"].iloc[1] == "not computed"
