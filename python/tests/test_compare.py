"""penumbra.compare: its records are results.csv's rows."""

import csv
import math

import penumbra
from conftest import SCENES


def _same(cell: str, value) -> bool:
    """A CSV cell and a record's value agree (empty cell: None)."""
    if cell == "":
        return value is None
    if isinstance(value, bool):
        return cell == str(value).lower()
    if isinstance(value, (int, float)):
        return math.isclose(float(cell), float(value), rel_tol=0, abs_tol=0)
    return cell == value


def test_records_are_the_rows_of_results_csv(tmp_path):
    records = penumbra.compare(
        SCENES / "quad.toml",
        techniques=["shadow-volumes", "dcs", "reference"],
        samples=[4, 16],
        reference_samples=64,
        width=32,
        height=24,
        repeat=1,
        threads=2,
        out=tmp_path,
        cache_dir=tmp_path / "cache",
        images=False,
    )
    with open(tmp_path / "results.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, rows = rows[0], rows[1:]
    assert len(records) == len(rows) > 0
    for record, row in zip(records, rows):
        assert list(record) == header
        for column, cell in zip(header, row):
            assert _same(cell, record[column]), (column, cell, record[column])
    # What a researcher reads: each technique's image error at each setting.
    flip = {(r["technique"], r["samples"]) for r in records if r["quantity"] == "flip"}
    assert ("dcs", 16) in flip and ("shadow-volumes", None) in flip
    exact = [r for r in records if r["technique"] == "dcs" and r["quantity"] == "vcoef"
             and r["region"] == "all"]
    assert exact and all(r["rmse"] >= 0 for r in exact)


def test_without_out_nothing_is_written_but_the_cache(tmp_path):
    cache = tmp_path / "cache"
    records = penumbra.compare(
        [SCENES / "quad.toml"],
        techniques=["dcs"],
        samples=[4],
        reference_samples=64,
        width=16,
        height=12,
        repeat=1,
        cache_dir=cache,
    )
    assert records
    assert [p.name for p in tmp_path.iterdir()] == ["cache"]


def test_extra_settings_only_when_asked(tmp_path):
    """Each technique's default configuration only, unless
    ``sweep_settings=True`` (``--sweep-settings``) adds the others."""
    args = dict(
        techniques=["dcs"],
        samples=[4],
        reference_samples=16,
        width=16,
        height=12,
        repeat=1,
        cache_dir=tmp_path / "cache",
    )
    plain = penumbra.compare(SCENES / "quad.toml", **args)
    swept = penumbra.compare(SCENES / "quad.toml", sweep_settings=True, **args)
    assert {r["technique"] for r in plain if r["median_ms"] is not None} == {"dcs"}
    assert "dcs centre" in {r["technique"] for r in swept}


def test_bad_options_name_the_parameter():
    import pytest

    with pytest.raises(ValueError, match="reference_samples"):
        penumbra.compare(SCENES / "quad.toml", techniques=["dcs"], reference_samples=3)
    with pytest.raises(ValueError, match="technique"):
        penumbra.compare(SCENES / "quad.toml", techniques=["no-such-technique"])
