"""compare/site/sittings.py: a report's rows beside the same rows measured in a later sitting
(fast tier, from the site's test store)."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from compare.site import data, pages, sittings

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site"


def _scaled(t: Any, k: float) -> Any:
    """A record's time block with every duration multiplied by ``k`` (counts untouched)."""
    if isinstance(t, dict):
        return {key: (v * k if key.endswith("_s") and isinstance(v, (int, float)) else _scaled(v, k))
                for key, v in t.items()}
    if isinstance(t, list):
        return [_scaled(v, k) for v in t]
    return t


def _sitting(tmp_path: Path, change) -> Path:
    """A report folder whose sittings/later/ holds the test store's records, each passed through ``change``."""
    store = json.loads((STORE / "results.json").read_text())
    store["records"] = [r for r in (change(r) for r in store["records"]) if r is not None]
    later = tmp_path / "report-store" / sittings.FOLDER / "later"
    later.mkdir(parents=True)
    (later / "results.json").write_text(json.dumps(store))
    return tmp_path / "report-store"


@pytest.fixture(scope="module")
def rows():
    return pages.evaluate(data.load([STORE]))[0]


def test_the_same_figures_in_a_later_sitting_lie_inside_and_a_slower_one_is_measured(tmp_path, rows):
    def slower_warp(r):
        return {**r, "time": _scaled(r["time"], 1.5)} if r["backend"] == "warp" and r.get("time") else r
    folder = _sitting(tmp_path, slower_warp)
    got = sittings.compare(rows, sittings.load_all([folder]))
    assert {b.sitting for b in got} == {"later"} and {"latency", "pipelined", "particles-small"} <= {b.row for b in got}
    for b in got:
        timed = b.framework == "warp" and b.unit in ("s", "1/s")      # durations and rates moved; bytes and errors not
        assert b.spread == pytest.approx(1.5 if timed else 1.0), (b.row, b.framework)
        assert b.inside is (None if b.ci is None else (b.ci[0] <= b.other <= b.ci[1]))
        if not timed:
            assert b.inside in (None, True)
    text = " ".join(getattr(x, "text", "") for x in sittings.summary(got, ["later"]))
    assert f"{len(got)} figures of " in text and "1 later sitting (later)" in text


def test_a_row_read_at_another_size_or_another_variant_is_not_compared(tmp_path, rows):
    def other_size(r):            # every SAXPY cell of the sitting at another n
        return {**r, "params": {**r["params"], "n": r["params"]["n"] * 2}} if r["scenario"] == "saxpy" else r
    got = sittings.compare(rows, sittings.load_all([_sitting(tmp_path, other_size)]))
    assert not [b for b in got if "saxpy" in b.row], "a row read at another size was compared"

    def no_default(r):            # the sitting timed none of the default variants: the rows pick others
        return None if r.get("variant") == "default" else r
    (tmp_path / "b").mkdir()
    picked = {(r.rule.key, f): c.variant for r in rows for f, c in r.cells.items()}
    for b in sittings.compare(rows, sittings.load_all([_sitting(tmp_path / "b", no_default)])):
        assert b.variant == picked[b.row, b.framework] != "default"


def test_no_sitting_says_so_and_no_row_block_is_added(tmp_path, rows):
    assert sittings.folders([STORE, tmp_path]) == [] and sittings.compare(rows, []) == []
    text = " ".join(getattr(x, "text", "") for x in sittings.summary([], []))
    assert "No row of this report has been re-measured in a second sitting yet" in text
    assert sittings.row_blocks(rows, []) == []


def test_a_symlinked_sitting_is_not_followed(tmp_path):
    real = tmp_path / "elsewhere"
    real.mkdir()
    (tmp_path / "store" / sittings.FOLDER).mkdir(parents=True)
    (tmp_path / "store" / sittings.FOLDER / "linked").symlink_to(real)
    assert sittings.folders([tmp_path / "store"]) == []


def _with_interval(r: dict) -> dict:
    """A SAXPY record as if timed in six processes: its latency's median within +-2 % at 97 % confidence."""
    lat = ((r.get("time") or {}).get("latency") or {}).get("median_s")
    if r["scenario"] != "saxpy" or not lat:
        return r
    block = {"median_s": lat, "ci_lo_s": 0.98 * lat, "ci_hi_s": 1.02 * lat, "values": [lat] * 6, "confidence": 0.969}
    return {**r, "time": {**r["time"], "processes": {"count": 6, "latency": block}}}


