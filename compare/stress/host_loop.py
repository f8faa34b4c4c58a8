"""Host-loop tasks, each in a fresh worker process: ``python -m compare.stress.host_loop TASK.json OUT.json``.

Some experiments need more than one cell gives, e.g. an optimiser no backend implements, driven
on the host with the backend's loss and gradient. Such a task is typed on our side (a
``HostTask``, e.g. ``compare.stress.projectile_tasks.Task``) and a JSON dict only across the
process boundary: ``to_json`` gives what the worker reads, whose ``call`` names the function that
runs it (``"package.module:function"``, e.g. ``compare.stress.projectile_tasks:run_task``); the
function gets that dict and returns a JSON-able dict, which the task's ``outcome`` decodes.
Process isolation is as for cells (``compare.running.cells``): frameworks' global state lives and
dies with the process, and a crash or a hang becomes ``{"error": ...}`` instead of a lost run.
"""
from __future__ import annotations

import importlib
import json
import math
import subprocess
import sys
import traceback
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from compare.running import lifeline
from compare.running.cells import ROOT, worker_env
from compare.stress.numerics import HostTask, Payload

R = TypeVar("R")


def call(task: Payload) -> Payload:
    """Run ``task`` (the worker's JSON) in this process: import and call its ``call`` target."""
    target = task.get("call")
    if not isinstance(target, str) or ":" not in target:
        raise ValueError(f"a host-loop task names its function as 'module:function', got {target!r}")
    module, function = target.split(":", 1)
    return getattr(importlib.import_module(module), function)(task)


def run(task: HostTask[R], timeout: float = 900.0) -> R:
    """Run ``task`` in a fresh interpreter (as compare.running.cells.run does for a cell); never
    raises: a timeout or a dead worker is an outcome with its ``error``."""
    return task.outcome(run_json(task.to_json(), task.backend, timeout))


def run_json(payload: Payload, backend: str | None, timeout: float) -> Payload:
    """The process boundary: ``payload`` to a worker of ``backend``'s environment, its answer back."""
    with lifeline.temp_dir("stress-task-") as tmp:
        spec, out = Path(tmp) / "task.json", Path(tmp) / "out.json"
        spec.write_text(json.dumps(payload))
        try:
            proc = subprocess.run(lifeline.command(__name__, str(spec), str(out)), cwd=ROOT,
                                  env=lifeline.child_environment(worker_env(backend), tmp),
                                  capture_output=True,
                                  text=True, timeout=timeout, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            return {"error": f"task timed out after {timeout:g} s"}
        if not out.exists():
            tail = " | ".join(proc.stderr.strip().splitlines()[-3:])
            return {"error": f"task process died (exit {proc.returncode}): {tail}"}
        answer: Payload = json.loads(out.read_text(), parse_constant=float,
                                     object_hook=lambda d: {k: _unstr(v) for k, v in d.items()})
        return answer


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else str(float(x))
    if isinstance(x, np.integer):
        return int(x)
    return x


def _unstr(v: Any) -> Any:
    if isinstance(v, str) and v in ("nan", "inf", "-inf"):
        return float(v)
    if isinstance(v, list):
        return [_unstr(x) for x in v]
    return v


def main(argv: list[str]) -> int:
    task = json.loads(Path(argv[0]).read_text())
    try:
        result = call(task)
    except Exception as exc:  # reported as an error row by the parent, never a lost run
        first = str(exc).splitlines()[0] if str(exc) else ""
        result = {"error": f"{type(exc).__name__}: {first}", "traceback": traceback.format_exc()}
    Path(argv[1]).write_text(json.dumps(_jsonable(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
