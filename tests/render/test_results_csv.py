"""compare/render/results_csv.py: results.csv, one row per cell, plain numbers or empty (fast tier)."""
from __future__ import annotations

import csv
import io

from compare.render import results_csv
from compare.results.record import Record


def rec(status: str = "ok", **fields) -> Record:
    return Record(scenario="saxpy", backend="warp", device="cuda", precision="float32", status=status,
                  params={"n": 10, "a": 2.0}, **fields)


def test_a_row_has_every_column_and_plain_numbers():
    r = rec(time={"median_s": 2e-6, "first_call_s": 0.5, "latency": {"median_s": 2e-6, "iqr_s": 1e-7, "repeats": 50},
                  "throughput": {"median_s": 1e-6, "k": 10}, "events": {"median_s": 1.5e-6}},
            memory={"device_bytes": 4096}, error={"vs_oracle": 1e-7, "tolerance": 1e-5})
    row = results_csv.tidy(r)
    assert list(row) == list(results_csv.CSV_COLUMNS)
    assert row["params"] == '{"a": 2.0, "n": 10}'
    assert (row["first_call_s"], row["latency_median_s"], row["latency_repeats"], row["throughput_k"]) == (0.5, 2e-6, 50, 10)
    assert row["events_median_s"] == 1.5e-6 and row["device_bytes"] == 4096 and row["err_vs_oracle"] == 1e-7


def test_what_a_record_lacks_is_empty():
    row = results_csv.tidy(rec(status="skipped", reason="no GPU"))
    assert row["reason"] == "no GPU" and row["latency_median_s"] == "" and row["events_median_s"] == ""
    assert row["device_bytes"] == "" and row["noise_reasons"] == ""


def test_csv_text_reads_back_with_the_header_first():
    text = results_csv.csv_text([rec(), rec(status="error", reason="boom, twice")])
    rows = list(csv.DictReader(io.StringIO(text)))
    assert text.splitlines()[0] == ",".join(results_csv.CSV_COLUMNS)
    assert [r["status"] for r in rows] == ["ok", "error"] and rows[1]["reason"] == "boom, twice"
