"""Timed cells, one fresh process each, their set-up done side by side and their clocks alone.

A cell's worker (``compare.running.worker``) starts, imports, makes its inputs and sets its framework up,
then waits at its gate (``compare.running.gate``) until this driver lets its clocks start; when its timed
window is over (kernel build, first call, warm-up and latency, throughput, download, graph) it
says so and goes on to the oracle, the check, its record and its exit. Here up to 1 + ``ahead``
workers set up at the same time, then their gates open one after another:

- a gate opens only when no other window is open, and a CPU cell's gate only when every other
  worker waits at its gate (blocked on a pipe: idle) or has exited, so nothing else runs on the
  host while a CPU cell is timed: no two windows overlap (each record keeps its own,
  ``time.window``), and no set-up, check or exit overlaps a CPU cell's window (a launch-bound
  cell's host thread shares cores, caches and memory with whatever else runs);
- beside a GPU cell's window (``beside``: ``--overlap`` on a host of at least ``BESIDE_CORES``
  usable cores) other workers set up, check and exit on the other cores: host work, and each
  one's device context, but no kernel of theirs (what it does to the figures, against exclusive
  windows: docs/results/h100/evidence/session23). Without ``beside`` the set-up of the next
  workers begins only when no worker is ready or timed;
- one worker per framework and GPU at a time (``engine.gpu_lane``), and the workers' memory
  estimates together within the budget;
- each cell still has its own process and empty kernel caches, so its first call is as cold
  as one at a time; waiting at the gate is its own part (``time.phases.wait``) and does not
  count against ``timeout``;
- a worker whose record is in *parks* (``Gate.park``): idle, it neither holds a gate nor exits
  while a window that must be alone is open or due; then its pipe is closed and it exits while
  the next workers set up, and no such gate opens before it is gone. Its lane and memory stay
  taken until then.
"""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, IO, Sequence

from compare.running import cells, lifeline
from compare.measuring import environment, phases
from compare.running.gate import GATE_ENV, READY, TIMED
from compare.spec import Cell

Result = cells.Result


BESIDE_CORES = 8    # fewer: the set-ups would share the timed worker's cores, so every window is alone


