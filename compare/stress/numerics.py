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
from typing import Any, BinaryIO, Callable, Iterable, Mapping, Protocol, Sequence, TypedDict, TypeVar, cast

import numpy as np

from compare.results.analysis import Finding, Series, Value
from compare.results.record import Record
from compare.results.record_parts import Check
from compare.spec import Cell

ORACLE = "oracle64"      # the float64 Python reference, as a row's backend ('host' device)

# a cell's parameter overrides (the scenario resolves and checks them: ``Scenario.params``)
Overrides = Mapping[str, int | float | str | bool]
Outputs = dict[str, np.ndarray]


@dataclasses.dataclass(frozen=True)
class Row:
    """One finding as an experiment makes it; ``to_json`` is its form in the file (``Finding``)."""
    experiment: str
    backend: str
    device: str
    precision: str
    setting: str
    figure: str
    value: Value
    verdict: str
    detail: str = ""

    def to_json(self) -> Finding:
        """The stored form: the COLUMNS, in their order (``Finding`` lists the same columns: a
        test holds the two together)."""
        return cast(Finding, {c: getattr(self, c) for c in COLUMNS})


# the columns of a finding (stress.md, stress.json's analysis.rows), in order
COLUMNS = tuple(f.name for f in dataclasses.fields(Row))
Result = tuple[list[Row], Series]                    # (rows, series for the plot)


class PlotStyle(TypedDict):
    """A line's matplotlib keywords: one colour per backend, one marker per device."""
    color: str
    marker: str | None
    markersize: float


Style = Callable[[str], PlotStyle]                       # "backend/device/..." -> plot kwargs


# a host-loop task or its answer as JSON: what is sent to and read back from the worker process
Payload = dict[str, Any]
_R = TypeVar("_R", covariant=True)
_I = TypeVar("_I")
_O = TypeVar("_O")


class HostTask(Protocol[_R]):
    """A host-loop task (``compare.stress.host_loop``): where it runs (``backend``, ``device``:
    its lane and worker environment), its JSON for the worker, and the decode of the worker's
    answer (which may be only ``{"error": ...}``: the worker crashed, hung or raised)."""
    @property
    def backend(self) -> str: ...
    @property
    def device(self) -> str: ...
    def to_json(self) -> Payload: ...
    def outcome(self, result: Payload) -> _R: ...


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
             params: Overrides, variant: str = "default") -> Cell: ...
    def row(self, experiment: str, backend: str, device: str, precision: str, setting: str,
            figure: str, value: Any, verdict: str, detail: str | None = "") -> Row: ...
    def label(self, cell: Cell) -> str: ...
    def error_row(self, experiment: str, cell: Cell, setting: str, rec: Record) -> Row: ...
    def fmt(self, x: Any) -> str: ...
    def run_cells(self, specs: list[Cell], fresh_process: bool = False
                  ) -> list[tuple[Record, Outputs | None]]: ...
    def map(self, fn: Callable[[_I], _O], items: list[_I]) -> list[_O]: ...
    def run_tasks(self, tasks: Sequence[HostTask[_O]]) -> list[_O]: ...


@dataclasses.dataclass(frozen=True)
class Experiment:
    """One stress experiment: ``run(ctx)`` gives (rows, series); ``plot(series, path, style)``
    draws the series kept in stress.json (so merged parts redraw); ``extra_markdown(rows)`` goes
    above the row table on the page, which shows ``table_rows(rows)`` (default: all rows);
    ``look`` is the sentence under the plot that says what to see in it."""
    name: str
    title: str
    run: Callable[[StressContext], Result]
    plot: Callable[[Series, Path | BinaryIO, Style], None] | None = None
    extra_markdown: Callable[[list[Finding]], str] | None = None
    table_rows: Callable[[list[Finding]], list[Finding]] | None = None
    look: str = ""


def check_of(rec: Record) -> Check:
    """The check block (``error``) of a cell that ran: every record of one that did not fail has it."""
    if rec.error is None:
        raise ValueError(f"the {rec.backend}/{rec.device} {rec.scenario} record has no check block")
    return rec.error


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
