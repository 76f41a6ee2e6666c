"""``vpr_core.utils``: CSV row helpers shared by the benchmarks, and the module's bad inputs."""

import pytest

from vpr_core.utils import code_version, configure_logging
from vpr_study.outputs import MAX_LABEL_BYTES, MAX_NAME_BYTES, check_label, check_name
from vpr_study.rows import read_rows, write_rows


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
    "long label": (
        lambda: check_label("\u00e9" * MAX_LABEL_BYTES),
        ValueError,
        rf"label '\u00e9{{20}}\.\.\.' is {2 * MAX_LABEL_BYTES} bytes long; give a label of "
        rf"at most {MAX_LABEL_BYTES} \(it names folders",
    ),
    "long name": (
        lambda: check_name("n" * (MAX_NAME_BYTES + 1)),
        ValueError,
        rf"name 'n{{20}}\.\.\.' is {MAX_NAME_BYTES + 1} bytes long; give a name of at most "
        rf"{MAX_NAME_BYTES} \(the file system",
    ),
    "stage": (
        lambda: code_version("plots"),
        ValueError,
        "unknown stage 'plots'; valid: landmarks, features, matching",
    ),
}


@pytest.mark.parametrize("case", BAD_UTILS_CALLS)
def test_bad_utils_inputs_raise_one_clear_line(case):
    call, exc, match = BAD_UTILS_CALLS[case]
    with pytest.raises(exc, match=match) as info:
        call()
    assert "\n" not in str(info.value)


def test_a_label_and_a_name_at_their_byte_limit_pass():
    assert check_label("a" * MAX_LABEL_BYTES) == "a" * MAX_LABEL_BYTES
    assert check_name("n" * MAX_NAME_BYTES) == "n" * MAX_NAME_BYTES
