"""The one engine every suite runs on: cells in worker processes -> records -> store.

A suite (``compare.suites.driver.Suite``: all/<scenario>, sweep, stress) plans a list of cells
(``compare.spec.Cell``: parameters resolved, typed); the driver (``compare.suites.driver.drive``) hands
them to ``run_cells`` and the suite renders what comes back. ``run_cells`` is the only place that starts worker processes: it skips cells whose
backend cannot use the device (a ``skipped`` record with the reason, never a run), runs the rest
one at a time (timed suites) or ``jobs`` at a time with one lane per backend and GPU (the stress
suite, whose figures are not timings), and hands every record to ``on_record`` as it finishes, so
a store can save it before the next cell starts.
"""
from __future__ import annotations

import concurrent.futures
import threading
from typing import Any, Callable, Hashable, Iterable, TypeVar

import numpy as np

import backends
import scenarios
from compare.running import cells
from compare.results.record import Record, RecordError
from compare.spec import IDENTITY, Cell, Identity, key
from compare.results.store import Store, jsonable

Outputs = dict[str, np.ndarray]
Result = tuple[Record, Outputs | None]


Probe = cells.Probe
Probes = dict[str, Probe]       # backend -> its probe


Lane = tuple[str, str] | None      # (backend, GPU) whose items run one after another; None: free
T = TypeVar("T")
R = TypeVar("R")


def device_lane(backend: str, device: str) -> Lane:
    """The lane of work of ``backend`` on ``device``: one per backend per GPU (None: no constraint).

    Frameworks reserve device memory per process (some size local memory for every thread the GPU
    can hold resident: docs/stress.md, "Running it on a GPU"), so several processes of one framework on one GPU can run
    out of memory at launch. One process per backend per GPU still lets different backends overlap.
    """
    return None if device in ("cpu", "host") else (backend, device)


def gpu_lane(cell: Cell) -> Lane:
    """Cells that must not overlap: those of one backend on one GPU (``device_lane``)."""
    return device_lane(cell.backend, str(cell.device))


def cell_lane(cell: Cell) -> Lane:
    """Cells whose workers must not overlap (``overlap.run_overlapped``): those of one backend on
    one GPU, and those that share a kernel-cache directory (``Cell.cache_dir``: a later one starts
    from what the earlier one left, so it starts once that one has gone)."""
    return gpu_lane(cell) or (("caches", cell.cache_dir) if cell.cache_dir else None)


def pool_map(fn: Callable[[T], R], items: list[T], *, lane: Callable[[T], Hashable | None],
             jobs: int = 1) -> list[R]:
    """``fn`` over ``items``, ``jobs`` at a time, items of one ``lane`` (not None) one after another;
    results in the order of ``items``."""
    groups: dict[Hashable, list[int]] = {}
    for i, it in enumerate(items):
        key = lane(it)
        groups.setdefault(("solo", i) if key is None else key, []).append(i)
    results: dict[int, R] = {}

    def run_group(idx: list[int]) -> None:
        for i in idx:
            results[i] = fn(items[i])

    if jobs <= 1 or len(groups) <= 1:
        for idx in groups.values():
            run_group(idx)
    else:
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(run_group, groups.values()))
    return [results[i] for i in range(len(items))]


def availability(names: Iterable[str]) -> Probes:
    """backend -> {"available": {device: None | reason}, "versions": {...}}, probed in parallel
    (each backend in its own process: probing imports the framework)."""
    names = list(names)
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, len(names))) as pool:
        return dict(zip(names, pool.map(cells.probe, names)))


def not_runnable(cell: Cell, probes: Probes) -> tuple[str, str] | None:
    """(status, reason) of a cell that must not start: its backend cannot use the device, or has
    no kernel file for the scenario (an error for a scenario every backend must have, a skip for
    a measurement-only one)."""
    available = probes[cell.backend].get("available", {}) if cell.backend in probes else {}
    why = available.get(cell.device, "device not probed")
    if why:
        return "skipped", why
    be = backends.get(cell.backend)
    why = be.variant_unavailable(cell.variant, cell.device) or be.precision_unavailable(cell.precision, cell.device)
    if why:
        return "skipped", why
    if not be.has_kernel(cell.scenario):
        where = f"{type(be).__module__.replace('.', '/')}/{cell.scenario}.py"
        if scenarios.get(cell.scenario).in_all:
            return "error", f"contract: no {where} (every backend needs one per scenario in 'all')"
        return "skipped", f"no {where} (optional: measurement-only scenario)"
    return None


