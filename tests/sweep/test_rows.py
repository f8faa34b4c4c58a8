"""A sweep record's tags read back (compare/sweep/rows.py): the knob the suite stored, typed."""
from __future__ import annotations

import pytest

from compare.results.record import Record
from compare.sweep.points import Knob
from compare.sweep.rows import knob, knob_value, ok, tag


def _rec(knob_json, status="ok", sweep="scaling"):
    return Record(scenario="particles", backend="numpy", device="cpu", precision="float32", status=status,
                  tags={"sweep": sweep, "role": "particles", "knob": knob_json},
                  time={"first_call_s": 1.0, "median_s": 1.0, "iqr_s": 0.0, "min_s": 1.0, "repeats": 1})


def test_the_stored_knob_reads_back_as_the_knob_the_suite_stored():
    for k in (Knob("n", 4096), Knob("dt", 0.0125), Knob("precision")):
        assert knob(_rec(k.to_json())) == k
    assert knob(_rec({})) == Knob("") and knob(Record(scenario="sdf", backend="numpy", device="cpu",
                                                      precision="float32", status="ok")) == Knob("")


def test_knob_value_is_the_stored_number_or_a_named_error():
    assert knob_value(_rec({"name": "n", "value": 4096})) == 4096
    assert isinstance(knob_value(_rec({"name": "n", "value": 4096})), int)     # tables show it as stored
    with pytest.raises(TypeError, match="numeric knob value"):
        knob_value(_rec({"name": "precision", "value": None}))


def test_ok_filters_by_tags_and_fields():
    recs = [_rec({}), _rec({}, status="error"), _rec({}, sweep="horizon")]
    assert ok(recs, sweep="scaling") == [recs[0]] and ok(recs, role="particles", backend="numpy") == [recs[0], recs[2]]
    assert tag(recs[2], "sweep") == "horizon" and tag(recs[2], "absent") is None
