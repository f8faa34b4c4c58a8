"""The contract between the driver and a framework.

A backend is a package ``backends/<name>/`` whose ``__init__.py`` defines ``BACKEND``, an instance
of a ``Backend`` subclass, and one module per scenario (``saxpy.py``, ``sdf.py``, ...) with a class
``Kernel`` implementing ``ScenarioKernel``. Nothing else: no timing, no checking, no I/O.

Life of a cell (one worker process per scenario x backend x device x precision x variant):
    BACKEND.setup(device, precision, variant)       # process-global init (ti.init, jax x64, ...)
    k = BACKEND.kernel(scenario)(params, inputs, device, precision, variant)  # allocate + upload
    r = k.run(); BACKEND.synchronize(device, r)     # timed, first call separately (compile)
    k.outputs()                                     # download (timed separately)
``run`` must be repeatable: every call computes the same outputs from the uploaded inputs, with no
host<->device transfers and no allocations where the framework lets us avoid them.
"""
from __future__ import annotations

import enum
import importlib
import importlib.util
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np

from scenarios.base import Precision

OWN_TIMER_S = 0.1     # one stretch of a framework's own timer (``Backend.own_latency``), seconds
DEFAULT_VARIANT = "default"   # every backend's first variant: the one the matrix publishes (matrix.all_defaults)
# Variants that change the arithmetic (a shipped fast-math default is one: docs/ports.md): shown on
# the pages, never ranked (compare.site.matrix), so timed in one process (compare.suites.driver.caps)
UNRANKED_VARIANTS: tuple[str, ...] = ("fastmath",)


class Device(enum.StrEnum):
    """Where a cell runs. A ``StrEnum``: it equals, prints and serialises as its name ("cpu")."""
    CPU = "cpu"
    CUDA = "cuda"


# the names, as plain strings (what a command line, a record and a message show)
DEVICES: tuple[str, ...] = tuple(d.value for d in Device)


class ScenarioKernel:
    """One scenario in one framework. Subclasses are named ``Kernel`` in backends/<fw>/<scenario>.py."""

    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        raise NotImplementedError

    def run(self) -> Any:
        """Launch the work; may return immediately (asynchronous); returns what synchronize needs."""
        raise NotImplementedError

    def outputs(self) -> dict[str, np.ndarray]:
        """Copy the results of the last run to host NumPy arrays, named as the scenario's outputs."""
        raise NotImplementedError

    def set_input(self, name: str, value: np.ndarray) -> None:
        """Overwrite input ``name`` in place (same shape and dtype), so a host loop can rerun the
        kernel at new inputs without rebuilding or recompiling it. Optional: the stress suite's
        host-loop tasks use it and rebuild the kernel per evaluation where it is missing."""
        raise NotImplementedError(f"{type(self).__module__}.Kernel cannot replace {name!r} in place")

    def info(self) -> dict[str, Any]:
        """Facts about how the kernel ran (launch config, donation, gradient method...)."""
        return {}


class EventTimer(Protocol):
    """Device events around one call: ``start()``, run, ``stop()``, synchronise, ``elapsed_s()``."""
    description: str

    def start(self) -> None: ...
    def stop(self) -> None: ...
    def elapsed_s(self) -> float: ...


