"""Repeats across processes (compare/running/repeats.py): the median's distribution-free interval, the
stopping rule, the seeded rounds, and a run whose records carry every process's figures."""
from __future__ import annotations

import json

import pytest

from compare.running import repeats
from compare.results.record import Record, plain
from compare.results.record_parts import Figure, Processes, Timing
from compare.site import data
from reliability_checks import run_main


@pytest.mark.parametrize("n,j,cover", [(6, 1, 0.96875), (10, 2, 0.978515625), (20, 6, 0.9586)])
def test_the_interval_is_the_narrowest_pair_of_order_statistics_at_95_percent(n, j, cover):
    lo, hi, c = repeats.interval(list(range(1, n + 1)))
    assert (lo, hi) == (j, n + 1 - j) and c == pytest.approx(cover, abs=1e-4) and c >= 0.95


def test_too_few_processes_give_the_range_at_its_lower_confidence():
    assert repeats.interval([3.0, 1.0, 2.0]) == (1.0, 3.0, 0.75)
    assert repeats.summary([_t(v) for v in (3e-5, 1e-5, 2e-5, 1e-4)])["latency"]["median_s"] == 2.5e-5


def _t(lat: float, first: float = 1.0) -> Timing:
    return Timing.of(latency={"median_s": lat}, throughput={"median_s": lat / 2}, first_call_s=first, setup_s=0.5)


def test_summary_keeps_every_process_and_first_is_set_up_plus_first_call():
    b = repeats.summary([_t(1e-5), _t(2e-5, 2.0), _t(3e-5)])
    assert b.count == 3 and b.latency is not None and b.latency.each == (1e-5, 2e-5, 3e-5)
    assert b.latency.median_s == 2e-5 and b.throughput is not None and b.throughput.median_s == 1e-5
    assert b.first_result is not None and b.first_result.each == (1.5, 2.5, 1.5)
    assert "graph" not in b and "events" not in b


def test_auto_stops_a_settled_cell_and_runs_a_scattered_one_to_the_maximum():
    calls: dict[int, int] = {0: 0, 1: 0}
    values = {0: iter([1e-5] * 20), 1: iter([1e-5, 2e-5] * 10)}

    def time_one(i: int) -> Timing:
        calls[i] += 1
        return _t(next(values[i]))
    rounds: list[list[int]] = []
    out = repeats.run_rounds({0: _t(1e-5), 1: _t(2e-5)}, "auto", 0, lambda order, rnd: [time_one(i) for i in order],
                             lambda b: rounds.append(sorted(b)))
    assert calls == {0: repeats.AUTO_MIN - 1, 1: repeats.AUTO_MAX - 1}
    assert out[0]["count"] == repeats.AUTO_MIN and out[1]["count"] == repeats.AUTO_MAX
    assert repeats.settled(out[0]) and not repeats.settled(out[1])
    assert rounds[0] == [0, 1] and rounds[-1] == [1]


def test_a_sitting_stops_the_rounds_past_the_fewest_that_would_not_fit():
    """--sitting: asked before each round past the fewest with the last round's length; the
    fewest always run, and a scattered cell stops where the next round would not fit."""
    asked: list[float] = []
    left = [3]                                   # rounds past the fewest that still fit

    def fits(round_s: float) -> bool:
        asked.append(round_s)
        left[0] -= 1
        return left[0] >= 0
    values = iter([1e-5, 2e-5] * 10)
    out = repeats.run_rounds({0: _t(2e-5)}, "auto", 0, lambda order, rnd: [_t(next(values)) for _ in order],
                             lambda b: None, fits)
    assert out[0]["count"] == repeats.AUTO_MIN + 3 and len(asked) == 4
    assert all(s >= 0.0 for s in asked)
    never = repeats.run_rounds({0: _t(2e-5)}, "auto", 0, lambda order, rnd: [_t(next(iter([3e-5])))
                               for _ in order], lambda b: None, lambda s: False)
    assert never[0]["count"] == repeats.AUTO_MIN


def test_time_to_first_result_is_the_cold_processes_and_keeps_no_round_open():
    """From round ``COLD`` on a cell runs with the caches its earlier process kept: those
    processes add no first-result value, and a first result that scatters (a cold compile)
    stops no cell at ``AUTO_MIN`` whose other figures settled."""
    def proc(rnd: int) -> Timing:
        t = _t(1e-5, first=float(rnd))           # cold first calls scatter widely
        return Timing.of(**t, cache="kept: X as an earlier process of this cell left it") if rnd > repeats.COLD else t
    seen: list[int] = []
    out = repeats.run_rounds({0: _t(1e-5, first=1.0)}, "auto", 0,
                             lambda order, rnd: seen.append(rnd) or [proc(rnd) for _ in order], lambda b: None)
    block = out[0]
    assert block.count == repeats.AUTO_MIN and seen == list(range(2, repeats.AUTO_MIN + 1))
    assert block.first_result is not None and block.first_result.each == (1.5, 2.5, 3.5)
    assert block.latency is not None and len(block.latency.each) == repeats.AUTO_MIN
    assert not repeats.settled(block) and repeats.settled(block, closed=("first_result",))
    assert "first_result" not in repeats.figures(proc(repeats.COLD + 1))


