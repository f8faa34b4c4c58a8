"""What a run needs of this machine before any worker starts: host memory per cell worker and for
the outputs the driver keeps, and disk for what the run writes (the suites' preflight).
A plan none of whose cells fits is refused; a cell that does not fit now is skipped, saying so.

A worker's memory is first bounded by its scenario's model (``cell_bytes``: the same for every
framework, the largest tape any port keeps). A big cell (one with a miniature, compare.planning.calibrate)
over that bound is then judged by its own framework and variant: its miniatures at 1/64 and 1/256
of its size are run, and their measured peaks extrapolated (``measured_need``). A cell whose
framework-independent part alone (``floor_bytes``, which every estimate includes) exceeds what is
available is refused from the model at once: no miniature could change that verdict."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

import scenarios
from compare.planning import calibrate, outdir
from compare.spec import Cell
from scenarios.base import ParamError

# The two miniature sizes of the memory estimate: the slope between them, where the fixed costs
# (interpreter, framework, compiler) cancel, times the big cell's size, and a margin on that slope:
# allocators keep more per item as arrays grow (PyTorch's float32 projectile tape: 4.6 kB per
# trajectory between B = 4096 and 16384, 8.2 kB between 16384 and 65536).
MEMORY_FACTORS = (calibrate.FACTOR, 4 * calibrate.FACTOR)
SLOPE_MARGIN = 2.0


# Host memory of one worker process beyond its cell's data (Scenario.footprint): the interpreter,
# NumPy, the framework and, on a GPU, its CUDA libraries; about twice the largest measured peak of
# a small cell (docs/reliability.md, "Host memory of CUDA workers").
WORKER_BASELINE_BYTES = {"cpu": 512 * 2**20, "cuda": 1024 * 2**20}
RECORD_BYTES = 64 * 2**10          # one record in results.json, generously (params, info, gradients)
PAGE_BYTES = 32 * 2**20            # results.csv, results.md and the plots of one run
# the stress suite's cell records and findings, generously (the CPU suite's stress.json is ~1 MB),
# and its page and plots
STRESS_BYTES = 256 * 2**20


def cell_bytes(cell: Cell) -> tuple[float, float, float]:
    """(worker peak, bytes handed back to the driver, bytes --save-arrays writes) of one cell."""
    sc, p, prec = scenarios.get(cell.scenario), cell.params, cell.precision
    outputs = sc.output_bytes(p, prec)
    arrays = outputs + sc.input_bytes(p, prec)
    worker = (WORKER_BASELINE_BYTES.get(cell.device, max(WORKER_BASELINE_BYTES.values()))
              + sc.footprint(p, prec, cell.device))
    return worker, (arrays if cell.save_inputs else outputs), arrays


def available() -> float:
    import psutil
    return float(psutil.virtual_memory().available)


def measured_later(cell: Cell, have: float) -> bool:
    """A big cell whose model bound exceeds ``have``: its miniatures decide (``measured_need``)."""
    return cell_bytes(cell)[0] > have and calibrate.miniature(cell) is not None


def floor_bytes(cell: Cell) -> float:
    """The least host memory the cell's worker needs whatever its framework: the scenario's model
    without the framework's working copies (Scenario.footprint as on a GPU: the check's arrays,
    inputs and outputs), which ``measured_need`` adds in full to every miniature estimate."""
    sc = scenarios.get(cell.scenario)
    return min(cell_bytes(cell)[0], sc.footprint(cell.params, str(cell.precision), "cuda"))


def least_need(cell: Cell, have: float) -> float:
    """What the cell's worker needs at least: the model bound, or for a cell its miniatures judge
    later, the floor no framework goes under (``floor_bytes``)."""
    return floor_bytes(cell) if measured_later(cell, have) else cell_bytes(cell)[0]


def _floor_text(cell: Cell, have: float) -> str:
    return (f"needs about {outdir.gib(floor_bytes(cell))} of host memory for its worker whatever its "
            f"framework (the check's arrays, inputs and outputs, before any framework's own copies: about "
            f"{outdir.gib(cell_bytes(cell)[0])} with the largest port's); {outdir.gib(have)} is available "
            f"on this machine")


def check_smallest(specs: list[Cell]) -> None:
    """Refuse a plan whose smallest worker cannot fit, before anything runs: a cell its miniatures
    judge later by its floor (``floor_bytes``), so a hopeless plan is refused without running
    any (a plan none of whose cells fits by the miniatures' estimates is refused there)."""
    if not specs:
        return
    have = available()
    s = min(specs, key=lambda s: least_need(s, have))
    if not measured_later(s, have):
        check_memory([s], driver=False)
    elif floor_bytes(s) > have:
        sc = scenarios.get(s.scenario)
        raise ParamError(f"{sc.name} with {sc.size_text(s.params)} ({s.precision}) {_floor_text(s, have)}")


def check_memory(specs: Sequence[Cell], driver: bool = True, worker: bool = True) -> None:
    """Refuse a plan this machine's AVAILABLE memory cannot hold, before any worker starts: the
    largest cell's worker (interpreter and framework + Scenario.footprint, a bound checked
    against measured peaks by tests/planning/test_preflight.py; a cell its miniatures judge later left
    out) plus, with ``driver``, the outputs the driver keeps of every cell until the report is
    written."""
    if not specs:
        return
    have = available()
    sizes = [cell_bytes(s) for s in specs]
    workers = [i for i, s in enumerate(specs) if not measured_later(s, have)]
    big = max(workers or range(len(specs)), key=lambda i: sizes[i][0])
    need = (sizes[big][0] if worker and workers else 0.0) + (sum(b for _, b, _ in sizes) if driver else 0.0)
    if need > have:
        s = specs[big]
        sc = scenarios.get(s.scenario)
        what = f"{sc.name} with {sc.size_text(s.params)}"
        parts = ([f"one {s.precision} cell's worker {outdir.gib(sizes[big][0])}"] if worker and workers else []) + \
                ([f"outputs of {len(specs)} cells kept by the driver {outdir.gib(sum(b for _, b, _ in sizes))}"]
                 if driver else [])
        raise ParamError(f"{what} needs about {outdir.gib(need)} of memory ({' + '.join(parts)}); "
                         f"{outdir.gib(have)} is available")


def memory_refusal(measured: Callable[[Cell], float | None] | None = None
                   ) -> Callable[[Cell], tuple[str, str] | None]:
    """A cell whose worker the memory available now cannot hold is skipped, saying so, while
    the plan's other cells run. ``measured``: a big cell's estimate from its miniatures
    (``measured_need``); without it a big cell over the model bound is not refused yet."""
    have = available()

    def refuse(cell: Cell) -> tuple[str, str] | None:
        need, how = cell_bytes(cell)[0], ""
        if need <= have:
            return None
        if measured_later(cell, have):
            if floor_bytes(cell) > have:      # no miniature can bring it under: not run
                return "skipped", _floor_text(cell, have)
            got = measured(cell) if measured is not None else 0.0
            if got is not None:           # None: its miniatures failed; the model bound decides
                if got <= have:
                    return None
                need, how = got, f" (its {cell.backend} runs at 1/{MEMORY_FACTORS[0]} and 1/{MEMORY_FACTORS[1]} of its size, scaled)"
        return "skipped", (f"needs about {outdir.gib(need)} of host memory for its worker{how}; "
                           f"{outdir.gib(have)} is available on this machine")
    return refuse


def measured_need(plan: list[Cell], timeout: float | None, minis: calibrate.Miniatures | None = None,
                  run: Callable[[Cell], Any] | None = None) -> Callable[[Cell], float | None]:
    """Each big cell of ``plan`` over the model bound, estimated from its own framework's
    miniatures (``minis``: those at 1/64 already run): the larger one's measured peak, plus the
    slope between the two (times SLOPE_MARGIN) up to the cell's size, plus the check's arrays at
    full size (Scenario.footprint on a GPU, where the port's working copies are not host
    memory: the miniatures are not checked). None where a miniature failed (the one at 1/256 is
    then not run). A cell over its floor (``floor_bytes``) runs none: it is refused whatever they find."""
    have = available()
    todo = [c for c in plan if measured_later(c, have) and floor_bytes(c) <= have]
    big = {**calibrate.run_miniatures([c for c in todo if calibrate.key(c) not in (minis or {})],
                                      timeout, MEMORY_FACTORS[0], run), **(minis or {})}
    small = calibrate.run_miniatures([c for c in todo if _ran(big.get(calibrate.key(c)))],
                                     timeout, MEMORY_FACTORS[1], run)
    needs = {calibrate.key(c): _extrapolate(c, big.get(calibrate.key(c)), small.get(calibrate.key(c)))
             for c in todo}
    return lambda cell: needs.get(calibrate.key(cell))


def _ran(got: calibrate.Miniature | None) -> bool:
    return got is not None and bool(got.peak_host_rss_bytes) and got.status in ("ok", "mismatch")


def _extrapolate(cell: Cell, a: calibrate.Miniature | None, b: calibrate.Miniature | None) -> float | None:
    points = []
    for got in (a, b):
        if got is None or not _ran(got):       # a miniature that did not run, or failed
            return None
        points.append((calibrate.items(got.cell), float(got.peak_host_rss_bytes or 0.0)))
    (n1, m1), (n0, m0) = points
    if n1 <= n0:
        return None
    slope = max(0.0, (m1 - m0) / (n1 - n0))
    sc = scenarios.get(cell.scenario)
    check = sc.footprint(cell.params, str(cell.precision), "cuda")
    return m1 + SLOPE_MARGIN * slope * max(0.0, calibrate.items(cell) - n1) + check


def disk_need(specs: list[Cell], save_arrays: bool, existing: Path | None = None) -> float:
    """Bytes the run writes at most: results.json (rewritten through a temporary beside it, so
    twice), tables and plots, and with --save-arrays every cell's inputs and outputs."""
    old = existing.stat().st_size if existing is not None and existing.exists() else 0
    need: float = 2 * (old + RECORD_BYTES * len(specs)) + PAGE_BYTES
    if save_arrays:
        need += sum(cell_bytes(s)[2] for s in specs)
    return need