class Backend:
    """A framework port. Required: ``name``, ``package``, ``available``, ``synchronize``.

    Everything else is an optional capability with a harmless default that a backend overrides
    (PhiFlow-style): the driver asks the backend, never switches on its name.
    """

    name: ClassVar[str]
    package: ClassVar[str]                     # the pip distribution the backend needs
    gradient_method: ClassVar[str] = "-"       # 'tape', 'ad', 'adjoint'
    variants: ClassVar[tuple[str, ...]] = (DEFAULT_VARIANT,)   # e.g. 'fastmath'
    # Variants that exist for one scenario only (e.g. a checkpointed projectile): scenario -> names.
    scenario_variants: ClassVar[dict[str, tuple[str, ...]]] = {}
    # Variants kept only as the measured alternative of an A/B (a port's former default, e.g.
    # Warp's tape.zero()): timed by ``--variants all``, never swept (compare/suites/sweep.py).
    comparison_variants: ClassVar[tuple[str, ...]] = ()
    is_reference: ClassVar[bool] = False
    # The plain-CPU yardstick every CPU figure is also shown against ("speed-up against NumPy").
    is_cpu_baseline: ClassVar[bool] = False
    title: ClassVar[str] = ""                  # as prose writes it ('NumPy'); default: ``name``
    # Deliberately wrong variants the stress suite runs as controls its detectors must flag:
    # scenario -> {variant: what is wrong}. Never listed in ``variants``, never in tables.
    control_variants: ClassVar[dict[str, dict[str, str]]] = {}
    # Table/plot order (lower first; the reference is always first) and a fixed matplotlib colour,
    # so a backend keeps its colour in every plot whatever else ran.
    display_order: ClassVar[int] = 100
    color: ClassVar[str | None] = None
    # Distributions whose versions go into a results file's environment (besides ``package``).
    related_packages: ClassVar[tuple[str, ...]] = ()
    def variants_for(self, scenario: str) -> tuple[str, ...]:
        """The variants a cell of ``scenario`` may take: every scenario's, then its own."""
        return self.variants + tuple(v for v in self.scenario_variants.get(scenario, ()) if v not in self.variants)

    def ran_fast_math(self, precision: str, info: "Mapping[str, Any] | None") -> bool:
        """Whether a record's kernel ran with fast math (never ranked: docs/ports.md), from its
        ``info``. Default: where the info says so. A port whose default once was fast math
        overrides it for the records made before it said so."""
        return bool(info) and info.get("fast_math") is True

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        """Environment variables that point this framework's on-disk kernel caches into
        ``cache_dir`` (an empty directory per cell), so the first call includes compilation.
        Set before the framework is imported. Default: the framework keeps no cache on disk."""
        return {}

    def worker_environment(self) -> dict[str, str]:
        """Environment variables every worker process of this backend needs (set with
        ``setdefault``, so the user's own settings win), e.g. not to preallocate GPU memory."""
        return {}

    def variant_environment(self, variant: str) -> dict[str, str]:
        """Environment variables a variant's worker needs on top of ``worker_environment``: a
        process-wide compile option (e.g. XLA flags), so no kernel file needs to know the variant."""
        return {}

    def variant_unavailable(self, variant: str, device: str) -> str | None:
        """Why ``variant`` cannot run on ``device`` (a capability the framework lacks there: the
        cell is skipped with this reason), or None. Decided without importing the framework."""
        return None

    def precision_unavailable(self, precision: str, device: str) -> str | None:
        """Why ``precision`` cannot run on ``device`` (e.g. no float64 on a GPU): the cell is
        skipped with this reason, or None. Decided without importing the framework."""
        return None

    def ensure_context(self, device: str) -> None:
        """Create the framework's device context now (not lazily inside the first kernel), so the
        device-memory baseline taken after it leaves the context out. Default: ``setup`` did."""

    def capture(self, device: str, run: Any) -> Any:
        """The framework's graph fast path: capture one ``run()`` and return a function that
        replays it (the throughput regime then also times the replays), or None where the
        framework offers no graph capture for it. Raising says why capture failed."""
        return None

    def event_timer(self, device: str) -> EventTimer | None:
        """Device events bracketing one call on the stream the kernels run on, or None when the
        framework's public API has none (then the wall clock alone is the clock)."""
        return None

    def own_latency(self, device: str, call: Any) -> dict[str, Any] | None:
        """The framework's own timing utility around ``call`` (one ``run()`` and the framework's
        synchronise), as its users would time it: ``{"tool", "median_s", "calls", "block"}``, where
        ``block`` is how many calls each of the samples the median is taken over averages (1: a
        time per call); a cross-check of the harness's latency regime, compared in the same
        statistic. None where the framework ships no such utility."""
        return None

    def available(self) -> dict[str, str | None]:
        """device -> None when usable, else the reason it is not (not installed, no GPU...)."""
        raise NotImplementedError

    def versions(self) -> dict[str, str]:
        return {}

    def setup(self, device: str, precision: str, variant: str) -> None:
        """Process-global initialisation; called once per worker before any kernel is built."""

    def synchronize(self, device: str, result: Any) -> None:
        """Block until everything launched by ``run`` has finished."""
        raise NotImplementedError

    def memory(self, device: str) -> dict[str, Any]:
        """Device memory figures the framework exposes (e.g. {'device_peak_bytes': ...}), if any."""
        return {}

    def kernel(self, scenario: str) -> type[ScenarioKernel]:
        module = importlib.import_module(f"{type(self).__module__}.{scenario}")
        return module.Kernel

    def has_kernel(self, scenario: str) -> bool:
        """Whether the backend has a kernel file for ``scenario`` (found without importing it)."""
        try:
            return importlib.util.find_spec(f"{type(self).__module__}.{scenario}") is not None
        except (ImportError, ValueError):
            return False


def not_installed(module: str, package: str, extra: str = "", first: str = "") -> str | None:
    """None if ``module`` imports, else a one-line reason, with the install command when the
    package comes with one of the project's extras (``pip install -e '.[extra]'``), after
    ``first`` where the right build must be installed before the extra."""
    try:
        importlib.import_module(module)
    except Exception as exc:  # ImportError, or a framework failing at import (driver/ABI issues)
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        how = f" (install: {first + ' && ' if first else ''}pip install -e '.[{extra}]')" if extra else ""
        return f"{package} not importable: {why}{how}"
    return None


def visible_gpus() -> int:
    """NVIDIA GPUs the driver (NVML) sees on this host, whatever any framework thinks; 0 without
    a driver or library."""
    try:
        import pynvml
    except ImportError:   # NVML's binding comes with the cuda extras: the driver's own listing
        try:
            return len(os.listdir("/proc/driver/nvidia/gpus"))
        except OSError:
            return 0
    try:
        pynvml.nvmlInit()
        try:
            return int(pynvml.nvmlDeviceGetCount())
        finally:
            pynvml.nvmlShutdown()
    except Exception:  # no driver, no library: no GPU
        return 0


def cuda_build_hint(reason: str) -> str:
    """A framework's reason for not seeing a GPU, plus the install command when the driver does
    see one (then the framework is a CPU-only build or lacks its CUDA libraries)."""
    n = visible_gpus()
    if not n:
        return reason
    return (f"{reason}; the driver sees {n} NVIDIA GPU(s): a CPU-only build or missing CUDA "
            f"libraries? install: pip install -e '.[cuda]' (CUDA 13: '.[cuda13]')")