KEPT = "kept: X as an earlier process of this cell left it"


def test_a_cell_cold_once_closes_its_first_result_after_its_first_process(monkeypatch):
    """``cold``: per cell, its cold processes (the driver: 1 for a non-default variant, ``COLD``
    for the default). A cell cold once has one first-result value, its first process's, and the
    figure is closed from round 2; one cold 3 times has three. Both stop at the fewest where the
    other figures settled."""
    def proc(i: int, rnd: int) -> Timing:
        t = _t(1e-5, first=float(rnd))           # cold first calls scatter widely
        return Timing.of(**t, cache=KEPT) if rnd > (1 if i == 0 else repeats.COLD) else t
    first = {0: _t(1e-5, first=1.0), 1: _t(1e-5, first=1.0)}
    out = repeats.run_rounds(first, "auto", 0, lambda order, rnd: [proc(i, rnd) for i in order], lambda b: None,
                             cold={0: 1})
    once, thrice = out[0], out[1]
    assert once.count == thrice.count == repeats.AUTO_MIN
    assert once.first_result is not None and once.first_result.each == (1.5,)
    assert thrice.first_result is not None and thrice.first_result.each == (1.5, 2.5, 3.5)
    assert once.latency is not None and len(once.latency.each) == repeats.AUTO_MIN
    # the closing itself shows where a cell's only figure is its first result: with 2 processes
    # the fewest, the cell cold once stops there, the one cold 3 times after its 3rd process
    monkeypatch.setattr(repeats, "AUTO_MIN", 2)

    def only_first(i: int, rnd: int) -> Timing:
        t = Timing.of(first_call_s=float(rnd), setup_s=0.5)
        return Timing.of(**t, cache=KEPT) if rnd > (1 if i == 0 else repeats.COLD) else t
    bare = {i: Timing.of(first_call_s=1.0, setup_s=0.5) for i in (0, 1)}
    rounds: list[list[int]] = []
    out = repeats.run_rounds(bare, "auto", 0, lambda order, rnd: [only_first(i, rnd) for i in order],
                             lambda b: rounds.append(sorted(b)), cold={0: 1})
    assert (out[0].count, out[1].count) == (2, 3) and rounds == [[0, 1], [1]]
    default = repeats.run_rounds(bare, "auto", 0, lambda order, rnd: [only_first(i, rnd) for i in order],
                                 lambda b: None)
    assert default[0].count == 3             # without ``cold`` every cell is cold ``COLD`` times


def test_a_capped_cell_stops_at_its_cap_while_another_goes_on():
    """``most``: a cell stops after its cap (its block says why), the others go on to the fewest
    and past it as ever; a cap of 1 runs no repeat process and gets a block without figures."""
    ran: dict[int, list[int]] = {0: [], 1: [], 2: []}
    values = iter([1e-5, 2e-5] * 20)                  # scattered: never settled

    def time_round(order: list[int], rnd: int) -> list[Timing]:
        for i in order:
            ran[i].append(rnd)
        return [_t(next(values)) for _ in order]
    rounds: list[list[int]] = []
    out = repeats.run_rounds({i: _t(1e-5) for i in ran}, "auto", 0, time_round, lambda b: rounds.append(sorted(b)),
                             most={0: repeats.COLD, 1: 1}, capped="WHY")
    assert ran == {0: [2, 3], 1: [], 2: list(range(2, repeats.AUTO_MAX + 1))}
    assert rounds[0] == [1] and rounds[1] == rounds[2] == [0, 2] and rounds[-1] == [2]
    assert out[0].count == repeats.COLD and out[0].capped == "WHY"
    assert out[0].first_result is not None and len(out[0].first_result.each) == repeats.COLD
    assert out[1].count == 1 and out[1].capped == "WHY" and out[1].latency is None and out[1].first_result is None
    assert out[2].count == repeats.AUTO_MAX and out[2].capped is None and not repeats.settled(out[2])
    # a cap at or above the fewest cuts nothing the others get: no words
    same = repeats.run_rounds({0: _t(1e-5)}, 3, 0, lambda o, r: [_t(1e-5) for _ in o], lambda b: None,
                              most={0: 3}, capped="WHY")
    assert same[0].count == 3 and same[0].capped is None
    j = out[1].to_json()
    assert Processes.from_json(j).to_json() == j == {"count": 1, "capped": "WHY"}


