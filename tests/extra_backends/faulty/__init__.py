"""A backend only the tests install: another backend's kernels that misbehave on request, so the
driver's handling of a failing cell can be tested without any fault code in the measuring worker.

Installed by naming this folder's parent in COMPARE_BACKENDS_EXTRA (``backends._discover``).
COMPARE_FAULTY_WRAPS names the backend it is (default numpy: cells that start without compiling;
a CUDA framework's name to fail with a live GPU context). COMPARE_FAULT="<scenario>:<kind>"
makes that scenario's cells fail when their outputs are downloaded, after the timed calls, as a
real framework would fail there: ``crash`` (SIGABRT), ``hang``, ``raise``, ``oom`` (out of memory,
safely: the address space is capped first) or ``mismatch`` (every output off by one, which the
oracle check must catch). Other scenarios run as the wrapped backend's.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import time

import numpy as np

from backends.base import ScenarioKernel

KINDS = ("crash", "hang", "raise", "oom", "mismatch")
WRAPPED = importlib.import_module(f"backends.{os.environ.get('COMPARE_FAULTY_WRAPS', 'numpy')}").BACKEND


def fault(scenario: str) -> str | None:
    target, _, kind = os.environ.get("COMPARE_FAULT", "").rpartition(":")
    return kind if target == scenario and kind in KINDS else None


def misbehave(kind: str, outputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    if kind == "crash":
        os.abort()
    if kind == "hang":
        time.sleep(10**6)
    if kind == "raise":
        raise RuntimeError("injected fault")
    if kind == "oom":
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (2**31, resource.getrlimit(resource.RLIMIT_AS)[1]))
        np.ones(2**31, dtype=np.float64)
    return {k: v + np.asarray(1, v.dtype) if v.dtype.kind == "f" else v for k, v in outputs.items()}


class FaultyBackend(type(WRAPPED)):   # type: ignore[misc]
    """The wrapped backend in every capability (devices, synchronise, events, caches), but its name."""
    name = "faulty"
    title = f"Faulty {WRAPPED.name} (tests only)"
    is_reference = is_cpu_baseline = False
    display_order, color = 99, "C9"

    def kernel(self, scenario: str) -> type[ScenarioKernel]:
        base = importlib.import_module(f"{type(WRAPPED).__module__}.{scenario}").Kernel
        kind = fault(scenario)
        if kind is None:
            return base

        class Faulty(base):   # type: ignore[misc, valid-type]
            def outputs(self) -> dict[str, np.ndarray]:
                return misbehave(kind, super().outputs())
        return Faulty

    def has_kernel(self, scenario: str) -> bool:
        return importlib.util.find_spec(f"{type(WRAPPED).__module__}.{scenario}") is not None


BACKEND = FaultyBackend()