# obj: a record's JSON as the worker wrote it (record.json, from its process) or an on_record
# hook's record written back (its figures may be NumPy scalars: the one loader checks them again)
def typed(obj: dict[str, Any], ident: Identity,
          check: Callable[[dict[str, Any]], str | None] | None) -> Record:   # a check of that JSON
    """A cell's record, checked; one that no reader could load fails its cell, not the whole file."""
    try:
        return Record.from_json(obj, check=check)
    except RecordError as exc:
        return Record.from_json({**ident, "status": "error", "reason": f"malformed record: {exc}",
                                 "time": None, "error": None})


def run_cells(specs: Iterable[Cell], *, timeout: float, jobs: int = 1,
              probes: Probes | None = None,
              on_record: Callable[[int, Record, Outputs | None], Record] | None = None,
              check: Callable[[dict[str, Any]], str | None] | None = None,  # of stored JSON
              runner: Callable[[Cell], cells.Result] | None = None,
              store: Store | None = None, resume: bool = False,
              share_process: bool = False,
              refuse: Callable[[Cell], tuple[str, str] | None] | None = None,
              ahead: int = 0, footprint: Callable[[Cell], float] | None = None) -> list[Result]:
    """Run every cell in a worker process; returns (record, outputs) per cell, in order.

    A record always carries the cell's identity (scenario, backend, device, precision, variant,
    resolved params, tags). A cell that must not start (``not_runnable``) gets its record without
    a process. ``jobs`` > 1 overlaps cells, and ``share_process`` lets warm-cache cells of one
    backend, device, precision and variant share one worker (``cells.run_batch``): both only for
    suites whose figures are not timings. ``runner`` replaces the local worker (e.g. a Dask
    client). With a ``store``, every record is put and saved as it arrives (a killed run keeps
    what finished), and with ``resume`` a cell the store holds as ok/mismatch/skipped is not run
    again (its record is returned, outputs None, without ``on_record``); error records are retried.
    ``refuse``: the caller's own reason not to start a cell (e.g. the memory it needs), as
    ``not_runnable``'s. ``ahead`` > 0 (timed suites, one cell at a time): up to that many
    workers start before their turn, their untimed parts overlapped and their clocks never
    (``compare.running.overlap``); ``footprint``: a worker's host-memory estimate, which bounds them.
    Every record is typed once (``Record.from_json``, with ``check``: its suite's own check,
    ``compare.results.formats``); ``on_record`` maps it to the record the store keeps (a function from
    Record to Record: it may add a yardstick, a run stamp, a converged error), checked again;
    a record that fails a check becomes an ``error`` record of its cell. The plan runs once: the
    repeats across processes (--processes) are the driver's (``compare.suites.driver.more_processes``).
    """
    plan = list(specs)
    probes = probes if probes is not None else availability({c.backend for c in plan})
    lock = threading.Lock()
    done: list[Result | None] = [None] * len(plan)
    failed: list[BaseException] = []
    idents = [c.identity() for c in plan]

    # got: the worker's record JSON (cells.Result: read from its process's record.json), or the
    # status and reason of a cell that never started, in that JSON's shape
    def finish(i: int, got: dict[str, Any], out: Outputs | None, flush: bool = True) -> None:
        inputs = got.pop("_inputs", None)     # --save-arrays: kept beside the outputs
        if inputs and out is not None:
            out = {**inputs, **out}
        rec = {**got, **idents[i]}
        rec.setdefault("reason", "")
        for k in ("time", "error"):
            rec.setdefault(k, None)
        rec = jsonable(rec)
        with lock:
            if failed:                            # the store could not save (a full disk): no
                raise failed[0]                   # other cell's record may pretend to be kept
            record = typed(rec, idents[i], check)
            if on_record is not None:             # first: it may add to the record (a sweep's
                # converged error) before the store keeps it; its figures may be NumPy scalars
                record = typed(jsonable(on_record(i, record, out).to_json()), idents[i], check)
            if store is not None:
                store.put(record)
                try:
                    if flush:
                        store.save()
                except BaseException as exc:
                    failed.append(exc)
                    raise
        done[i] = (record, out)

    groups: dict[tuple[str | int, ...], list[int]] = {}     # (backend, device, precision, variant) or ("solo", i)
    deferred = False
    for i, cell in enumerate(plan):
        if store is not None and resume and store.done(key(idents[i])):
            kept = store.get(key(idents[i]))
            assert kept is not None               # done() is true only for a record it holds
            done[i] = (kept, None)                # as read and checked (Store.read), not run again
            continue
        blocked = not_runnable(cell, probes) or (refuse(cell) if refuse is not None else None)
        if blocked:       # nothing ran: saved once with the others below, not a file write each
            finish(i, {"status": blocked[0], "reason": blocked[1]}, None, flush=False)
            deferred = True
            continue
        shared = share_process and runner is None and cell.cache == "warm"
        group = (cell.backend, cell.device, cell.precision, cell.variant) if shared else ("solo", i)
        groups.setdefault(group, []).append(i)

    if store is not None and deferred:
        store.save()

    def run_group(idx: list[int]) -> None:
        if runner is not None:
            for i in idx:
                finish(i, *runner(plan[i]))
        else:
            cells.run_batch([plan[i] for i in idx], timeout,
                            on_result=lambda k, result: finish(idx[k], *result))

    solo = [idx[0] for idx in groups.values() if len(idx) == 1]
    if ahead > 0 and runner is None and jobs <= 1 and len(solo) == len(groups) and len(solo) > 1:
        from compare.running import overlap
        overlap.run_overlapped([plan[i] for i in solo], timeout, lambda k, res: finish(solo[k], *res),
                               ahead, need=footprint, budget=overlap.memory_budget(), lane=cell_lane)
    else:
        pool_map(run_group, list(groups.values()), jobs=jobs, lane=lambda g: gpu_lane(plan[g[0]]))
    return [r for r in done if r is not None]


