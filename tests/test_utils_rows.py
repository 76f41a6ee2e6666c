"""CSV row helpers shared by the benchmarks: ``vpr_core.utils.read_rows`` / ``write_rows``."""

from vpr_core.utils import read_rows, write_rows


def test_rows_round_trip_with_union_of_columns(tmp_path):
    path = tmp_path / "t.csv"
    assert read_rows(path) == []
    write_rows(path, [{"a": 1, "b": "x"}, {"a": 2, "c": 0.5}])
    assert read_rows(path) == [{"a": "1", "b": "x", "c": ""}, {"a": "2", "b": "", "c": "0.5"}]
    write_rows(path, [{"z": 3}])  # replaces the table, leaves no temporary file behind
    assert read_rows(path) == [{"z": "3"}]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]
