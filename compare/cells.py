"""Run cells in worker processes, with a timeout, and turn any failure into an ``error`` record."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from backends.base import DEVICES

ROOT = Path(__file__).resolve().parent.parent


def worker_env(backend: str | None = None) -> dict[str, str]:
    """The environment of a worker process: ours, the repository on PYTHONPATH, and what the
    backend asks for (``Backend.worker_environment``; every backend's when none is named). The
    user's own settings win."""
    import backends
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env.setdefault("PYTHONUNBUFFERED", "1")
    chosen = [backends.BACKENDS[backend]] if backend in backends.BACKENDS else list(backends.BACKENDS.values())
    for b in chosen:
        for k, v in b.worker_environment().items():
            env.setdefault(k, v)
    return env


def _tail(text: str, lines: int = 5) -> str:
    rows = [r for r in text.strip().splitlines() if r.strip()]
    return " | ".join(rows[-lines:])


def run(spec: dict[str, Any], timeout: float | None = 600.0) -> tuple[dict[str, Any], dict[str, np.ndarray] | None]:
    """Run one cell in a fresh interpreter; returns (record, outputs or None)."""
    with tempfile.TemporaryDirectory(prefix="cell-") as tmp:
        tmp_path = Path(tmp)
        (tmp_path / "spec.json").write_text(json.dumps(spec))
        cmd = [sys.executable, "-m", "compare.worker", str(tmp_path / "spec.json"), str(tmp_path)]
        try:
            proc = subprocess.run(cmd, cwd=ROOT, env=worker_env(spec["backend"]), capture_output=True, text=True,
                                  timeout=timeout, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired as exc:
            err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
            return {"status": "error", "reason": f"timed out after {timeout:g} s; {_tail(err, 2)}".rstrip("; ")}, None
        rec_file = tmp_path / "record.json"
        if proc.returncode != 0 or not rec_file.exists():
            rc = proc.returncode
            how = f"killed by signal {signal.Signals(-rc).name}" if rc < 0 else f"exit code {rc}"
            return {"status": "error", "reason": f"worker died ({how}): {_tail(proc.stderr)}"}, None
        record = json.loads(rec_file.read_text())
        outputs = None
        if (tmp_path / "outputs.npz").exists():
            with np.load(tmp_path / "outputs.npz") as z:
                outputs = {k: z[k] for k in z.files}
        if spec.get("save_inputs") and (tmp_path / "inputs.npz").exists():
            with np.load(tmp_path / "inputs.npz") as z:
                record["_inputs"] = {k: z[k] for k in z.files}
        return record, outputs


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


def probe(name: str, timeout: float = 180.0) -> dict[str, Any]:
    """Which devices a backend can use (and why not), checked in its own process."""
    try:
        proc = subprocess.run([sys.executable, "-c", PROBE, name], cwd=ROOT, env=worker_env(name),
                              capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        why = f"availability probe timed out after {timeout:g} s"
        return {"available": {d: why for d in DEVICES}, "versions": {}}
    for line in proc.stdout.splitlines():
        if line.startswith("PROBE"):
            return json.loads(line[5:])[name]
    why = f"availability probe failed (exit {proc.returncode}): {_tail(proc.stderr, 2)}"
    return {"available": {d: why for d in DEVICES}, "versions": {}}