def test_a_figure_moved_past_its_interval_is_counted_outside(tmp_path):
    """Where the report's figure has a 95 % interval (six processes), a later sitting's figure
    1.5x slower lies outside it, an unchanged one inside, and the machine page counts them."""
    store = json.loads((STORE / "results.json").read_text())
    store["records"] = [_with_interval(r) for r in store["records"]]
    report = tmp_path / "report"
    report.mkdir()
    (report / "results.json").write_text(json.dumps(store))
    rows = pages.evaluate(data.load([report]))[0]

    def slower_warp(r):
        r = _with_interval(r)
        return {**r, "time": _scaled(r["time"], 1.5)} if r["backend"] == "warp" and r.get("time") else r
    (tmp_path / "s").mkdir()
    got = [b for b in sittings.compare(rows, sittings.load_all([_sitting(tmp_path / "s", slower_warp)]))
           if b.row == "latency"]
    assert got and all(b.ci is not None for b in got)
    assert [b.inside for b in got if b.framework == "warp"] == [False]
    assert all(b.inside for b in got if b.framework != "warp") and len(got) > 1
    text = " ".join(getattr(x, "text", "") for x in sittings.summary(got, ["later"]))
    assert f"**{len(got) - 1} of {len(got)}** with an interval fall inside" in text
    table = sittings.row_blocks(rows, got)[-1]
    assert [r[-1] for r in table.rows if r[1] == "warp"] == ["**outside**"]


def test_an_exact_figure_is_neither_one_process_nor_short_of_an_interval(tmp_path, rows):
    """A deterministic figure (an error share, a byte count) needs no interval and has no processes:
    the row page says "exact figure", never "(1 process)", and the machine page counts it apart
    from timed figures that lack an interval."""
    got = sittings.compare(rows, sittings.load_all([_sitting(tmp_path, lambda r: r)]))
    exact = [b for b in got if b.exact]
    timed = [b for b in got if not b.exact and b.inside is None]
    assert exact and timed and {b.row for b in exact} <= {r.rule.key for r in rows if r.rule.exact}
    table = sittings.row_blocks(rows, got)[-1]
    for r in table.rows:
        exact_row = next(x.rule.exact for x in rows if x.rule.question == r[0])
        assert (r[-1] == "exact figure") is exact_row, r
        assert not (exact_row and "(1 process)" in r[6]), r
    text = " ".join(getattr(x, "text", "") for x in sittings.summary(got, ["later"]))
    assert f"{len(timed)} timed in fewer than 6 processes; {len(exact)} exact figures, which need none" in text
    counts = sittings.summary(got, ["later"])[-1]
    col = {c: i for i, c in enumerate(counts.headers)}
    assert sum(int(r[col["no interval"]]) for r in counts.rows) == len(timed)
    assert sum(int(r[col["exact"]]) for r in counts.rows) == len(exact)


def test_a_sitting_of_the_busy_row_alone_is_compared_on_that_row():
    """A later sitting that re-measured only the shared-host experiment holds busy records and no
    other timed record: its busy row is still set beside the report's (its devices are the busy
    records' own), each framework's time under load with its interval."""
    from test_shared_host import cell, machine
    from compare.site import matrix

    def recs(k: float) -> list:
        out = []
        for sc in matrix.IN_ALL:
            out += [cell("numpy", sc, 1e-3, ci=(0.9e-3, 1.1e-3)),
                    cell("numpy", sc, 1.1e-3 * k, busy=1, ci=(1.0e-3 * k, 1.2e-3 * k)),
                    cell("numba", sc, 1e-4, ci=(0.9e-4, 1.1e-4)),
                    cell("numba", sc, 3e-4, busy=1, ci=(2.8e-4, 3.2e-4))]
        return out
    report, later = machine(recs(1.0)), machine(recs(1.5))
    assert later.devices() == [] and later.busy              # only busy records
    busy_rows = [r for r in pages.evaluate(report)[0] if r.rule.key == "busy"]
    got = sittings.compare(busy_rows, [("later", later)])
    by = {b.framework: b for b in got}
    assert set(by) == {"numpy", "numba"} and {b.row for b in got} == {"busy"}
    assert by["numba"].inside and by["numba"].spread == pytest.approx(1.0)
    assert by["numpy"].spread == pytest.approx(1.5) and by["numpy"].inside is False


