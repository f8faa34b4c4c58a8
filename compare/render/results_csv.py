"""results.csv: one row per cell, one column per quantity, plain numbers in SI units (seconds,
bytes) or empty; docs/commands.md "results.csv" documents each column. Loaded with pandas as is."""
from __future__ import annotations

import csv
import io
import json
from typing import Mapping

from compare.measuring import noise, timing
from compare.results.record import Record, plain


def params_text(rec: Record) -> str:
    """A record's resolved parameters as one JSON line (keys sorted)."""
    return json.dumps(plain(rec.params), sort_keys=True)


CSV_COLUMNS = {
    "scenario": ("scenario",), "backend": ("backend",), "device": ("device",),
    "precision": ("precision",), "variant": ("variant",), "status": ("status",), "reason": ("reason",),
    "params": None,                                    # JSON of the resolved parameters
    "first_call_s": ("time", "first_call_s"),
    "latency_median_s": ("time", "latency", "median_s"), "latency_iqr_s": ("time", "latency", "iqr_s"),
    "latency_min_s": ("time", "latency", "min_s"), "latency_repeats": ("time", "latency", "repeats"),
    "events_median_s": None,                           # CUDA events, where the backend has them
    "throughput_median_s": ("time", "throughput", "median_s"),
    "throughput_iqr_s": ("time", "throughput", "iqr_s"), "throughput_min_s": ("time", "throughput", "min_s"),
    "throughput_k": ("time", "throughput", "k"), "throughput_host_s": ("time", "throughput", "host_s"),
    "graph_median_s": ("time", "graph", "median_s"), "graph_host_s": ("time", "graph", "host_s"),
    "floor_s": ("throughput", "floor_s"), "floor_kind": ("throughput", "floor_kind"),
    "hw_fraction": ("throughput", "hw_fraction"),
    "device_bytes": ("memory", "device_bytes"), "framework_device_peak_bytes": ("memory", "device_peak_bytes"),
    "peak_host_rss_bytes": ("memory", "peak_host_rss_bytes"), "host_bytes": ("memory", "host_bytes"),
    "gradients_per_s": ("throughput", "gradients_per_s"),
    "err_vs_oracle": ("error", "vs_oracle"), "tolerance": ("error", "tolerance"),
    "err_vs_reference": ("error", "vs_reference"), "reference": ("error", "reference"),
    "gradient_method": ("gradient", "method"), "gradient_rel_error": ("gradient", "vs_oracle_rel"),
    "gradient_fd_agreement": ("gradient", "fd_agreement"),
    "setup_s": ("time", "setup_s"), "download_s": ("time", "download_s"), "machine": ("machine",),
    "noisy": ("time", "noise", "noisy"), "noise_reasons": None,      # compare/measuring/noise.py
    "others_cores": ("time", "noise", "others_cores"),
}


CsvValue = str | int | float      # a results.csv cell: a number, a word, or '' (a bool is an int)


def tidy(rec: Record) -> dict[str, CsvValue]:
    """One results.csv row: every CSV_COLUMNS quantity of the record, or '' where it has none."""
    out: dict[str, CsvValue] = {}
    for col, path in CSV_COLUMNS.items():
        if col == "params":
            out[col] = params_text(rec)
            continue
        if col == "noise_reasons":
            out[col] = "; ".join(noise.reasons_for(rec))
            continue
        if col == "events_median_s":
            ev = timing.events_of(rec.time)
            m = ev.median_s if ev and "median_s" in ev else None
            out[col] = m if isinstance(m, (str, int, float)) else ""
            continue
        assert path is not None, col         # every column without a path is handled above
        v: object = getattr(rec, path[0])
        for k in path[1:]:
            v = v.get(k) if isinstance(v, Mapping) else None
        out[col] = v if isinstance(v, (str, int, float)) else ""     # None, an object or a list: none
    return out


def csv_text(records: list[Record]) -> str:
    """results.csv's text: the header, then one ``tidy`` row per record."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(CSV_COLUMNS))
    w.writeheader()
    w.writerows(tidy(r) for r in records)
    return buf.getvalue()
