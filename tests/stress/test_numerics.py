"""compare/stress/numerics.py: a finding (``Row``) and its stored form, the check block of a
cell that ran."""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from compare.results.record import Record
from compare.results.store import jsonable
from compare.stress import numerics
from compare.stress.numerics import COLUMNS, Finding, Row

# the columns of stress.json's analysis.rows, in the order every stored file has them
STORED = ("experiment", "backend", "device", "precision", "setting", "figure", "value", "verdict", "detail")


def test_the_columns_are_the_row_fields_and_the_stored_keys_in_their_order():
    assert COLUMNS == STORED
    assert tuple(Finding.__annotations__) == STORED


@pytest.mark.parametrize("value", [1.5, 3, None, "n/a", True, math.inf, math.nan])
def test_a_row_stores_as_the_dict_the_file_always_had(value):
    """Same keys, same order, same values: the JSON text is that of the old dict rows."""
    values = ("particles-dt", "numpy", "cpu", "float32", "dt=0.02", "max error", value, "ok", "why")
    row = Row(*values)
    got = row.to_json()
    assert list(got) == list(STORED)
    old = dict(zip(STORED, values))
    assert json.dumps(jsonable(got)) == json.dumps(jsonable(old))
    assert Row(**got) == row or (isinstance(value, float) and math.isnan(value))   # nan != nan


def test_a_row_is_immutable_and_has_an_empty_detail_by_default():
    row = Row("races", "numba", "cpu", "float32", "saxpy", "differing", 0, "bitwise reproducible")
    assert row.detail == "" and row.to_json()["detail"] == ""
    with pytest.raises(dataclasses.FrozenInstanceError):
        row.verdict = "other"      # type: ignore[misc]


def test_check_of_gives_the_check_block_and_names_a_record_without_one():
    ran = Record("saxpy", "numpy", "cpu", "float32", "ok", error={"vs_oracle": 0.25, "tolerance": 1.0})
    assert numerics.check_of(ran).vs_oracle == 0.25 and numerics.check_of(ran).tolerance == 1.0
    crashed = Record("saxpy", "numba", "cpu", "float32", "error", reason="boom")
    with pytest.raises(ValueError, match="numba/cpu saxpy"):
        numerics.check_of(crashed)


def test_log_floor_keeps_zeros_visible_and_non_numbers_as_nan():
    got = numerics.log_floor([0.0, 2.0, None, math.inf, np.float64(1e-30)], eps=1e-18)
    assert got[:2] == [1e-18, 2.0] and math.isnan(got[2]) and math.isnan(got[3]) and got[4] == 1e-18


def _outputs(seed=0):
    rng = np.random.default_rng(seed)
    return {k: rng.standard_normal(100).astype(np.float32) for k in ("x", "y", "vx", "vy")}


def test_bitwise_differences_counts_elements_and_treats_equal_nans_as_equal():
    a = _outputs()
    b = {k: v.copy() for k, v in a.items()}
    assert numerics.bitwise_differences(a, b) == 0
    a["x"][3] = b["x"][3] = np.nan
    assert numerics.bitwise_differences(a, b) == 0
    b["y"][7] = np.nextafter(b["y"][7], np.float32(np.inf))      # one ulp
    b["vx"][0] = -b["vx"][0]
    assert numerics.bitwise_differences(a, b) == 2
    assert numerics.bitwise_differences({"z": np.float32([0.0])}, {"z": np.float32([-0.0])}) == 1
    assert numerics.bitwise_differences(a, {**b, "extra": b["x"]}) == -1
    assert numerics.bitwise_differences({"x": a["x"]}, {"x": a["x"][:5]}) == -1


def test_ulps_of_correctly_rounded_results_are_at_most_half():
    ref = np.random.default_rng(1).standard_normal(1000)
    assert np.max(numerics.ulps(ref.astype(np.float32), ref)) <= 0.5
    assert numerics.ulps(np.float32([1.0 + 2 ** -23]), np.array([1.0]))[0] == 1.0


def test_a_row_and_its_stored_form_list_the_same_columns_in_order():
    """numerics.Row (the row an experiment makes) and results.analysis.Finding (its form in
    stress.json, which the pages read) are one row in two places: their columns must agree."""
    from compare.results.analysis import Finding
    from compare.stress.numerics import COLUMNS, Row
    assert tuple(Finding.__annotations__) == COLUMNS
    row = Row("ulps", "numpy", "cpu", "float32", "n=1", "max ulp", 1, "ok")
    assert list(row.to_json()) == list(COLUMNS) and row.to_json()["detail"] == ""