def _landing(sitting: str, fw: str, first: float, other: float, floors: tuple[float, float] | None) -> sittings.Between:
    f = floors or (None, None)
    return sittings.Between("latency", "Small kernel: one synchronised call", fw, "default", "s", first, None,
                            sitting, other, 3, False, f[0], f[1])


def test_a_later_sitting_lands_inside_the_range_of_the_report_and_the_earlier_ones_in_floors_and_seconds():
    """The first later sitting has only the report's figure (no range); the second lands where its
    figure lies between the report's and the first's, in floors and, separately, in seconds."""
    between = [_landing("a", "warp", 10e-6, 14e-6, (1.0, 1.2)), _landing("a", "jax", 20e-6, 20e-6, (2.0, 2.0)),
               _landing("b", "warp", 10e-6, 16e-6, (1.0, 1.1)),      # seconds outside, floors inside
               _landing("b", "jax", 20e-6, 20e-6, (2.0, 2.5)),       # seconds inside (a point), floors outside
               _landing("b", "torch", 5e-6, 5e-6, None)]             # no floor: not counted
    got = sittings.landed(between, ["a", "b"])
    assert [x.sitting for x in got] == ["b"]
    assert (got[0].figures, got[0].inside_floors, got[0].inside_seconds) == (2, 1, 1)
    text = " ".join(str(b) for b in sittings.landing(got))
    assert "1 (50 %)" in text and "90 %" in text
    assert sittings.landing([]) == []


def test_a_later_sitting_is_held_to_its_rows_band_from_the_sittings_before_it():
    """A row's band pools every earlier sitting's ratio to the report (the report's 1 among them),
    across frameworks: a figure with no earlier range of its own is held to it too, and the bands
    of every sitting are what the machine page states for the next one."""
    between = [_landing("a", "warp", 10e-6, 14e-6, (1.0, 1.2)), _landing("a", "jax", 20e-6, 16e-6, (2.0, 1.8)),
               _landing("b", "torch", 10e-6, 11e-6, (1.0, 1.1)),     # band: floors 0.9-1.2, seconds 0.8-1.4
               _landing("b", "warp", 10e-6, 13e-6, (1.0, 1.3)),      # seconds inside, floors outside
               _landing("b", "cupy", 10e-6, 7e-6, (1.0, 0.95))]      # floors inside, seconds outside
    before = sittings.bands(between, ["a"])["latency"]
    assert before.n == 3 and before.coverage == pytest.approx(0.5)
    assert (min(before.floors), max(before.floors)) == pytest.approx((0.9, 1.2))
    assert (min(before.seconds), max(before.seconds)) == pytest.approx((0.8, 1.4))
    got = sittings.landed(between, ["a", "b"])
    assert [x.sitting for x in got] == ["b"] and got[0].figures == 1          # warp alone has its own range
    assert (got[0].banded, got[0].band_floors, got[0].band_seconds) == (3, 2, 2)
    assert sittings.bands(between, ["a", "b"])["latency"].n == 6
    text = " ".join(str(b) for b in sittings.landing(got, sittings.bands(between, ["a", "b"])))
    assert "2 (67 %)" in text and "0.90–1.30×" in text and "71 %" in text
    assert sittings.bands(between, []) == {}


def test_a_travelling_rows_figures_carry_their_floors_on_both_sides(tmp_path, rows):
    """compare() with the report's stores gives a figure of a travelling row in launch floors where
    its record keeps its run's yardstick (the same records on both sides here: the same floors),
    none for a row that does not travel, and none without the report's stores."""
    report = _sitting(tmp_path, lambda r: r)
    got = sittings.compare(rows, sittings.load_all([report]), data.load([STORE]))
    floored = [b for b in got if b.first_floors is not None]
    assert floored and {b.row for b in floored} <= set(sittings.TRAVEL)
    assert all(b.other_floors == b.first_floors for b in floored)
    assert all(b.first_floors is None for b in sittings.compare(rows, sittings.load_all([report])))


def test_a_row_page_gives_a_travelling_figure_in_floors_beside_its_seconds(rows):
    latency = [r for r in rows if r.rule.key == "latency"]
    table = sittings.row_blocks(latency, [_landing("a", "warp", 10e-6, 12e-6, (1.0, 1.5))])[-1]
    assert table.headers[-1] == "in launch floors" and table.rows[0][-1] == "1 → 1.5 (1.5×)"
    table = sittings.row_blocks(latency, [_landing("a", "warp", 10e-6, 12e-6, None)])[-1]
    assert "in launch floors" not in table.headers
