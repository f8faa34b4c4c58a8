"""Numba: ``@njit(parallel=True)`` on the CPU, ``numba.cuda`` kernels (the numba-cuda package) on CUDA.

Shared conventions of the kernel files:
  * every kernel is built by a factory cached per (dtype, fastmath), with the scalar type ``S``
    captured in the closure, and every constant written ``S(...)`` or passed as a typed argument,
    so the float32 specialisation has no float64 arithmetic (Python float literals would promote,
    numba/numba#4676);
  * the factories only create dispatchers; Numba compiles lazily at the first call, i.e. in the
    first ``run()``, which the driver reports as the first-call (compile) time;
  * CUDA kernels take device arrays made in the constructor and launch on ``launch_stream()``;
    ``run`` only launches.
Importing this package does not import numba.
"""
from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.base import dtype_of

from ..base import Backend, cuda_build_hint, not_installed

THREADS_PER_BLOCK = 256
SIMULATOR = "CUDA simulator (correctness only)"


def scalar_type(precision: str) -> type[np.floating]:
    return dtype_of(precision)


def use_fastmath(variant: str) -> bool:
    return variant == "fastmath"


def blocks(n: int, per_block: int = THREADS_PER_BLOCK) -> int:
    """Blocks of ``per_block`` threads covering ``n`` items (at least one)."""
    return max(1, -(-n // per_block))


_STREAM: list[Any] = []


def launch_stream() -> Any:
    """The stream every CUDA kernel here launches on: one per process, created on first use.
    Not the legacy default stream, because CUDA cannot capture that one into a graph
    (``NumbaBackend.capture``); it is a blocking stream, so it orders with the default stream that
    the events and downloads use, exactly as launches on the default stream would."""
    if not _STREAM:
        from numba import cuda
        _STREAM.append(cuda.stream())
    return _STREAM[0]


def _driver_check(result: tuple[Any, ...]) -> Any:
    """The value of a cuda.bindings driver call, or its error raised."""
    from cuda.bindings import driver
    err, *rest = result
    if err != driver.CUresult.CUDA_SUCCESS:
        raise RuntimeError(f"CUDA driver: {driver.cuGetErrorName(err)[1].decode()}")
    return rest[0] if rest else None


def kernel_info(device: str, fastmath: bool, **extra: Any) -> dict[str, Any]:
    """What ``ScenarioKernel.info`` reports: launch configuration or CPU threads, fastmath."""
    if device == "cuda":
        return {"threads_per_block": THREADS_PER_BLOCK, "fastmath": fastmath, **extra}
    import numba
    return {"parallel": True, "threads": numba.get_num_threads(), "fastmath": fastmath, **extra}


def _simulator() -> bool:
    if os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0"):
        return True
    try:
        from numba import config
        return bool(getattr(config, "ENABLE_CUDASIM", False))
    except Exception:
        return False


class NumbaBackend(Backend):
    name = "numba"
    package = "numba"
    gradient_method = "adjoint"          # hand-written discrete adjoint: Numba has no autodiff
    variants = ("default", "fastmath")
    display_order, color = 3, "C3"
    related_packages = ("numba-cuda", "llvmlite")

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # Numba caches on disk only for cache=True functions (none here); the driver's JIT cache
        # holds PTX compiled for numba.cuda kernels
        return {"NUMBA_CACHE_DIR": str(cache_dir / "numba"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def ensure_context(self, device: str) -> None:
        if device == "cuda":
            from numba import cuda
            cuda.current_context()

    def capture(self, device: str, run: Any) -> Any:
        """One ``run()`` captured into a CUDA graph through the driver (cuda.bindings, which
        numba-cuda uses), on the stream every kernel here launches on, and replayed with
        ``cuGraphLaunch`` there. numba-cuda has no graph API of its own; stream capture records
        launches from any library, so this is the graph a Numba user builds. CUDA only."""
        if device != "cuda" or _simulator():
            return None
        from cuda.bindings import driver
        handle = launch_stream().handle
        stream = driver.CUstream(int(handle.value if hasattr(handle, "value") else handle))
        _driver_check(driver.cuStreamBeginCapture(
            stream, driver.CUstreamCaptureMode.CU_STREAM_CAPTURE_MODE_THREAD_LOCAL))
        try:
            run()
        finally:
            graph = _driver_check(driver.cuStreamEndCapture(stream))
        exe = _driver_check(driver.cuGraphInstantiate(graph, 0))
        return lambda: _driver_check(driver.cuGraphLaunch(exe, stream))

    def event_timer(self, device: str) -> "NumbaEvents | None":
        return NumbaEvents() if device == "cuda" else None

    def available(self) -> dict[str, str | None]:
        reason = not_installed("numba", self.package)
        if reason:
            return {"cpu": reason, "cuda": reason}
        return {"cpu": None, "cuda": self._cuda_reason()}

    @staticmethod
    def _cuda_reason() -> str | None:
        # numba-cuda, Numba's CUDA target, comes with the cuda extras (a CPU-only install has no
        # CUDA package); the numba.cuda that some Numba releases still ship is not the one this
        # port is written for, so it never counts, simulator included
        reason = not_installed("numba_cuda", "numba-cuda", extra="cuda")
        if reason:
            return reason
        if _simulator():
            return SIMULATOR
        from numba import cuda
        try:
            return None if cuda.is_available() else cuda_build_hint("no CUDA device visible to numba.cuda")
        except Exception as exc:  # driver / toolkit problems surface here
            return cuda_build_hint(f"numba.cuda unusable: {type(exc).__name__}: {exc}")

    def versions(self) -> dict[str, str]:
        out = {}
        for dist in ("numba", "numba-cuda", "llvmlite"):
            try:
                out[dist] = importlib.metadata.version(dist)
            except importlib.metadata.PackageNotFoundError:
                pass
        return out

    def setup(self, device: str, precision: str, variant: str) -> None:
        if device == "cuda":   # a small projectile batch (B = 1 is one thread) launches fewer blocks than SMs: no low-occupancy warnings
            from numba import config
            config.CUDA_LOW_OCCUPANCY_WARNINGS = False

    def synchronize(self, device: str, result: Any) -> None:
        if device == "cuda":
            from numba import cuda
            cuda.synchronize()


class NumbaEvents:
    description = "CUDA events (numba.cuda.event on the default stream) around run()"

    def __init__(self) -> None:
        from numba import cuda
        self.cuda = cuda
        self.a, self.b = cuda.event(timing=True), cuda.event(timing=True)

    def start(self) -> None:
        self.a.record()

    def stop(self) -> None:
        self.b.record()

    def elapsed_s(self) -> float:
        self.b.synchronize()
        return self.cuda.event_elapsed_time(self.a, self.b) * 1e-3       # milliseconds


BACKEND = NumbaBackend()
