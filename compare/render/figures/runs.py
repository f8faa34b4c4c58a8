"""What a scenario's picture is drawn from: (record, outputs) of the runs that kept their outputs."""
from __future__ import annotations

import numpy as np

from backends.base import DEFAULT_VARIANT
from compare.results.record import Record

Runs = list[tuple[Record, dict[str, np.ndarray]]]


def run_label(record: Record) -> str:
    v = record.variant
    return f"{record.backend}/{record.device}/{record.precision}" + ("" if v == DEFAULT_VARIANT else f"/{v}")


def pick_runs(runs: Runs, limit: int) -> Runs:
    """One float32 default-variant run per (backend, device) if there are any, else the first runs."""
    seen, out = set(), []
    for rec, o in runs:
        key = (rec.backend, rec.device)
        if rec.precision == "float32" and rec.variant == DEFAULT_VARIANT and key not in seen:
            seen.add(key); out.append((rec, o))
    return (out or runs)[:limit]
