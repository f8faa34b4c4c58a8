"""Worker processes die with their driver, and their temporary files with them.

Every process a driver starts for a cell, a host-loop task or an availability probe is started
as ``command(MODULE, *args)`` (``python -m compare.running.lifeline MODULE ARGS...``) or
``command("-c", CODE, *args)``. Before it runs its module, that process asks the kernel to
SIGKILL it when its parent dies (Linux ``prctl(PR_SET_PDEATHSIG)``; elsewhere a thread polls the
parent's PID), and exits at once if the parent has already gone (``COMPARE_PARENT_PID``). So a
driver killed with SIGKILL leaves no worker running on without its timeout.

Temporary directories (a cell's outputs and its empty kernel caches, gigabytes for large cells)
live under one root per driver process, ``temp_root()`` (``$TMPDIR/compare-<pid>-XXXX``), and a
worker's TMPDIR points inside it (frameworks write their own temporaries there too). With
the root the driver starts a small reaper process that holds the read end of a pipe whose write
end only the driver has: when the driver exits, however it exits, the kernel closes the pipe and
the reaper deletes the root. The root holds a flock of its driver (``.owner``); a root whose
flock is free (driver and reaper both gone, e.g. after a power cut) is deleted by the next
driver that makes one.
"""
from __future__ import annotations

import os
import runpy
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

PARENT_ENV = "COMPARE_PARENT_PID"
ROOT_ENV = "COMPARE_TEMP_ROOT"     # the driver's temporary root, where a worker's warm caches outlive it
PREFIX = "compare-"
PR_SET_PDEATHSIG = 1

_root: Path | None = None
_owner_fd: int | None = None
_reaper: subprocess.Popen | None = None
_lock = threading.Lock()

# The reaper: stdlib only, started with -S (no site) so it costs a few milliseconds.
REAPER = r"""
import os, shutil, signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)      # Ctrl-C is for the driver; we follow its exit
root = sys.argv[1]
try:
    while sys.stdin.buffer.read(65536):
        pass
except BaseException:
    pass
gone = 0
for _ in range(100):           # a dying worker may still be writing: until gone twice in a row
    shutil.rmtree(root, ignore_errors=True)
    gone = gone + 1 if not os.path.exists(root) else 0
    if gone >= 2:
        break
    time.sleep(0.1)
"""


def command(*args: str) -> list[str]:
    """The command line of a worker process: ``command("compare.running.worker", spec, out)`` or
    ``command("-c", code, *argv)``; the environment must carry ``child_environment()``."""
    return [sys.executable, "-m", "compare.running.lifeline", *args]


def child_environment(env: dict[str, str], tmp: str | Path | None = None) -> dict[str, str]:
    """``env`` with this process named as the parent a worker must not outlive, and its
    temporary files (``TMPDIR``: a framework's own, e.g. NVRTC's precompiled headers) inside
    ``tmp`` (default: this driver's root), so they go when the root goes."""
    tmp = str(tmp if tmp is not None else temp_root())
    return {**env, PARENT_ENV: str(os.getpid()), ROOT_ENV: str(temp_root()), "TMPDIR": tmp, "TEMP": tmp, "TMP": tmp}


# ---- the worker side -------------------------------------------------------------------------
def tie_to_parent() -> None:
    """Die with the parent named in COMPARE_PARENT_PID (no-op without it)."""
    want = os.environ.pop(PARENT_ENV, "")
    if not want.isdigit():
        return
    parent = int(want)
    armed = False
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent:          # it died before we could ask: follow it now
        os._exit(137)
    if not armed:
        def watch() -> None:
            import time
            while os.getppid() == parent:
                time.sleep(0.5)
            os._exit(137)
        threading.Thread(target=watch, name="compare-lifeline", daemon=True).start()


def main(argv: list[str]) -> None:
    tie_to_parent()
    if argv[:1] == ["-c"] and len(argv) >= 2:
        sys.argv = ["-c", *argv[2:]]
        code = compile(argv[1], "<string>", "exec")
        exec(code, {"__name__": "__main__", "__builtins__": __builtins__})
        return
    if not argv:
        raise SystemExit("usage: python -m compare.running.lifeline MODULE [ARGS...] | -c CODE [ARGS...]")
    sys.argv = [argv[0], *argv[1:]]
    runpy.run_module(argv[0], run_name="__main__", alter_sys=True)


# ---- the driver side -------------------------------------------------------------------------
def _stale(path: Path) -> bool:
    """A root of ours whose driver is gone: its .owner flock can be taken."""
    import fcntl
    try:
        if path.stat().st_uid != os.getuid():
            return False
        fd = os.open(path / ".owner", os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return False          # no .owner yet (being created) or not ours: leave it
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except OSError:
        return False
    finally:
        os.close(fd)


def clean_stale(base: str | Path | None = None) -> list[Path]:
    """Delete the temporary roots of drivers that are gone; returns them."""
    base = Path(base or tempfile.gettempdir())
    removed: list[Path] = []
    try:
        found = [p for p in base.iterdir() if p.name.startswith(PREFIX) and p.is_dir()]
    except OSError:
        return removed
    for p in found:
        if p != _root and _stale(p):
            shutil.rmtree(p, ignore_errors=True)
            removed.append(p)
    return removed


def temp_root() -> Path:
    """This driver's temporary root (made, with its reaper, on first use)."""
    global _root, _owner_fd, _reaper
    with _lock:
        if _root is not None and _root.is_dir() and _reaper is not None and _reaper.poll() is None:
            return _root
        import fcntl
        clean_stale()
        root = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-"))
        fd = os.open(root / ".owner", os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
        fcntl.flock(fd, fcntl.LOCK_EX)
        os.write(fd, f"{os.getpid()}\n".encode())
        reaper = subprocess.Popen([sys.executable, "-S", "-c", REAPER, str(root)], stdin=subprocess.PIPE,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True, close_fds=True)
        # the write end stays open in this process only (never inherited: close_fds and
        # O_CLOEXEC), so the reaper sees EOF exactly when this process is gone
        _root, _owner_fd, _reaper = root, fd, reaper
        return root


def temp_dir(prefix: str) -> tempfile.TemporaryDirectory:
    """A TemporaryDirectory under this driver's root."""
    return tempfile.TemporaryDirectory(prefix=prefix, dir=temp_root())


if __name__ == "__main__":
    main(sys.argv[1:])
