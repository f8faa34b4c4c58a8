"""compare/site/stability_outcomes.py: a framework's outcome in a stress experiment from its rows
and the other frameworks' rows of the same cases (fast tier); the pages that show it:
tests/site/test_pages_stability.py."""
from __future__ import annotations

import pytest

from compare.site import stability_outcomes as so


@pytest.mark.parametrize("rows,kind", [
    ([("a", "ok"), ("b", "ok")], so.PASS),
    ([("a", "EXCEEDS derived bound"), ("b", "EXCEEDS derived bound")], so.WITH_ALL),
    ([("a", "EXCEEDS derived bound"), ("b", "ok"), ("c", "ok")], so.ALONE),
    ([("a", "EXCEEDS derived bound"), ("b", "EXCEEDS derived bound"), ("c", "ok")], so.WITH_SOME),
    ([("a", "EXCEEDS derived bound")], so.ALONE),
    ([("a", "error")], so.ERROR),
    ([("a", "skipped")], so.SKIPPED),
])
def test_a_failing_row_is_shared_by_all_some_or_none_of_the_frameworks_of_its_case(rows, kind):
    names = dict(zip("abc", ("warp", "jax", "numba")))
    found = [{"experiment": "x", "backend": names[b], "device": "cuda", "precision": "float32", "setting": "s",
              "figure": "f", "value": 1.0, "verdict": v, "detail": ""} for b, v in rows]
    assert so.outcomes(found)[("warp", "x")].kind == kind


def test_a_racy_control_passes_when_caught_and_fails_when_missed():
    row = {"experiment": "races", "backend": "warp", "device": "cuda", "precision": "float32", "setting": "s",
           "figure": "elements differing between two runs", "value": 3, "detail": "control: racy"}
    assert not so.failing({**row, "verdict": "RACE DETECTED (runs differ)"})
    assert so.failing({**row, "value": 0, "verdict": "MISSED: race not flagged"})
    assert not so.failing({**row, "device": "cpu", "value": 0, "verdict": "race not observable on CPU"})


def test_frameworks_that_gave_the_same_finding_share_a_line():
    row = {"experiment": "x", "device": "cuda", "precision": "float32", "setting": "s", "figure": "f",
           "value": 0.5, "verdict": "ok", "detail": "d"}
    rows = [{**row, "backend": "warp"}, {**row, "backend": "jax"}, {**row, "backend": "numba", "value": 0.25}]
    assert [line[0] for line in so.collapsed(rows)] == ["warp, jax", "numba"]
