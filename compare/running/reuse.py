"""Answers the test suite's processes share: the float64 oracle's outputs of a cell (here), the
run's hardware yardstick (``compare.running.hardware.for_run``), a backend's availability probe
(``compare.running.cells.probe``, keyed by ``probe_key``), through ``kept``.

Many of the tests' cells ask the oracle the same question (the parity suite's cases for every
backend, the variants' runs, the frameworks' own groups): the same scenario, parameters,
precision and inputs give the same outputs, and the projectile's Python rollout and adjoint cost
up to a second a batch; a run's cells of one scenario and precision, one per framework, ask it
too. The first worker's outputs are kept, keyed by a hash of the question, and later workers
read them back bit for bit: in ``ENV``'s folder where it names one (tests/conftest.py sets it),
else in an ``oracles`` folder of the driver's temporary root (``compare.running.lifeline``: one
driver's workers, deleted with it); outside a driver's worker every call computes them.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import sys
from pathlib import Path
from typing import Any, Callable, Mapping, TypeVar

import numpy as np

from compare.files import atomic_write

ENV = "COMPARE_ORACLE_REUSE"
PROBE_ENV = "COMPARE_PROBE_REUSE"   # a folder: the tests' processes share each backend's probe
T = TypeVar("T")


def _key(name: str, params: Any, inputs: Mapping[str, np.ndarray], precision: str) -> str | None:
    """A hash of the question, or None where an input is not a plain array (not kept)."""
    p = dataclasses.asdict(params) if dataclasses.is_dataclass(params) and not isinstance(params, type) else params
    h = hashlib.sha256(json.dumps([name, p, str(precision)], sort_keys=True, default=repr).encode())
    for k in sorted(inputs):
        a = np.asarray(inputs[k])
        if a.dtype.hasobject:
            return None
        h.update(f"{k}|{a.dtype.str}|{a.shape}|".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def kept(folder: str, name: str | None, compute: Callable[[], T], encode: Callable[[T], bytes | None],
         decode: Callable[[bytes], T]) -> T:
    """``compute()``, or, where ``folder`` is given, the answer kept there as ``name`` by the first
    process that computed it (``encode``: its bytes, None to keep nothing; ``decode``: back). The
    file is written whole or not at all (``atomic_write``); one that cannot be read is computed again.
    A process whose writes fail on purpose (COMPARE_FAULT_DISK, ``compare.files``) keeps nothing:
    it counts the run's own writes, and whether another test kept this answer first must not
    change which of them fails."""
    if not folder or name is None:
        return compute()
    path = Path(folder) / name
    try:
        return decode(path.read_bytes())
    except (OSError, ValueError):
        pass
    got = compute()
    raw = None if os.environ.get("COMPARE_FAULT_DISK") else encode(got)
    if raw is not None:
        try:
            atomic_write(path, raw)
        except OSError:
            pass
    return got


KEPT_BYTES = 16 * 2**20     # a larger oracle is computed by every worker: no gigabytes kept on disk (a sweep)


def _npz(out: Any) -> bytes | None:     # an oracle's answer: kept only where it is plain arrays
    if not (isinstance(out, dict) and all(isinstance(v, np.ndarray) and not v.dtype.hasobject for v in out.values())):
        return None
    if sum(v.nbytes for v in out.values()) > KEPT_BYTES:
        return None
    buf = io.BytesIO()
    np.savez(buf, **out)
    return buf.getvalue()


def _arrays(raw: bytes) -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(raw), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def folder() -> str:
    """Where oracles are kept: ``ENV``'s folder, else (a driver's worker) its temporary root's
    ``oracles``, made here; empty: nowhere."""
    given = os.environ.get(ENV, "")
    if given:
        return given
    from compare.running.lifeline import ROOT_ENV
    root = os.environ.get(ROOT_ENV, "")
    if not root or not Path(root).is_dir():
        return ""
    try:
        (Path(root) / "oracles").mkdir(exist_ok=True)
    except OSError:
        return ""
    return str(Path(root) / "oracles")


def oracle(sc: Any, params: Any, inputs: Mapping[str, np.ndarray], precision: str) -> dict[str, np.ndarray]:
    """``sc.oracle(params, inputs, precision)``, read back where a worker before kept it (``folder``)."""
    where = folder()
    key = _key(sc.name, params, inputs, precision) if where else None
    return kept(where, key and f"oracle-{key}.npz", lambda: sc.oracle(params, inputs, precision), _npz, _arrays)


def probe_key(name: str, env: Mapping[str, str], root: Path) -> str:
    """The name under which ``PROBE_ENV``'s folder keeps backend ``name``'s probe: a hash of
    everything the probe's process sees that can change within a test run, the environment (less
    pytest's per-test variables), the repository it runs in and the backend's own files (a test
    may write one)."""
    h = hashlib.sha256(json.dumps([name, str(root), sorted((k, v) for k, v in env.items()
                                                            if not k.startswith("PYTEST_"))]).encode())
    import backends
    b = backends.BACKENDS.get(name)
    mod = sys.modules.get(type(b).__module__) if b is not None else None
    here = Path(mod.__file__).parent if mod is not None and mod.__file__ else None
    for f in sorted(here.glob("*.py")) if here is not None else ():
        st = f.stat()
        h.update(f"{f}|{st.st_mtime_ns}|{st.st_size}|".encode())
    return f"probe-{name}-{h.hexdigest()[:32]}.json"
