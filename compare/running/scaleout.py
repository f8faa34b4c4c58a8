"""Cells as tasks on a Dask cluster, never two timed cells on one GPU or one CPU core set.

``--scheduler local`` starts a cluster on this host with one single-threaded worker per GPU that
NVML sees (the dask-cuda pattern, without its dependencies): worker i sees only GPU i
(``CUDA_VISIBLE_DEVICES``), owns the i-th slice of this process's CPU cores (``COMPARE_CPU_SET``,
applied by the cell's worker process before any framework starts), and declares one ``GPU``
resource. With no GPU it is one worker, as before. ``--scheduler ADDRESS`` uses a running
cluster; start one worker per GPU yourself, each with ``--nthreads 1 --resources GPU=1``, its
``CUDA_VISIBLE_DEVICES`` and a disjoint core set (``taskset -c``), as docs/measurement.md shows.

Placement: where some worker declares ``GPU``, a CUDA cell asks for one, so the scheduler never
runs two at once on a GPU, and cells run side by side only on different workers, i.e. different
GPUs and core sets. Where none does (a CPU-only or undeclared cluster), cells go one at a time,
each submitted when the previous one has finished: slower, never overlapping.
"""
from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Any, Callable, TypedDict

from backends.base import visible_gpus
from compare.spec import Cell
from scenarios.base import ParamError

if TYPE_CHECKING:       # the worker imports this module: not the engine with it
    from compare.running.engine import Probes

CPU_SET_ENV = "COMPARE_CPU_SET"


def core_sets(n: int, cores: list[int] | None = None) -> list[list[int]]:
    """This process's CPU cores cut into ``n`` contiguous, disjoint, near-equal slices."""
    cores = sorted(os.sched_getaffinity(0)) if cores is None else cores
    n = max(1, min(n, len(cores)))
    size, extra = divmod(len(cores), n)
    out, start = [], 0
    for i in range(n):
        end = start + size + (1 if i < extra else 0)
        out.append(cores[start:end])
        start = end
    return out


def apply_cpu_set() -> None:
    """In a cell's worker process: keep to the core set its Dask worker owns, if any."""
    spec = os.environ.get(CPU_SET_ENV)
    if spec:
        os.sched_setaffinity(0, {int(c) for c in spec.split(",") if c.strip()})


def local_cluster() -> Any:
    """One single-threaded worker per GPU, each pinned to its GPU and core set (or one worker)."""
    from distributed import LocalCluster, Nanny, Scheduler, SpecCluster
    gpus = visible_gpus()
    if gpus <= 1:
        return LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                            resources={"GPU": 1} if gpus else None)
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    ids = [d.strip() for d in visible.split(",")] if visible else [str(i) for i in range(gpus)]
    sets = core_sets(len(ids))
    workers = {f"gpu{i}": {"cls": Nanny, "options": {
        "nthreads": 1, "resources": {"GPU": 1},
        "env": {"CUDA_VISIBLE_DEVICES": gpu, CPU_SET_ENV: ",".join(map(str, sets[i % len(sets)]))}}}
        for i, gpu in enumerate(ids)}
    return SpecCluster(workers=workers, scheduler={"cls": Scheduler, "options": {"dashboard_address": None}})


def client(scheduler: str) -> Any:
    """A Dask distributed client (``local``: ``local_cluster``); a bad or unreachable address is
    a one-line ParamError, before anything is written."""
    try:
        from distributed import Client
    except ImportError:
        raise ParamError("--scheduler needs the 'distributed' package (pip install -e '.[dask]')") from None
    if scheduler == "local":
        return Client(local_cluster())
    try:
        return Client(scheduler, timeout="30s")
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        first = (str(exc).splitlines() or [""])[0]
        raise ParamError(f"--scheduler {scheduler}: cannot connect ({type(exc).__name__}: {first})") from None


def gpu_workers(c: Any) -> int:
    """Workers of the cluster that declare a GPU resource."""
    info = c.scheduler_info().get("workers", {})
    return sum(1 for w in info.values() if (w.get("resources") or {}).get("GPU"))


class Placement(TypedDict):
    """What a run's environment records of its cluster (``scheduler``, beside its address)."""
    workers: int
    gpu_workers: int
    mode: str
    worker_names: list[str]


def placement(c: Any) -> Placement:
    """What the run's environment records about the cluster: workers, GPU workers, mode."""
    info = c.scheduler_info().get("workers", {})
    gpus = gpu_workers(c)
    return Placement(workers=len(info), gpu_workers=gpus,
                     mode="one cell per GPU worker at a time" if gpus else "one cell at a time (no GPU resources)",
                     worker_names=sorted(str(w.get("name", "")) for w in info.values()))


def runner(c: Any, timeout: float, plan: list[Cell],
           probes: Probes) -> Callable[[Cell], Any]:
    """A ``run_cells`` runner: each cell a task that starts its own worker process (the same
    isolation and timeout as locally), collected in plan order. A task ships the cell's
    ``to_dict`` (the one encoding a cell crosses a process boundary in)."""
    from compare.running import cells, engine
    runnable = [cell for cell in plan if not engine.not_runnable(cell, probes)]
    if not gpu_workers(c):      # nothing declares a device: never overlap two timed cells
        return lambda cell: c.submit(cells.run_task, cell.to_dict(), timeout, pure=False).result()
    futures = {json.dumps(cell.to_dict(), sort_keys=True):
               c.submit(cells.run_task, cell.to_dict(), timeout, pure=False,
                        resources={"GPU": 1} if cell.device != "cpu" else None)
               for cell in runnable}
    return lambda cell: futures[json.dumps(cell.to_dict(), sort_keys=True)].result()
