"""compare/sweep/horizon.py: memory, time and gradient quality against the horizon (fast tier),
on hand-made horizon records and on the site's test store."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from compare.results.record import Record
from compare.results.store import Store
from compare.sweep import horizon, plots

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site" / "sweep.json"


def rec(steps: int, device_bytes: float | None, *, batch: int = 4, contact: str = "hard", device: str = "cuda",
        backend: str = "warp", host_bytes: float | None = None, fd: float | None = 1.0) -> Record:
    return Record(scenario="projectile", backend=backend, device=device, precision="float32", status="ok",
                  params={"steps": steps, "batch": batch, "contact": contact},
                  tags={"sweep": "horizon", "knob": {"name": "steps", "value": steps}},
                  memory={"device_bytes": device_bytes, "host_bytes": host_bytes},
                  gradient={"fd_agreement": fd} if fd is not None else None, error={"vs_oracle": 0.0, "tolerance": 1.0},
                  time={"median_s": 1e-3, "iqr_s": 0.0, "wall": {"median_s": 1e-3, "iqr_s": 0.0}})


def test_memory_is_device_bytes_on_cuda_and_host_bytes_on_the_cpu():
    assert horizon.memory(rec(10, 1e6)) == (1e6, "device")
    assert horizon.memory(rec(10, 1e6, device="cpu", host_bytes=2e6)) == (2e6, "host")
    assert horizon.memory(rec(10, None)) == (None, "device")


def test_slopes_are_bytes_per_item_step_between_horizons():
    rows = [rec(10, 1000.0), rec(20, 1000.0 + 4 * 10 * 8), rec(40, None), rec(80, 5000.0)]
    assert horizon.items(rows[0]) == 4
    assert horizon.slopes(rows) == [None, 8.0, None, None]        # fixed costs cancel; no memory, no slope


def test_series_groups_by_everything_but_the_horizon_sorted_by_it():
    recs = [rec(40, 3.0), rec(10, 1.0), rec(20, 2.0, contact="soft"), rec(10, 1.0, contact="soft"),
            rec(10, 1.0, device="cpu")]
    groups = horizon.series(recs, "cuda", "projectile")
    assert [[r.params["steps"] for r in g] for g in groups.values()] == [[10, 40], [10, 20]]
    assert horizon.varying([r for g in groups.values() for r in g], "steps") == ["contact"]


def test_the_table_names_the_varying_parameter_and_the_slope():
    text = horizon.table([rec(10, 1000.0), rec(20, 1320.0), rec(10, 1000.0, contact="soft", fd=0.5)],
                         "cuda", "projectile")
    head = text.splitlines()[0]
    assert "| contact " in head and " steps |" in head and "bytes per batch-step (slope)" in head
    cells = [[c.strip() for c in line.split("|")[1:-1]] for line in text.splitlines()[2:]]
    names = [h.strip() for h in head.split("|")[1:-1]]
    slope, fd = names.index("bytes per batch-step (slope)"), names.index("FD agreement")
    assert [c[slope] for c in cells] == ["-", "8", "-"] and [c[fd] for c in cells] == ["100 %", "100 %", "50 %"]
    assert horizon.table([], "cuda", "projectile") == ""


def test_the_stored_horizon_sweep_tables_and_plots(tmp_path):
    recs = list(Store.read(STORE, "sweep").records)
    assert "| warp " in horizon.table(recs, "cuda", "projectile")
    assert plots.plot_horizon(recs, "cuda", tmp_path / "h.png", "projectile")
    assert (tmp_path / "h.png").read_bytes().startswith(b"\x89PNG")
    assert not plots.plot_horizon(recs, "cpu", tmp_path / "none.png", "projectile")


def test_gradient_quality_counts_the_cells_past_their_bound_too():
    """A mismatch (error past its bound) still returned a gradient: the agreement band keeps it,
    so a horizon's mean is not left to the frameworks that happened to pass."""
    past = dataclasses.replace(rec(600, None, backend="torch", fd=0.25), status="mismatch")
    cells = horizon.gradient_cells([rec(600, None, fd=0.5), past, rec(600, None, device="cpu")],
                                   "cuda", "projectile")
    assert [(r.backend, r.status) for r in cells] == [("warp", "ok"), ("torch", "mismatch")]
