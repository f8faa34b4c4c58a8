"""Run cells in worker processes, with a timeout, and turn any failure into an ``error`` record."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Sequence, TypedDict

import numpy as np

from backends.base import DEVICES
from compare.running import lifeline
from compare.measuring import phases
from compare.spec import Cell

ROOT = Path(__file__).resolve().parents[2]
Result = tuple[dict[str, Any], "dict[str, np.ndarray] | None"]    # the worker's record JSON, its outputs


class Probe(TypedDict):
    """What probing one backend found (``probe``): per device None (usable) or why not."""
    available: dict[str, str | None]
    versions: dict[str, str]


def worker_env(backend: str | None = None, variant: str = "default") -> dict[str, str]:
    """The environment of a worker process: ours, the repository on PYTHONPATH, and what the
    backend asks for (``Backend.worker_environment``; every backend's when none is named) and
    its variant (``Backend.variant_environment``). The user's own settings win."""
    import backends
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env.setdefault("PYTHONUNBUFFERED", "1")
    chosen = [backends.BACKENDS[backend]] if backend in backends.BACKENDS else list(backends.BACKENDS.values())
    for b in chosen:
        for k, v in b.worker_environment().items():
            env.setdefault(k, v)
        if backend is not None:
            for k, v in b.variant_environment(variant).items():
                env.setdefault(k, v)
    return env


def tail(text: str, lines: int = 5) -> str:
    rows = [r for r in text.strip().splitlines() if r.strip()]
    return " | ".join(rows[-lines:])


def died(proc: subprocess.Popen, err: str) -> str:
    rc = proc.returncode
    how = f"killed by signal {signal.Signals(-rc).name}" if rc is not None and rc < 0 else f"exit code {rc}"
    return f"worker died ({how}): {tail(err)}"


def collect(cell_dir: Path, cell: Cell) -> Result:
    record = json.loads((cell_dir / "record.json").read_text())
    outputs = None
    if (cell_dir / "outputs.npz").exists():
        with np.load(cell_dir / "outputs.npz") as z:
            outputs = {k: z[k] for k in z.files}
    if cell.save_inputs and (cell_dir / "inputs.npz").exists():
        with np.load(cell_dir / "inputs.npz") as z:
            record["_inputs"] = {k: z[k] for k in z.files}
    return record, outputs


def run_batch(specs: Sequence[Cell], timeout: float | None = 600.0,
              on_result: Callable[[int, Result], None] | None = None) -> list[Result]:
    """Run cells one after another in ONE fresh interpreter; returns (record, outputs) per spec.

    Only for cells that may share a process: same backend, device, precision and variant (the
    framework's process-global set-up) and warm kernel caches (a cold first call needs its own
    process). ``timeout`` applies to each cell: the worker writes each record as it finishes,
    and a cell that takes longer is killed with its process; the cells after it run again in a
    new process, so one crash or hang costs one record, never the batch. ``on_result(i, result)``
    is called as each cell finishes (so a store keeps it even if the driver dies later).
    """
    def got(result: Result) -> None:
        results.append(result)
        if on_result is not None:
            on_result(len(results) - 1, result)

    if not specs:
        return []
    batch = list(specs)
    results: list[Result] = []
    # under this driver's temporary root: deleted even if the driver is killed (compare.running.lifeline)
    with lifeline.temp_dir("cells-") as tmp:
        tmp_path = Path(tmp)
        (tmp_path / "cells.json").write_text(json.dumps([c.to_dict() for c in batch]))
        cmd = lifeline.command("compare.running.worker", str(tmp_path / "cells.json"), str(tmp_path))
        with tempfile.TemporaryFile("w+") as err:
            env = lifeline.child_environment(worker_env(batch[0].backend, batch[0].variant), tmp_path)
            env[phases.LAUNCHED_ENV] = repr(time.time())
            proc = subprocess.Popen(cmd, cwd=ROOT, env=env,
                                    stdout=subprocess.DEVNULL, stderr=err, text=True, stdin=subprocess.DEVNULL)
            started, done = time.monotonic(), 0
            began = started             # when the cell now running (or the last one) started
            reason = None
            try:
                while done < len(batch):
                    if (tmp_path / f"cell-{done}" / "record.json").exists():
                        got(collect(tmp_path / f"cell-{done}", batch[done]))
                        done, began, started = done + 1, started, time.monotonic()
                        continue
                    if proc.poll() is not None:
                        if (tmp_path / f"cell-{done}" / "record.json").exists():
                            continue
                        err.seek(0)
                        reason = died(proc, err.read())
                        break
                    if timeout is not None and time.monotonic() - started > timeout:
                        proc.kill()
                        proc.wait()
                        err.seek(0)
                        reason = f"timed out after {timeout:g} s; {tail(err.read(), 2)}".rstrip("; ")
                        break
                    time.sleep(0.02)
                if reason is None and proc.poll() is None:
                    # the timeout bounds the worker's whole life, its exit included: one that
                    # saved its last record and hangs (an exit handler, a thread) is killed
                    try:
                        proc.wait(None if timeout is None else max(0.0, began + timeout - time.monotonic()))
                    except subprocess.TimeoutExpired:
                        proc.kill()
                        proc.wait()
                        print(f"warning: a worker of {batch[-1].scenario}/{batch[-1].backend} did not "
                              f"exit within --timeout {timeout:g} s of its last cell's start; killed "
                              "(its records are kept)", file=sys.stderr)
            finally:        # the driver gives up (a full disk, Ctrl-C): no worker runs on
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
    if reason is not None:
        got(({"status": "error", "reason": reason}, None))
        start = len(results)
        results += run_batch(batch[start:], timeout,
                             None if on_result is None else lambda k, r: on_result(start + k, r))
    return results


def run(cell: Cell, timeout: float | None = 600.0) -> Result:
    """Run one cell in a fresh interpreter; returns (record, outputs or None)."""
    return run_batch([cell], timeout)[0]


def run_task(spec: dict[str, Any], timeout: float | None = 600.0) -> Result:   # a Dask task's JSON
    """``run`` as a Dask task (``compare.running.scaleout``): the cell crosses to the cluster's
    worker as its ``Cell.to_dict`` and is decoded there."""
    return run(Cell.from_dict(spec), timeout)


PROBE = """
import json, sys
import backends
out = {}
for name in sys.argv[1:]:
    b = backends.get(name)
    try:
        avail = b.available()
        if not isinstance(avail, dict):
            raise TypeError(f"available() returned {type(avail).__name__}, not a dict")
        vers = b.versions() if any(v is None for v in avail.values()) else {}
    except Exception as exc:
        why = f"probe failed: {type(exc).__name__}: {exc}"
        avail, vers = {d: why for d in backends.DEVICES}, {}
    # a device the backend does not report is unavailable, never run on whatever it does
    avail = {d: (avail[d] if d in avail and (avail[d] is None or isinstance(avail[d], str)) else
                 f"{name}'s available() does not report {d!r}" if d not in avail else
                 f"{name}'s available() gives {avail[d]!r} for {d!r}, not None or a reason")
             for d in backends.DEVICES}
    out[name] = {"available": avail, "versions": vers}
print("PROBE" + json.dumps(out))
"""


def probe(name: str, timeout: float = 180.0) -> Probe:
    """Which devices a backend can use (and why not), checked in its own process; where
    ``reuse.PROBE_ENV`` names a folder (the tests'), the answer of a probe that ran in the same
    environment is read back (one that timed out or printed no answer is never kept)."""
    from compare.running import reuse
    folder = os.environ.get(reuse.PROBE_ENV, "")
    if not folder:
        return _probe(name, timeout)[0]
    return reuse.kept(folder, reuse.probe_key(name, worker_env(name), ROOT), lambda: _probe(name, timeout),
                      lambda got: json.dumps(got[0]).encode() if got[1] else None,
                      lambda raw: (json.loads(raw), True))[0]


def _probe(name: str, timeout: float) -> tuple[Probe, bool]:
    """The probe's answer, and whether its process gave one."""
    try:
        proc = subprocess.run(lifeline.command("-c", PROBE, name), cwd=ROOT,
                              env=lifeline.child_environment(worker_env(name)),
                              capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        why = f"availability probe timed out after {timeout:g} s"
        return Probe(available={d: why for d in DEVICES}, versions={}), False
    for line in proc.stdout.splitlines():
        if line.startswith("PROBE"):
            return json.loads(line[5:])[name], True
    why = f"availability probe failed (exit {proc.returncode}): {tail(proc.stderr, 2)}"
    return Probe(available={d: why for d in DEVICES}, versions={}), False
