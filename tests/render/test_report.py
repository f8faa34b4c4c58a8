"""compare/render/report.py: a run's tables, its summary and its closing lines (fast tier)."""
from __future__ import annotations

import csv
import io
from typing import Any

import pytest

from compare.render import report
from compare.results.record import Record


def rec(backend: str, t: float | None = 1e-4, *, device: str = "cpu", iqr: float = 0.0, status: str = "ok",
        scenario: str = "saxpy", throughput: bool = True, **fields: Any) -> Record:
    time = None
    if t is not None:
        time = {"median_s": t, "iqr_s": iqr, "repeats": 100, "latency": {"median_s": t, "iqr_s": iqr, "repeats": 100}}
        if throughput:
            time["throughput"] = {"median_s": t, "iqr_s": iqr, "repeats": 100, "k": 10}
    return Record(scenario=scenario, backend=backend, device=device, precision="float32", status=status,
                  params={"n": 1000}, time=time, **fields)


@pytest.mark.parametrize("s,text", [(2.0, "2 s"), (1.5e-3, "1.5 ms"), (2e-6, "2 µs"), (5e-10, "0.5 ns"),
                                    (None, "-"), (float("nan"), "-"), ("x", "-")])
def test_fmt_time(s, text):
    assert report.fmt_time(s) == text


def test_fmt_num_and_bytes():
    assert report.fmt_num(None) == "-" and report.fmt_num(0) == "0" and report.fmt_num(1.23456e-7) == "1.23e-07"
    assert report.fmt_num([1, "a"]) == "[1, a]"
    assert report.fmt_bytes(3 * 2**20) == "3 MiB" and report.fmt_bytes(100) == "100 B" and report.fmt_bytes(None) == "-"


def test_fmt_gradient():
    assert report.fmt_gradient(rec("warp")) == "-"
    g = rec("warp", gradient={"method": "tape", "vs_oracle_rel": 1e-6, "reference": "oracle", "vs_fd64_rel": 2e-3})
    assert report.fmt_gradient(g) == "tape: 1e-06 rel vs oracle, 0.002 vs fd64"


def test_call_time_prefers_the_throughput_regime():
    assert report.call_time(rec("warp", 2e-4)) == (2e-4, 0.0, "throughput")
    assert report.call_time(rec("jax", 3e-4, throughput=False)) == (3e-4, 0.0, "latency")
    assert report.call_time(rec("jax", None)) == (None, None, "latency")


def test_a_row_has_every_column_and_notes_why():
    r = rec("warp", error={"vs_oracle": 1e-7, "tolerance": 1e-5, "checked_items": "4096 of 1000000"})
    row = report.row(r)
    assert len(row) == len(report.COLUMNS)
    cols = dict(zip(report.COLUMNS, row))
    assert cols["backend"] == "warp" and cols["status"] == "ok" and cols["latency"] == "100 µs"
    assert row[-1] == "oracle checked 4096 of 1000000"


def test_summary_counts_cells_and_names_the_fastest_only_where_separated():
    far = [rec("numpy", 8e-4), rec("warp", 1e-4), rec("jax", 4e-4), rec("torch", None, status="error")]
    lines = report.summary_lines(far)
    assert lines[0] == "4 cells: 3 ok, 1 error"
    text = " ".join(lines)
    assert "fastest warp (100 µs a call), 4x ahead of jax" in text
    assert "against NumPy: warp 8x, jax 2x" in text
    close = report.summary_lines([rec("warp", 1e-4), rec("jax", 1.03e-4)])
    assert "tie: warp, jax" in close[1] and "within 5 %" in close[1]
    overlap = report.summary_lines([rec("warp", 1e-4, iqr=0.09e-4), rec("jax", 1.06e-4, iqr=0.095e-4)])
    assert "their spreads overlap" in overlap[1]


def test_no_noise_no_closing_lines():
    assert report.noise_lines([rec("warp"), rec("jax")]) == []


def test_tables_group_by_scenario_with_their_parameters():
    text = report.tables([rec("warp"), rec("warp", scenario="sdf")], "github")
    assert "saxpy" in text and "sdf" in text and "| warp " in text
    assert list(report.by_scenario([rec("a", scenario="sdf"), rec("b")])) == ["sdf", "saxpy"]


def test_write_tables_writes_the_csv_and_the_markdown(tmp_path):
    recs = [rec("warp"), rec("jax", 2e-4)]
    report.write_tables(tmp_path, {"command": "python -m compare saxpy"}, recs)
    rows = list(csv.DictReader(io.StringIO((tmp_path / "results.csv").read_text())))
    assert [r["backend"] for r in rows] == ["warp", "jax"]
    md = (tmp_path / "results.md").read_text()
    assert md.startswith("# Results\n") and "warp" in md
