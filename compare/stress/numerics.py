"""Scenario-agnostic numerics of the stress suite, and what a stress experiment is.

An experiment (a scenario's, in the module compare/stress/<scenario>.py that compare/stress/registry.py finds) runs through a context the
driver hands it (``StressContext``: cells, host-loop tasks, row helpers), so that experiments
import neither the driver nor the store, and compare/results/records.py can read their page hooks. What
those experiments share is here.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterable, Protocol

import numpy as np

ORACLE = "oracle64"      # the float64 Python reference, as a row's backend ('host' device)

Row = dict[str, Any]
# the columns of a finding (stress.md, stress.json's analysis.rows), in order
COLUMNS = ("experiment", "backend", "device", "precision", "setting", "figure", "value", "verdict", "detail")
Result = tuple[list[Row], dict[str, Any]]                    # (rows, series for the plot)
Outputs = dict[str, np.ndarray]
Style = Callable[[str], dict[str, Any]]                       # "backend/device/..." -> plot kwargs


class StressContext(Protocol):
    """What an experiment may use: the selection, and the driver's ways to run things."""
    backends: list[str]
    devices: list[str]
    quick: bool

    @property
    def reference(self) -> str: ...
    def why_not(self, backend: str, device: str) -> str | None: ...
    def targets(self, variants: bool = False) -> list[tuple[str, str, str]]: ...
    def precisions(self, backend: str, device: str, wanted: tuple[str, ...]) -> tuple[str, ...]: ...
    def skip_rows(self, experiment: str, variants: bool = False,
                  precisions: tuple[str, ...] = ()) -> list[Row]: ...
    def spec(self, scenario: str, backend: str, device: str, precision: str,
             params: dict[str, Any], variant: str = "default") -> dict[str, Any]: ...
    def row(self, experiment: str, backend: str, device: str, precision: str, setting: str,
            figure: str, value: Any, verdict: str, detail: str | None = "") -> Row: ...
    def label(self, spec_or_rec: dict[str, Any]) -> str: ...
    # a cell's record is a compare.results.record.Record, not imported here: compare/results/records.py imports the
    # experiments to check their findings
    def error_row(self, experiment: str, s: dict[str, Any], setting: str, rec: Any) -> Row: ...
    def fmt(self, x: Any) -> str: ...
    def run_cells(self, specs: list[dict[str, Any]], fresh_process: bool = False
                  ) -> list[tuple[Any, Outputs | None]]: ...
    def map(self, fn: Callable[[Any], Any], items: list[Any]) -> list[Any]: ...
    def run_tasks(self, tasks: list[dict[str, Any]]) -> list[dict[str, Any]]: ...


@dataclasses.dataclass(frozen=True)
class Experiment:
    """One stress experiment: ``run(ctx)`` gives (rows, series); ``plot(series, path, style)``
    draws the series kept in stress.json (so merged parts redraw); ``extra_markdown(rows)`` goes
    above the row table on the page, which shows ``table_rows(rows)`` (default: all rows)."""
    name: str
    title: str
    run: Callable[[StressContext], Result]
    plot: Callable[[dict[str, Any], Path | BinaryIO, Style], None] | None = None
    extra_markdown: Callable[[list[Row]], str] | None = None
    table_rows: Callable[[list[Row]], list[Row]] | None = None


def ulps(out: np.ndarray, ref: np.ndarray, dtype: Any = np.float32) -> np.ndarray:
    """|out - ref| in units of the spacing of ``dtype`` at ref (ulps of the correctly rounded result)."""
    ref = np.asarray(ref, np.float64)
    spacing = np.spacing(np.abs(ref).astype(dtype)).astype(np.float64)
    return np.abs(np.asarray(out, np.float64) - ref) / spacing


def bitwise_differences(a: Outputs, b: Outputs) -> int:
    """Number of elements whose bit patterns differ (NaN == NaN when the bits match); -1 when the
    two sets of outputs do not even have the same names, shapes or dtypes."""
    n = 0
    for k in sorted(set(a) | set(b)):
        if k not in a or k not in b:
            return -1
        x, y = np.ascontiguousarray(a[k]), np.ascontiguousarray(b[k])
        if x.shape != y.shape or x.dtype != y.dtype:
            return -1
        if x.size:
            bx, by = x.view(np.uint8).reshape(x.size, -1), y.view(np.uint8).reshape(y.size, -1)
            n += int(np.sum(np.any(bx != by, axis=1)))
    return n


def log_floor(xs: Iterable[Any], eps: float = 1e-18) -> list[float]:
    """Values for a log axis: at least ``eps`` (an exact 0 stays visible), non-numbers as NaN."""
    return [max(float(x), eps) if isinstance(x, (int, float)) and math.isfinite(x) else math.nan for x in xs]
