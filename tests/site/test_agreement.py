"""One row, one run (compare/site/provenance.py) and two runs held against each other ordering
by ordering (compare/site/agreement.py, ``compare agree``)."""
from __future__ import annotations

from typing import Any

from compare.results.record import Record
from compare.site import agreement, provenance
from compare.site import pages
from test_matrix import latency, machine, rec, row


def stamp(created: str, commit: str = "abc1234", dirty: bool | None = False) -> dict[str, Any]:
    return {"created": created, "commit": commit, "dirty": dirty}


def test_a_row_of_one_run_is_ranked_and_says_which_run():
    r = row("latency", [rec("warp", time=latency(10e-6)), rec("cupy", time=latency(40e-6))])
    assert r.best == "warp" and provenance.one_run(r.runs)
    assert r.runs == ("run 2026-11-27 00:00 UTC, commit abc1234",)


def test_a_row_spanning_runs_names_no_best():
    r = row("latency", [rec("warp", time=latency(10e-6)),
                        rec("cupy", time=latency(40e-6), run=stamp("2026-11-28T09:00:00+00:00", "def5678", True))])
    assert r.best is None and r.tied == () and r.top == "warp"
    assert r.best_text() == "— (2 runs)" and r.verdict.startswith("Not ranked: this row's figures come from 2 run(s)")
    assert "commit def5678 (dirty tree)" in r.verdict and not any(c.tied for c in r.cells.values())


def test_unstamped_records_are_not_one_run():
    r = row("latency", [rec("warp", time=latency(10e-6), run=None), rec("cupy", time=latency(40e-6), run=None)])
    assert r.best is None and r.best_text() == "— (not one run)"
    assert provenance.UNSTAMPED in r.verdict


def test_one_run_of_an_uncommitted_tree_names_no_best():
    dirty = stamp("2026-11-28T09:00:00+00:00", "def5678", True)
    r = row("latency", [rec("warp", time=latency(10e-6), run=dirty), rec("cupy", time=latency(40e-6), run=dirty)])
    assert r.best is None and r.tied == () and r.top == "warp" and r.best_text() == "— (not a commit)"
    assert "not a commit someone can check out" in r.verdict


def _two(warp: float, cupy: float, torch: float, ci: float = 0.01) -> list[Record]:
    return [rec(fw, time=latency(v, (v * (1 - ci), v * (1 + ci)), n=6))
            for fw, v in (("warp", warp), ("cupy", cupy), ("torch", torch))]


def test_agreeing_runs_count_every_separated_pair():
    got = agreement.compare_rows([row("latency", _two(10e-6, 20e-6, 40e-6))],
                                 [row("latency", _two(11e-6, 21e-6, 39e-6))])
    [a] = got
    assert (a.significant, a.agree, a.tie, a.disagree) == (3, 3, 0, 0)
    assert agreement.summary(got).startswith("3 of 3 significant orderings agree")


def test_a_tie_in_one_run_is_allowed_and_a_reversal_is_named():
    got = agreement.compare_rows([row("latency", _two(10e-6, 20e-6, 40e-6))],
                                 [row("latency", _two(20e-6, 10e-6, 20.2e-6))])
    [a] = got
    assert a.disagree == 1 and a.reversed_pairs == ("cupy vs warp",)
    assert a.tie == 1 and a.agree == 1          # cupy-torch tie there, warp-torch agrees
    assert "1 reversed" in agreement.summary(got)


def test_rows_read_at_other_sizes_are_not_compared():
    small = [rec("warp", time=latency(1e-5), params={"n": 1000}), rec("cupy", time=latency(4e-5), params={"n": 1000})]
    assert agreement.compare_rows([row("latency", _two(10e-6, 20e-6, 40e-6))], [row("latency", small)]) == []


def test_agree_refuses_what_is_not_a_store_with_one_line_and_exit_2(tmp_path):
    import subprocess
    import sys
    from conftest import ROOT
    bad = tmp_path / "x.json"
    bad.write_text("[1, 2]")
    for args in ([str(tmp_path / "missing"), str(bad)], [str(bad), str(bad)]):
        p = subprocess.run([sys.executable, "-m", "compare", "agree", *args], cwd=ROOT, capture_output=True,
                           text=True, timeout=120)
        assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr, p.stderr


def _timed(v: float) -> dict[str, Any]:
    return latency(v, (v * 0.99, v * 1.01), n=6)


def test_only_the_cells_both_runs_measured_are_held():
    """A second run that timed the default variant alone: the report's fastest variant (another)
    is not set against it, so no reversal appears that is a variant's; the defaults are held."""
    report = machine([rec("warp", time=_timed(10e-6)), rec("warp", variant="record_cmd", time=_timed(5e-6)),
                      rec("cupy", time=_timed(7e-6))])
    sitting = machine([rec("warp", time=_timed(10.5e-6)), rec("cupy", time=_timed(7.2e-6))])
    raw = agreement.compare_rows(pages.evaluate(report)[0], pages.evaluate(sitting)[0])
    assert sum(r.disagree for r in raw) == 1        # record_cmd's 5 µs against the default's 10.5 µs
    held = agreement.hold(report, sitting)
    assert (held.cells, held.only_first, held.only_second, held.reversed) == (2, 1, 0, 0)
    assert sum(r.agree for r in held.rows) == 1     # cupy ahead of warp's default in both
    assert held.words().endswith("; not compared: 1 the first alone measured")


def test_a_reversal_on_the_cells_both_measured_still_counts():
    report = machine([rec("warp", time=_timed(10e-6)), rec("cupy", time=_timed(7e-6))])
    swapped = machine([rec("warp", time=_timed(7e-6)), rec("cupy", time=_timed(10e-6))])
    held = agreement.hold(report, swapped)
    assert held.reversed == 1 and held.cells == 2 and "not compared" not in held.words()