def test_a_failed_repeat_is_counted_not_hidden():
    out = repeats.run_rounds({0: _t(1e-5)}, 3, 0, lambda order, rnd: [None] * len(order), lambda b: None)
    assert out[0]["count"] == 1 and out[0]["failed"] == 2


def test_a_round_is_timed_in_its_seeded_order_and_must_answer_for_every_cell():
    """Each round hands the whole shuffled order to ``time_round`` at once (so set-ups may run
    side by side), the same order for the same seed; an answer that skips a cell is refused."""
    orders: list[list[int]] = []

    def time_round(order: list[int], rnd: int) -> list[Timing]:
        orders.append(list(order))
        return [_t(1e-5) for _ in order]
    first = {i: _t(1e-5) for i in range(8)}
    repeats.run_rounds(first, 3, 5, time_round, lambda b: None)
    again: list[list[int]] = []
    repeats.run_rounds(first, 3, 5, lambda o, r: again.append(list(o)) or [_t(1e-5) for _ in o], lambda b: None)
    assert len(orders) == 2 and orders == again and sorted(orders[0]) == list(range(8))
    assert orders[0] != orders[1]          # each round its own shuffle
    with pytest.raises(RuntimeError, match="time blocks for a round"):
        repeats.run_rounds(first, 2, 5, lambda o, r: [_t(1e-5)], lambda b: None)


def test_the_site_reads_the_median_of_processes_and_its_interval():
    rec = Record.from_json({"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32",
                            "variant": "default", "status": "ok", "reason": "", "params": {"n": 1000},
                            "time": {"first_call_s": 1.0, "median_s": 9e-6, "iqr_s": 0.0, "min_s": 9e-6,
                                     "repeats": 10, "latency": {"median_s": 9e-6, "iqr_s": 0.0, "min_s": 9e-6,
                                                                "repeats": 10},
                                     "processes": repeats.summary([_t(v) for v in (1e-5, 1.1e-5, 1e-5, 1e-5,
                                                                                   1.05e-5, 1e-5)]).to_json()},
                            "error": {"vs_oracle": 0.0, "tolerance": 1.0}})
    t = data.timing(rec, "latency")
    assert t.processes == 6 and t.median == 1e-5 and t.ci == (1e-5, 1.1e-5) and "disagree" not in t.noisy
    j = plain(rec.to_json())
    del j["time"]["processes"]
    one = data.timing(Record.from_json(j), "latency")
    assert one.processes == 1 and one.ci is None and one.median == 9e-6


def test_a_run_with_three_processes_keeps_all_three(tmp_path):
    out = tmp_path / "r"
    # compare.cli.main in this process (no interpreter to start); the cells in their own, as ever
    rc, lines = run_main(["run", "saxpy", "--backends", "numpy", "--devices", "cpu", "--precision", "float32",
                          "--quick", "--repeat", "3", "--min-time", "0", "--processes", "3", "--out", str(out),
                          "--no-plots"])
    assert rc == 0, lines
    doc = json.loads((out / "results.json").read_text())
    [rec] = [r for r in doc["records"] if r["status"] == "ok"]
    block = rec["time"]["processes"]
    assert block["count"] == 3 and len(block["latency"]["values"]) == 3 and len(block["first_result"]["values"]) == 3
    assert doc["runs"][0]["processes"] == 3


def test_the_block_is_typed_and_its_json_is_the_stored_one():
    """``time.processes`` is a ``Processes`` of ``Figure``s whose JSON keeps the stored keys in order."""
    b = repeats.summary([_t(1e-5), _t(2e-5)], failed=1)
    assert isinstance(b, Processes) and isinstance(b.latency, Figure) and b.latency.each == (1e-5, 2e-5)
    j = b.to_json()
    assert list(j) == ["count", "order", "interval", "latency", "throughput", "first_result", "failed"]
    assert list(j["latency"]) == ["values", "median_s", "ci_lo_s", "ci_hi_s", "confidence"]
    assert j["latency"]["values"] == [1e-5, 2e-5] and Processes.from_json(j).to_json() == j



def test_resume_says_how_many_kept_cells_are_short_of_their_processes(capsys):
    """--resume keeps a cell cut off in its repeat rounds with the processes it reached (processes
    of another sitting are not added to its figures) and says how many such cells it keeps: below
    the count asked (``auto``: its fewest), or below the cell's cap where that is lower."""
    counts = {0: 4, 1: 6, 2: 1, 3: 4}
    assert repeats.say_short(counts, "auto", {3: 3, 2: 1}) == 1                     # cell 0 only
    assert "--resume keeps 1 cell with fewer processes than asked" in capsys.readouterr().err
    assert repeats.say_short({k: counts[k] for k in (0, 1, 2)}, 4, {}) == 1          # cell 2: one process
    capsys.readouterr()
    assert repeats.say_short({1: 6}, "auto", {}) == 0 and capsys.readouterr().err == ""
