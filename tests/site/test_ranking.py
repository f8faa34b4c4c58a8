"""compare/site/ranking.py: the separation rule on bare figures (fast tier).

The matrix rows that apply it to records are tested in tests/site/test_matrix.py.
"""
from __future__ import annotations

from typing import NamedTuple

import pytest

from compare.site import ranking


class F(NamedTuple):
    framework: str
    value: float | None
    ci: tuple[float, float] | None = None
    processes: int = 1


def test_separation_rule_constants():
    assert (ranking.SEPARATED_GAP, ranking.ONE_PROCESS_GAP) == (1.05, 1.6)


def test_gap_is_a_ratio_of_at_least_one():
    assert ranking.gap(2.0, 1.0) == ranking.gap(1.0, 2.0) == 2.0


def test_a_separated_pair_names_a_best():
    a, b = F("warp", 10.0, (9.9, 10.1)), F("cupy", 11.0, (10.8, 11.2))
    s = ranking.separated(a, b)
    assert s.apart and s.kind == ranking.INTERVALS and s.gap == pytest.approx(1.1)
    assert ranking.tie([a, b]) == ("warp",)
    assert s.words() == "1.1×; 95 % intervals apart need 5 %"


def test_overlapping_intervals_tie_whatever_the_gap():
    a, b = F("warp", 10.0, (5.0, 30.0)), F("cupy", 20.0, (15.0, 25.0))
    s = ranking.separated(a, b)
    assert not s.apart and s.kind == ranking.OVERLAP and s.words() == ranking.OVERLAP
    assert ranking.tie([a, b]) == ("warp", "cupy")


def test_intervals_apart_under_five_percent_tie():
    s = ranking.separated(F("a", 10.0, (9.99, 10.01)), F("b", 10.4, (10.39, 10.41)))
    assert not s.apart and s.kind == ranking.INTERVALS


def test_one_process_figures_need_the_one_process_gap():
    one = ranking.separated(F("a", 10.0, (9.9, 10.1)), F("b", 15.0))      # one interval is not enough
    assert not one.apart and one.kind == ranking.ONE_PROCESS and one.needed == ranking.ONE_PROCESS_GAP
    assert ranking.separated(F("a", 10.0), F("b", 16.0)).apart
    assert ranking.separated(F("a", 10.0), F("b", 20.8)).words() == "2.08×; figures without a 95 % interval need 1.6×"


def test_deterministic_figures_need_five_percent_and_equal_ones_tie():
    assert not ranking.separated(F("a", 1.0), F("b", 1.04), exact=True).apart
    s = ranking.separated(F("a", 1.0), F("b", 1.06), exact=True)
    assert s.apart and s.kind == ranking.EXACT
    eq = ranking.separated(F("a", 1.0, (0.9, 1.1)), F("b", 1.0, (5.0, 6.0)))
    assert not eq.apart and eq.kind == ranking.EQUAL and eq.gap == 1.0


def test_only_figures_are_ranked():
    with pytest.raises(ValueError):
        ranking.separated(F("a", None), F("b", 1.0))


def test_tie_keeps_the_best_and_everyone_not_separated_from_it_in_order():
    ranked = [F("a", 1.0), F("b", 1.5), F("c", 2.0), F("d", 1.55)]
    assert ranking.tie(ranked) == ("a", "b", "d") and ranking.tie([]) == ()


def test_why_tied_groups_the_tests():
    top = F("a", 10.0)
    assert ranking.why_tied(top, [F("b", 12.2)]) == "figures without a 95 % interval within 1.22×, under the 1.6× they need"
    mixed = ranking.why_tied(F("a", 10.0, (9.9, 10.1)), [F("b", 10.0), F("c", 10.3, (10.2, 10.4))])
    assert mixed == ("b: equal figures; c: 95 % intervals apart but within 3.0 %, under the 5 % they need")


def test_shorten_keeps_three_names_else_two_and_a_count():
    assert ranking.shorten(["a", "b", "c"]) == "a, b, c"
    assert ranking.shorten(["a", "b", "c", "d", "e"]) == "a, b +3"


def test_a_row_that_ranks_only_repeated_figures_says_why_it_ranks_nothing():
    """Every figure with an interval: ranked (''); one from one process, or from too few processes
    for an interval, and the row names no best; without a command the rule ranks any figure."""
    six = [F("numba", 1.0, (0.9, 1.1), 6), F("jax", 2.0, (1.9, 2.1), 6), F("torch", None)]
    assert ranking.bare(six) == "" and ranking.unrepeated(six, "CMD") == ""
    one = [F("numba", 1.0), F("jax", 2.0), F("torch", None)]
    assert ranking.bare(one) == "one process"
    assert ranking.unrepeated(one, "CMD") == (
        "Not ranked: every figure here is from one process a cell; this row ranks only figures repeated "
        "across processes, each with a 95 % interval (`CMD`). Ratios are to the leading figure; no best is named.")
    assert ranking.unrepeated(one, "") == ""
    mixed = [six[0], F("jax", 2.0, None, 3)]
    assert ranking.bare(mixed) == "under 6 processes"
    assert ranking.unrepeated(mixed, "CMD").startswith("Not ranked: jax: no 95 % interval across processes;")