QUIET_LINE_S = 300.0     # not a terminal: a progress line at least this often while cells run


def progress(total: int, label: Callable[[Record], str] | None = None, every: bool = True
             ) -> Callable[[int, Record, Outputs | None], None]:
    """An ``on_record`` that reports each finished cell on stderr: a tqdm bar on a terminal, one
    line per cell otherwise (CI logs). ``label``: a record's name (default: its identity).
    ``every=False`` (not a terminal): a line per quarter of the cells that run (the skipped ones
    come first, all at once, and are only counted), one at least every QUIET_LINE_S, and one per
    failed cell."""
    import os
    import sys
    import time
    quiet = bool(os.environ.get("CI")) or not sys.stderr.isatty()
    bar = None
    if not quiet:
        from tqdm import tqdm
        bar = tqdm(total=total, unit="cell", file=sys.stderr)
    seen = {"skipped": 0, "ran": 0, "part": 0, "at": time.monotonic()}

    def on_record(i: int, rec: Record, out: Outputs | None) -> None:
        name = label(rec) if label else "/".join(str(rec.identity.get(k)) for k in IDENTITY)
        if bar is not None:
            bar.set_description(name)
            bar.update(1)
            if bar.n >= total:
                bar.close()
            return
        if every or rec.status in ("error", "mismatch"):
            print(f"  [{i + 1}/{total}] {name}: {rec.status} {rec.reason or ''}".rstrip(), file=sys.stderr,
                  flush=True)
            if every:
                return
        if rec.status == "skipped" and not seen["ran"]:
            seen["skipped"] += 1
            return
        seen["ran"] += 1
        runs = max(total - seen["skipped"], 1)
        part, now = seen["ran"] * 4 // runs, time.monotonic()
        if part > seen["part"] or now - seen["at"] >= QUIET_LINE_S:
            seen["part"], seen["at"] = part, now
            print(f"  {seen['ran']}/{runs} cells run ({seen['skipped']} skipped; last: {name}: {rec.status})",
                  file=sys.stderr, flush=True)
    return on_record
