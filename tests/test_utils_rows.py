"""``vpr_core.utils``: CSV row helpers shared by the benchmarks, and the module's bad inputs."""

import pytest

from vpr_core.utils import code_version, configure_logging, read_rows, write_rows


def test_rows_round_trip_with_union_of_columns(tmp_path):
    path = tmp_path / "t.csv"
    assert read_rows(path) == []
    write_rows(path, [{"a": 1, "b": "x"}, {"a": 2, "c": 0.5}])
    assert read_rows(path) == [{"a": "1", "b": "x", "c": ""}, {"a": "2", "b": "", "c": "0.5"}]
    write_rows(path, [{"z": 3}])  # replaces the table, leaves no temporary file behind
    assert read_rows(path) == [{"z": "3"}]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]


#: id -> (call, exception, message)
BAD_UTILS_CALLS = {
    "logging stream": (
        lambda: configure_logging(stream="file"),
        ValueError,
        "unknown configure_logging stream 'file'; valid: stderr, stdout",
    ),
    "stage": (
        lambda: code_version("plots"),
        KeyError,
        "unknown stage 'plots'; stages: landmarks, features, matching",
    ),
}


@pytest.mark.parametrize("case", BAD_UTILS_CALLS)
def test_bad_utils_inputs_raise_one_clear_line(case):
    call, exc, match = BAD_UTILS_CALLS[case]
    with pytest.raises(exc, match=match) as info:
        call()
    assert "\n" not in str(info.value)
