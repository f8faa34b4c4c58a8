"""compare/planning/calibrate.py: big cells timed in miniature first, and skipped with the
prediction where their protocol would outlast --timeout (fast tier: the miniatures' runs are
stand-ins here; the protocol's call count and a real miniature: tests/running/test_overlap.py)."""
from __future__ import annotations

import pytest

from compare.planning import calibrate
from compare.results.record_parts import Timing
from compare.spec import Cell

BIG = {"batch": 65536}


def big(backend="numpy", **params) -> Cell:
    return Cell.make("projectile", backend, "cpu", "float32", params={**BIG, **params})


def test_a_big_cell_has_a_miniature_at_one_factor_of_its_size_and_a_small_one_none():
    cell = big()
    small = calibrate.miniature(cell)
    assert small.params.batch == 65536 // calibrate.FACTOR
    assert calibrate.items(cell) == pytest.approx(calibrate.FACTOR * calibrate.items(small))
    assert (small.warmup, small.repeat, small.throughput, small.check, small.save_outputs) == (0, 2, False, False, False)
    assert calibrate.miniature(Cell.make("projectile", "numpy", "cpu", "float32", params={"batch": 1})) is None


def test_the_prediction_scales_one_call_by_the_work_and_keeps_the_compilation():
    cell = big()
    small = calibrate.miniature(cell)
    t = Timing.of(median_s=0.5, first_call_s=2.5, iqr_s=0.0, min_s=0.5, repeats=2)
    total, per_call = calibrate.predict(cell, small, t)
    assert per_call == pytest.approx(0.5 * calibrate.FACTOR)
    assert total == pytest.approx(2.0 + per_call * (1 + calibrate.protocol_calls(per_call, cell)))


@pytest.mark.parametrize("s,text", [(59.4, "59 s"), (600, "10 min"), (3 * 3600, "3.0 h")])
def test_when(s, text):
    assert calibrate._when(s) == text


def ran(median_s=1.0, status="ok"):
    def run(small):
        return {"status": status, "time": {"median_s": median_s, "first_call_s": median_s},
                "memory": {"peak_host_rss_bytes": 123}}, None
    return run


def test_without_a_timeout_nothing_is_refused_and_nothing_runs():
    def run(small):
        raise AssertionError("no miniature without a timeout")
    assert calibrate.time_refusal([big()], None, run=run)(big()) is None


def test_only_cells_predicted_past_the_timeout_are_skipped_with_the_timeout_that_runs_them():
    plan = [big()]
    refuse = calibrate.time_refusal(plan, 10.0, run=ran(1.0))          # 64 s a call
    status, reason = refuse(plan[0])
    assert status == "skipped" and "one call about 64 s, from a 1/64-size run" in reason
    assert "over --timeout 10 s; --timeout " in reason
    assert calibrate.time_refusal(plan, 1e6, run=ran(1e-3))(plan[0]) is None    # fits
    assert calibrate.time_refusal(plan, 10.0, run=ran(1.0, "error"))(plan[0]) is None   # the cell will say why
    small = Cell.make("projectile", "numpy", "cpu", "float32", params={"batch": 1})
    assert calibrate.time_refusal([small], 1e-9, run=ran(1.0))(small) is None   # not big: never judged


def test_a_miniatures_record_is_read_back():
    cell = calibrate.miniature(big())
    m = calibrate.Miniature.of(cell, ran(0.25)(cell))
    assert m.status == "ok" and m.time.median_s == 0.25 and m.peak_host_rss_bytes == 123.0
    none = calibrate.Miniature.of(cell, ({"status": "error"}, None))
    assert none.time is None and none.peak_host_rss_bytes is None
    minis = calibrate.run_miniatures([big(), big("jax")], 10.0, run=ran(0.25))
    assert set(minis) == {calibrate.key(big()), calibrate.key(big("jax"))}


def test_a_miniature_runs_within_a_small_share_of_the_timeout(monkeypatch):
    """Issue 58 item 8: a miniature waited --timeout (900 s) before saying nothing; now a share of
    it, never under MINIATURE_MIN_S (import and first compile) nor over --timeout."""
    assert calibrate.miniature_timeout(900.0) == pytest.approx(calibrate.MINIATURE_MIN_S)
    assert calibrate.miniature_timeout(7200.0) == pytest.approx(7200.0 * calibrate.MINIATURE_SHARE)
    assert calibrate.miniature_timeout(20.0) == 20.0 and calibrate.miniature_timeout(None) is None
    limits = []
    monkeypatch.setattr(calibrate.cells, "run", lambda c, timeout: (limits.append(timeout), ran(0.25)(c))[1])
    calibrate.run_miniatures([big()], 900.0)
    assert limits == [calibrate.miniature_timeout(900.0)] and limits[0] < 900.0


def test_miniatures_show_a_ticking_bar_on_a_terminal_and_nothing_elsewhere(monkeypatch):
    import io
    import sys
    import time

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    def slow(small):
        time.sleep(1.3)                # past one tick of the bar's clock
        return ran(0.25)(small)
    monkeypatch.delenv("CI", raising=False)
    for err, shown in ((Tty(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", err)
        calibrate.run_miniatures([big()], 20.0, run=slow)
        text = err.getvalue()
        assert ("big cells at 1/64 of their size, at most 20 s each" in text) is shown, text
        assert ("00:01" in text and "numpy cpu float32 projectile" in text) is shown, text