def ahead(args: Any = None) -> int:
    """Workers that set up beside the next one: ``--overlap`` (``auto``: half the cores less
    one, at least one: 7 on 16 cores). Not given: ``auto`` where every window is alone anyway
    (fewer than ``BESIDE_CORES`` usable cores; local workers; no ``--busy``, whose spinners run
    through a worker's set-up), so only set-ups and exits move, never a clock; else 0 (on larger
    hosts ``auto`` would also let host work run beside GPU windows)."""
    given = getattr(args, "overlap", None)
    if given is None:
        alone = environment.usable_cores() < BESIDE_CORES and not getattr(args, "busy", 0)
        given = "auto" if args is not None and alone and not getattr(args, "scheduler", None) else 0
    if given == 0:
        return 0
    if given == "auto":
        return max(1, environment.usable_cores() // 2 - 1)
    return int(given)


def beside(ahead: int) -> bool:
    """Whether other workers' host work (set-up, check, exit) runs beside a GPU cell's window:
    an overlapped run (``ahead`` > 0) on a host of at least ``BESIDE_CORES`` usable cores."""
    return ahead > 0 and environment.usable_cores() >= BESIDE_CORES


def _alone(job: "_Job", beside: bool) -> bool:
    """The job's window (due or open) needs the host to itself: a CPU cell's, or any without ``beside``."""
    return not beside or str(job.cell.device) in ("cpu", "host")


def schedule(plan: list[Cell]) -> list[int]:
    """The order cells run in: CUDA and CPU cells alternate and consecutive cells of one device
    differ in framework where they can, so that workers setting up together rarely share a lane."""
    by_dev: dict[str, list[int]] = {}
    for i, c in enumerate(plan):
        by_dev.setdefault("cpu" if c.device == "cpu" else "gpu", []).append(i)
    for idx in by_dev.values():
        idx.sort(key=lambda i: (str(plan[i].precision), plan[i].scenario, plan[i].variant, plan[i].backend))
    gpu, cpu = by_dev.get("gpu", []), by_dev.get("cpu", [])
    out: list[int] = []
    for k in range(max(len(gpu), len(cpu))):
        out += gpu[k:k + 1] + cpu[k:k + 1]
    return out


@dataclasses.dataclass
class _Job:
    i: int
    cell: Cell
    dir: Path
    proc: subprocess.Popen
    gate: int                      # the write end of the worker's gate pipe
    err: IO[str]
    launched: float
    state: str = "start"           # start -> ready -> timed -> after -> (parked -> exiting) -> (exit)
    ready_at: float = 0.0
    waited: float = 0.0
    result: Result | None = None

    def close(self) -> None:
        """Once only: a closed descriptor's number may already be another worker's pipe."""
        if self.gate >= 0:
            try:
                os.close(self.gate)
            except OSError:
                pass
            self.gate = -1
        self.err.close()


def memory_budget() -> float:
    """Host memory the overlapped workers may hold together: 90 % of what is available now."""
    import psutil
    return 0.9 * float(psutil.virtual_memory().available)


def run_overlapped(plan: list[Cell], timeout: float | None, on_result: Callable[[int, Result], None],
                   ahead: int, need: Callable[[Cell], float] | None = None,
                   budget: float | None = None, lane: Callable[[Cell], Any] | None = None,
                   ordered: bool = False) -> None:
    """Run every cell of ``plan`` (one process each), calling ``on_result(i, result)`` as each
    finishes. ``need``/``budget``: a worker's host-memory estimate and what the workers may hold
    together; ``lane``: cells of one lane never run at the same time (None: no constraint).
    ``ordered``: keep the plan's order (a repeat round's seeded shuffle) rather than ``schedule``'s.
    Host work beside GPU cells' windows where ``beside(ahead)``."""
    side = beside(ahead)
    todo = list(range(len(plan))) if ordered else schedule(plan)
    active: list[_Job] = []
    idle: list[_Job] = []          # parked or exiting: results in, processes not yet gone
    with lifeline.temp_dir("overlap-") as tmp:
        root = Path(tmp)
        try:
            while todo or active or idle:
                now = time.monotonic()
                for job in list(active):
                    over = _advance(job, now, timeout)
                    if not over and job.state != "parked":
                        continue
                    active.remove(job)
                    if job.result is None:      # _advance finishes a job only once it has one
                        raise RuntimeError(f"overlap: cell {job.i} finished without a result")
                    on_result(job.i, job.result)
                    if over:
                        job.close()
                        _remove(job.dir)
                    else:
                        idle.append(job)
                idle = _release(idle, active, now, side)
                _grant(active, idle, side)
                started = _launchable(todo, active, plan, ahead, need, budget, lane, idle, side)
                if started is not None:
                    todo.remove(started)
                    active.append(_launch(started, plan[started], root, timeout))
                    continue
                # while a window is open the driver's own polling is other work: rarely then
                time.sleep(0.01 if any(j.state == "timed" for j in active) else 0.002)
        finally:                       # the driver gives up (a full disk, Ctrl-C): no worker runs on
            for job in active + idle:
                if job.proc.poll() is None:
                    job.proc.kill()
                    job.proc.wait()
                job.close()


def _launch(i: int, cell: Cell, root: Path, timeout: float | None) -> _Job:
    d = root / f"cell-{i}"
    d.mkdir()
    (d / "cells.json").write_text(json.dumps([cell.to_dict()]))
    r, w = os.pipe()
    env = lifeline.child_environment(cells.worker_env(cell.backend, cell.variant), d)
    env[phases.LAUNCHED_ENV] = repr(time.time())
    env[GATE_ENV] = str(r)
    err = tempfile.TemporaryFile("w+")
    proc = subprocess.Popen(lifeline.command("compare.running.worker", str(d / "cells.json"), str(d)), cwd=cells.ROOT,
                            env=env, stdout=subprocess.DEVNULL, stderr=err, text=True,
                            stdin=subprocess.DEVNULL, pass_fds=(r,))
    os.close(r)
    return _Job(i, cell, d, proc, w, err, time.monotonic())


def _advance(job: _Job, now: float, timeout: float | None) -> bool:
    """Move ``job`` on from what its worker left in its directory; True once it is over (its
    record read and its process gone, or its failure made a record)."""
    out = job.dir / "cell-0"
    if job.state == "start" and (out / READY).exists():
        job.state, job.ready_at = "ready", now
    if job.state == "timed" and (out / TIMED).exists():
        job.state = "after"
    if job.result is None and (out / "record.json").exists():
        job.result = cells.collect(out, job.cell)
        job.state = "after"
    alive = job.proc.poll() is None
    if job.result is not None and not alive:
        return True
    if job.result is not None and job.state == "after":     # its worker parks (Gate.park): idle
        job.state = "parked"
        return False
    spent = now - job.launched - job.waited - (now - job.ready_at if job.state == "ready" else 0.0)
    if alive and (timeout is None or spent <= timeout):
        return False
    if alive:
        job.proc.kill()
        job.proc.wait()
        if job.result is not None:      # its record is kept; only its exit hung
            return True
        job.err.seek(0)
        why = f"timed out after {timeout:g} s; {cells.tail(job.err.read(), 2)}".rstrip("; ")
    else:
        job.err.seek(0)
        why = cells.died(job.proc, job.err.read())
    job.result = ({"status": "error", "reason": why}, None)
    return True


EXIT_S = 60.0       # a released worker that has not exited by then is killed (its record is in)


def _release(idle: list[_Job], active: list[_Job], now: float, beside: bool = False) -> list[_Job]:
    """Close the pipes of the parked workers once no window that must be alone is open or due (no
    such active worker is ready or timed), so they exit while the next workers set up (or beside a
    GPU cell's window); the idle jobs still alive."""
    if not any(j.state in ("ready", "timed") and _alone(j, beside) for j in active):
        for job in idle:
            if job.state == "parked":
                job.close()
                job.state, job.ready_at = "exiting", now
    left = []
    for job in idle:
        if job.state == "exiting" and job.proc.poll() is None and now - job.ready_at > EXIT_S:
            job.proc.kill()
            job.proc.wait()
        if job.proc.poll() is None:
            left.append(job)
        else:
            job.close()
            _remove(job.dir)
    return left


def _grant(active: list[_Job], idle: Sequence[_Job] = (), beside: bool = False) -> None:
    """Open the next gate: the first ready worker in launch order, when no window is open and,
    for a window that must be alone, every other worker waits at its gate (none is setting up,
    checking or exiting)."""
    ready = [j for j in active if j.state == "ready"]
    if not ready or any(j.state == "timed" for j in active):
        return
    job = ready[0]
    if _alone(job, beside) and (len(ready) < len(active) or any(j.state == "exiting" for j in idle)):
        return
    try:
        os.write(job.gate, b"g")
    except OSError:                   # the worker died at its gate: _advance records why
        return
    job.waited += time.monotonic() - job.ready_at
    job.state = "timed"


def _launchable(todo: list[int], active: list[_Job], plan: list[Cell], ahead: int,
                need: Callable[[Cell], float] | None, budget: float | None,
                lane: Callable[[Cell], Any] | None, idle: Sequence[_Job] = (),
                beside: bool = False) -> int | None:
    """The next cell to start now, or None: at most 1 + ``ahead`` workers, and only while none
    whose window must be alone is ready or timed (set-ups start together, then the gates open one
    by one; beside GPU windows they go on); the first of ``todo`` within the memory budget and the
    lanes, which ``idle`` workers (parked or exiting) still hold."""
    if not todo or len(active) > ahead:
        return None
    if not active and not idle:
        return todo[0]
    if any(j.state in ("ready", "timed") and _alone(j, beside) for j in active):
        return None
    present = [*active, *idle]
    held = sum(need(j.cell) for j in present) if need else 0.0
    lanes = {lane(j.cell) for j in present} if lane else set()
    for i in todo:          # past a cell whose lane is taken: a batch fills up with other frameworks
        cell = plan[i]
        if need and budget is not None and held + need(cell) > budget:
            continue
        if lane and lane(cell) is not None and lane(cell) in lanes:
            continue
        return i
    return None


def _remove(d: Path) -> None:
    import shutil
    shutil.rmtree(d, ignore_errors=True)
