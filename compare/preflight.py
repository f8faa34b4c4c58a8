"""What a run needs of this machine before any worker starts: host memory per cell worker and for
the outputs the driver keeps, and disk for what the run writes (the suites' preflight).
A plan none of whose cells fits is refused; a cell that does not fit now is skipped, saying so."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import scenarios
from compare import options
from compare.spec import Cell, as_cell
from scenarios.base import ParamError


# Host memory of one worker process beyond its cell's data (Scenario.footprint): the interpreter,
# NumPy, the framework and, on a GPU, its CUDA libraries; about twice the largest measured peak of
# a small cell (docs/reliability.md, "Host memory of CUDA workers").
WORKER_BASELINE_BYTES = {"cpu": 512 * 2**20, "cuda": 1024 * 2**20}
RECORD_BYTES = 64 * 2**10          # one record in results.json, generously (params, info, gradients)
PAGE_BYTES = 32 * 2**20            # results.csv, results.md and the plots of one run


def cell_bytes(spec: Cell | dict[str, Any]) -> tuple[float, float, float]:
    """(worker peak, bytes handed back to the driver, bytes --save-arrays writes) of one cell."""
    cell = as_cell(spec)
    sc, p, prec = scenarios.get(cell.scenario), cell.params, cell.precision
    outputs = sc.output_bytes(p, prec)
    arrays = outputs + sc.input_bytes(p, prec)
    worker = (WORKER_BASELINE_BYTES.get(cell.device, max(WORKER_BASELINE_BYTES.values()))
              + sc.footprint(p, prec, cell.device))
    return worker, (arrays if cell.save_inputs else outputs), arrays


def check_memory(specs: list[Cell | dict[str, Any]], driver: bool = True, worker: bool = True) -> None:
    """Refuse a plan this machine's AVAILABLE memory cannot hold, before any worker starts: the
    largest cell's worker (interpreter and framework + Scenario.footprint, a bound checked
    against measured peaks by tests/test_memory_guard.py) plus, with ``driver``, the outputs the
    driver keeps of every cell until the report is written."""
    import psutil
    if not specs:
        return
    sizes = [cell_bytes(s) for s in specs]
    big = max(range(len(specs)), key=lambda i: sizes[i][0])
    need = (sizes[big][0] if worker else 0.0) + (sum(b for _, b, _ in sizes) if driver else 0.0)
    have = psutil.virtual_memory().available
    if need > have:
        s = as_cell(specs[big])
        sc = scenarios.get(s.scenario)
        what = f"{sc.name} with {sc.size_text(s.params)}"
        parts = ([f"one {s.precision} cell's worker {options.gib(sizes[big][0])}"] if worker else []) + \
                ([f"outputs of {len(specs)} cells kept by the driver {options.gib(sum(b for _, b, _ in sizes))}"]
                 if driver else [])
        raise ParamError(f"{what} needs about {options.gib(need)} of memory ({' + '.join(parts)}); "
                         f"{options.gib(have)} is available")


def memory_refusal() -> Callable[[Cell], tuple[str, str] | None]:
    """A cell whose worker the memory available now cannot hold is skipped, saying so, while
    the plan's other cells run (a plan none of whose cells fits is refused by ``plan``)."""
    import psutil
    have = float(psutil.virtual_memory().available)

    def refuse(cell: Cell) -> tuple[str, str] | None:
        need = cell_bytes(cell)[0]
        if need <= have:
            return None
        return "skipped", (f"needs about {options.gib(need)} of host memory for its worker; "
                           f"{options.gib(have)} is available on this machine")
    return refuse


def disk_need(specs: list[Cell], save_arrays: bool, existing: Path | None = None) -> float:
    """Bytes the run writes at most: results.json (rewritten through a temporary beside it, so
    twice), tables and plots, and with --save-arrays every cell's inputs and outputs."""
    old = existing.stat().st_size if existing is not None and existing.exists() else 0
    need = 2 * (old + RECORD_BYTES * len(specs)) + PAGE_BYTES
    if save_arrays:
        need += sum(cell_bytes(s)[2] for s in specs)
    return need
