"""A worker's side of an overlapped run (``compare.running.overlap``): wait for the driver's word before
the cell's clocks start, and say when they have stopped.

The driver passes the read end of a pipe (``COMPARE_GATE_FD``); the worker writes ``ready`` in
its cell directory and blocks on the pipe until the driver writes a byte, then writes ``timed``
when its timed regions are over. Once its record is written it *parks*: it blocks on the same pipe
until the driver closes it, so that its exit (a framework's teardown, seconds for some) runs while
the next workers set up, never while another cell is timed, and no gate waits for it. Without the
variable (a plain worker, a Dask task) all three are no-ops: the cell's clocks start as soon as it
is set up and the process exits when it is done.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

GATE_ENV = "COMPARE_GATE_FD"
READY, TIMED = "ready", "timed"


class Gate:
    def __init__(self, cell_dir: Path) -> None:
        raw = os.environ.pop(GATE_ENV, "")        # one cell per gate: a later cell runs ungated
        self.fd = int(raw) if raw.isdigit() else None
        self.gated = self.fd is not None
        self.dir = cell_dir
        self.window: list[float] = []

    def wait(self) -> None:
        """Block until the driver opens the gate (nothing to wait for when ungated)."""
        if self.fd is not None:
            (self.dir / READY).touch()
            if not os.read(self.fd, 1):              # the driver is gone: no clock may start
                raise SystemExit("the driver closed the gate")
        self.window = [time.time()]

    def release(self) -> None:
        """The cell's timed regions are over: the driver may open the next gate."""
        if not self.window:
            return
        self.window.append(time.time())
        if self.fd is not None:
            (self.dir / TIMED).touch()

    def park(self) -> None:
        """The record is written: idle until the driver closes the pipe (or is gone), then return
        so the process exits. A worker that failed before its gate parks the same way."""
        if self.fd is None:
            return
        try:
            while os.read(self.fd, 1):
                pass
        except OSError:
            pass
        finally:
            os.close(self.fd)
            self.fd = None
