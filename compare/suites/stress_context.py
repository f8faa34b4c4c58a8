"""The context every stress experiment runs in: which backends and devices, and how to run things.

Experiments (``compare.stress.numerics.Experiment``) receive a ``Ctx`` and use only its methods
(``numerics.StressContext``) and pure numerics, so the modules that define them never import the
driver. Cells
go through ``compare.running.engine.run_cells`` (a worker process per cell, ``jobs`` at a time, one lane
per backend and GPU); host work and host-loop tasks through the same lanes.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, Sequence, TypeVar

import numpy as np

import backends
from backends.base import DEFAULT_VARIANT
from compare.running import engine
from compare.results.record import Record
from compare.render.report import fmt_num
from compare.results.store import Store
from compare.spec import Cell
from compare.stress import host_loop
from compare.stress.numerics import HostTask, Outputs, Overrides, Row

_In = TypeVar("_In")
_Out = TypeVar("_Out")


def lane(item: object) -> engine.Lane:
    """Items that must not overlap (``engine.device_lane``): a cell, a host-loop task
    (``HostTask``: its backend and device) or a (backend, device, ...) tuple; any other item
    (host work of no device) has no constraint."""
    if isinstance(item, Cell):
        return engine.gpu_lane(item)
    backend, device = (item[:2] if isinstance(item, tuple) and len(item) >= 2 else
                       (getattr(item, "backend", None), getattr(item, "device", None)))
    return engine.device_lane(backend, device) if isinstance(backend, str) and isinstance(device, str) else None


@dataclasses.dataclass
class Ctx:
    backends: list[str]
    devices: list[str]
    quick: bool
    jobs: int
    timeout: float
    probes: engine.Probes
    store: Store | None = None
    # the suite's per-record hook (``driver.Suite.on_record``): every cell's record passes it
    on_record: Callable[[int, Record, Outputs | None], Record] | None = None

    @property
    def reference(self) -> str:
        return backends.reference()

    def why_not(self, backend: str, device: str) -> str | None:
        return self.probes[backend]["available"].get(device)

    def targets(self, variants: bool = False) -> list[tuple[str, str, str]]:
        """(backend, device, variant) that can run, reference first; with ``variants`` every
        variant the backend offers on that device."""
        out = []
        for d in self.devices:
            for b in self.backends:
                if self.why_not(b, d):
                    continue
                be = backends.get(b)
                out += [(b, d, v) for v in (be.variants if variants else ("default",))
                        if not be.variant_unavailable(v, d)]
        return out

    @staticmethod
    def precisions(backend: str, device: str, wanted: tuple[str, ...]) -> tuple[str, ...]:
        """The precisions of ``wanted`` that the framework has on that device (MLX: no float64
        on a GPU); skip_rows(..., precisions=wanted) says why the others are missing."""
        be = backends.get(backend)
        return tuple(p for p in wanted if not be.precision_unavailable(p, device))

    def skip_rows(self, experiment: str, variants: bool = False,
                  precisions: tuple[str, ...] = ()) -> list[Row]:
        """A ``skipped`` row, with its reason, per backend and device that cannot run (and, with
        ``variants``, per variant that the framework lacks on that device; with ``precisions``,
        per precision of them that it lacks there)."""
        rows = [self.row(experiment, b, d, "-", "-", "-", None, "skipped", self.why_not(b, d))
                for d in self.devices for b in self.backends if self.why_not(b, d)]
        rows += [self.row(experiment, b, d, p, "-", "-", None, "skipped",
                          backends.get(b).precision_unavailable(p, d))
                 for d in self.devices for b in self.backends if not self.why_not(b, d)
                 for p in precisions if backends.get(b).precision_unavailable(p, d)]
        if variants:
            rows += [self.row(experiment, b, d, "-", f"variant={v}", "-", None, "skipped",
                              backends.get(b).variant_unavailable(v, d))
                     for d in self.devices for b in self.backends if not self.why_not(b, d)
                     for v in backends.get(b).variants if backends.get(b).variant_unavailable(v, d)]
        return rows

    @staticmethod
    def spec(scenario: str, backend: str, device: str, precision: str, params: Overrides,
             variant: str = "default") -> Cell:
        """The cell of ``params`` (overrides of the scenario's defaults, resolved here)."""
        # Timing is not measured here: the first call and one timed call, no warm-ups (an eager
        # PyTorch descent costs seconds a call on CUDA), and the frameworks' kernel caches stay
        # warm so cells do not recompile the same kernels.
        return Cell.make(scenario, backend, device, precision, variant, dict(params), quick=False,
                         warmup=0, repeat=1, min_time=0.0, cache="warm", timer="wall", throughput=False)

    @staticmethod
    def row(experiment: str, backend: str, device: str, precision: str, setting: str, figure: str,
            value: Any, verdict: str, detail: str | None = "") -> Row:
        """A finding; a NumPy scalar value becomes its Python number, a missing detail ''."""
        if isinstance(value, (np.floating, np.integer)):
            value = value.item()
        return Row(experiment, str(backend), str(device), str(precision), setting, figure, value, verdict,
                   detail or "")

    @staticmethod
    def label(cell: Cell) -> str:
        return f"{cell.backend}/{cell.device}" + ("" if cell.variant == DEFAULT_VARIANT else f"/{cell.variant}")

    def error_row(self, experiment: str, cell: Cell, setting: str, rec: Record) -> Row:
        return self.row(experiment, cell.backend, cell.device, cell.precision, setting,
                        "cell", None, "error", rec.reason)

    @staticmethod
    def fmt(x: Any) -> str:
        return fmt_num(x)

    def run_cells(self, specs: list[Cell], fresh_process: bool = False
                  ) -> list[tuple[Record, Outputs | None]]:
        """(record, outputs) per spec, in order. Stress figures are not timings, so cells of one
        backend, device, precision and variant share a worker process (the framework starts once),
        unless ``fresh_process`` (run-to-run comparisons want two separate processes). Every
        record also goes into the suite's store."""
        return engine.run_cells(specs, timeout=self.timeout, jobs=self.jobs, probes=self.probes,
                                share_process=not fresh_process, store=self.store, on_record=self.on_record)

    def map(self, fn: Callable[[_In], _Out], items: list[_In]) -> list[_Out]:
        """``fn`` over ``items`` on threads, ``--jobs`` at a time, one GPU item per backend at a time
        (stress figures are not timings); results in the order of ``items``."""
        return engine.pool_map(fn, items, jobs=self.jobs, lane=lane)

    def run_tasks(self, tasks: Sequence[HostTask[_Out]]) -> list[_Out]:
        """Host-loop tasks (``compare.stress.host_loop``), each in its own worker process."""
        def one(task: HostTask[_Out]) -> _Out:
            return host_loop.run(task, timeout=self.timeout)
        return self.map(one, list(tasks))
