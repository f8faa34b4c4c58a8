"""The one engine every suite runs on: plan -> run cells in processes -> store records -> render.

A suite (``compare.run_suite`` for all/<scenario>, ``compare.sweep``, ``compare.stress``) makes a
list of cell specs (``compare.spec.CellSpec``), hands them to ``run_cells``, and renders what
comes back. ``run_cells`` is the only place that starts worker processes: it skips cells whose
backend cannot use the device (a ``skipped`` record with the reason, never a run), runs the rest
one at a time (timed suites) or ``jobs`` at a time with one lane per backend and GPU (the stress
suite, whose figures are not timings), and hands every record to ``on_record`` as it finishes, so
a store can save it before the next cell starts.
"""
from __future__ import annotations

import concurrent.futures
import threading
from typing import Any, Callable, Iterable

import numpy as np

from compare import cells

Outputs = dict[str, np.ndarray]
Result = tuple[dict[str, Any], Outputs | None]


def gpu_lane(spec: dict[str, Any]) -> Any:
    """Cells that must not overlap: those of one backend on one GPU (None: no constraint).

    Frameworks reserve device memory per process: Taichi sizes each kernel's autodiff-stack local
    memory for every thread the GPU can hold resident, so eight Taichi processes on one H100 ran out
    of memory at launch. One process per backend per GPU still lets different backends overlap.
    """
    return None if spec.get("device") in ("cpu", "host") else (spec.get("backend"), spec.get("device"))


def pool_map(fn: Callable[[Any], Any], items: list[Any], jobs: int = 1,
             lane: Callable[[Any], Any] = gpu_lane) -> list[Any]:
    """``fn`` over ``items``, ``jobs`` at a time, items of one ``lane`` (not None) one after another;
    results in the order of ``items``."""
    groups: dict[Any, list[int]] = {}
    for i, it in enumerate(items):
        key = lane(it)
        groups.setdefault(("solo", i) if key is None else key, []).append(i)
    results: list[Any] = [None] * len(items)

    def run_group(idx: list[int]) -> None:
        for i in idx:
            results[i] = fn(items[i])

    if jobs <= 1 or len(groups) <= 1:
        for idx in groups.values():
            run_group(idx)
    else:
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(run_group, groups.values()))
    return results


def availability(names: Iterable[str]) -> dict[str, dict[str, Any]]:
    """backend -> {"available": {device: None | reason}, "versions": {...}}, probed in parallel
    (each backend in its own process: probing imports the framework)."""
    names = list(names)
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, len(names))) as pool:
        return dict(zip(names, pool.map(cells.probe, names)))


def run_cells(specs: list[dict[str, Any]], *, timeout: float, jobs: int = 1,
              probes: dict[str, dict[str, Any]] | None = None,
              on_record: Callable[[int, dict[str, Any], Outputs | None], None] | None = None,
              runner: Callable[[dict[str, Any]], Result] | None = None) -> list[Result]:
    """Run every cell spec in its own worker process; returns (record, outputs) per spec, in order.

    A record always carries the spec's identity (scenario, backend, device, precision, variant)
    and its ``tags``; a backend that cannot use the device gives a ``skipped`` record (reason
    from its probe) without starting a process. ``jobs`` > 1 overlaps cells (only for suites
    whose figures are not timings). ``runner`` replaces the local worker (e.g. a Dask client).
    """
    probes = probes if probes is not None else availability({s["backend"] for s in specs})
    run = runner or (lambda s: cells.run(s, timeout=timeout))
    lock = threading.Lock()
    done: list[Result | None] = [None] * len(specs)

    def one(i: int) -> Result:
        spec = specs[i]
        ident = {k: spec[k] for k in ("scenario", "backend", "device", "precision")}
        ident["variant"] = spec.get("variant", "default")
        if spec.get("tags"):
            ident["tags"] = spec["tags"]
        why = probes.get(spec["backend"], {}).get("available", {}).get(spec["device"], "not probed")
        if why:
            rec: dict[str, Any] = {**ident, "status": "skipped", "reason": why}
            out = None
        else:
            got, out = run(spec)
            rec = {**ident, **got}
        rec.setdefault("reason", "")
        if on_record is not None:
            with lock:
                on_record(i, rec, out)
        done[i] = (rec, out)
        return rec, out

    pool_map(lambda i: one(i), list(range(len(specs))), jobs=jobs,
             lane=lambda i: gpu_lane(specs[i]))
    return [r for r in done if r is not None]
