"""CuPy: CUDA C kernels compiled by NVRTC at the first call (CUDA only; CuPy has no CPU target).

Why these choices:
  * saxpy, copy and launch are ``cupy.ElementwiseKernel``s (CuPy's one-line kernel idiom, with its
    per-call argument handling: that overhead is part of what the comparison measures); sdf,
    particles and the projectile are ``cupy.RawKernel``s (CUDA C, one thread per pixel, particle
    or trajectory, in Warp's operation order), and so is SAXPY's ``vector`` variant (16-byte
    loads and stores, the CUDA C idiom for bandwidth-bound kernels);
  * every kernel is typed: the CUDA C sources are made per precision from ``prelude`` (``real``
    and the math functions of that precision; constants written ``R(0.35)``, a double literal
    rounded to ``real`` at compile time exactly as Warp's ``scalar(0.35)`` and Numba's
    ``S(0.35)`` round it), so the float32 code has no double arithmetic; scalars are passed as
    NumPy scalars of the declared C type (a Python float would be passed as a double);
  * NVRTC's defaults are kept (``--fmad=true``: multiply-adds contract to FMAs), as Warp's
    (``fuse_fp``) and Numba's (NVVM) defaults do;
  * kernels launch on the current stream, so ``capture`` records one ``run()`` on a non-default
    stream into a CUDA graph and replays it on the current stream, which ``synchronize`` waits on.
Importing this package does not import cupy (the driver imports every backend package).
"""
from __future__ import annotations

import importlib.metadata
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.base import dtype_of

from ..base import OWN_TIMER_S, Backend, Precision, not_installed

# One CUDA 12 wheel; on a CUDA 13 driver/toolkit install cupy-cuda13x instead (same import name,
# same code here): pick the wheel whose major version matches `nvidia-smi`'s "CUDA Version".
PACKAGE = "cupy-cuda12x"
THREADS_PER_BLOCK = 256
CPU_REASON = "CuPy runs on CUDA devices only"


def scalar_type(precision: Precision) -> type[np.floating]:
    return dtype_of(precision)


# CUDA C's type of each precision and the suffix of its math functions (sqrtf in float32): this
# backend's one map from Precision
CTYPES = {Precision.FLOAT32: ("float", "f"), Precision.FLOAT64: ("double", "")}


def ctype(precision: Precision) -> str:
    return CTYPES[precision][0]


def blocks(n: int, per_block: int = THREADS_PER_BLOCK) -> int:
    """Blocks of ``per_block`` threads covering ``n`` items (at least one)."""
    return max(1, -(-n // per_block))


_MATH = ("sqrt", "exp", "log", "sin", "fabs", "fmax", "fmin")


def prelude(precision: Precision) -> str:
    """CUDA C lines that fix the precision of a kernel source: ``real``, ``R(x)`` for constants and
    upper-case math functions of that precision (sqrtf ... in float32: no double promotion)."""
    suffix = CTYPES[precision][1]
    lines = [f"typedef {ctype(precision)} real;", "#define R(x) ((real)(x))"]
    lines += [f"#define {f.upper()} {f}{suffix}" for f in _MATH]
    return "\n".join(lines) + "\n"


def raw_kernel(source: str, name: str) -> Any:
    """A cupy.RawKernel for ``source``; compiled by NVRTC at its first launch (the driver's
    first-call time), with NVRTC's default options."""
    import cupy
    return cupy.RawKernel(source, name)


def upload(a: np.ndarray, dtype: Any = None) -> Any:
    import cupy
    return cupy.asarray(np.ascontiguousarray(a, dtype))


def empty(shape: Any, dtype: Any) -> Any:
    import cupy
    return cupy.empty(shape, dtype=dtype)


def kernel_info(**extra: Any) -> dict[str, Any]:
    return {"fmad": "NVRTC default (on)", **extra}


class CupyBackend(Backend):
    name = "cupy"
    package = PACKAGE
    gradient_method = "adjoint"          # hand-written discrete adjoint (as Numba's): no autodiff
    display_order, color = 4, "C4"       # after warp, taichi, jax, numba (C0-C3)
    scenario_variants = {"saxpy": ("vector",)}   # 16-byte loads and stores (saxpy.py)
    related_packages = ("cupy-cuda13x", "cuda-pathfinder", "nvidia-cuda-nvrtc-cu12")

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # CuPy's on-disk kernel cache (cubins by source hash) and the driver's JIT cache
        return {"CUPY_CACHE_DIR": str(cache_dir / "cupy"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def ensure_context(self, device: str) -> None:
        if device == "cuda":
            import cupy
            cupy.cuda.runtime.free(0)           # cudaFree(NULL): creates the primary context
            cupy.cuda.Device().synchronize()

    def available(self) -> dict[str, str | None]:
        reason = not_installed("cupy", self.package, extra="cupy")
        return {"cpu": CPU_REASON, "cuda": reason or self._cuda_reason()}

    @staticmethod
    def _cuda_reason() -> str | None:
        import cupy
        try:
            count = cupy.cuda.runtime.getDeviceCount()
        except Exception as exc:  # no driver, driver too old for the wheel's runtime, ...
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            return f"no CUDA device visible to CuPy ({first})"
        return None if count > 0 else "no CUDA device visible to CuPy"

    def versions(self) -> dict[str, str]:
        import cupy
        out = {"cupy": cupy.__version__}
        for dist in (PACKAGE, "cupy-cuda13x"):
            try:
                out[dist] = importlib.metadata.version(dist)
            except importlib.metadata.PackageNotFoundError:
                pass
        try:
            major, minor = cupy.cuda.nvrtc.getVersion()
            out["nvrtc"] = f"{major}.{minor}"
            rt = cupy.cuda.runtime.runtimeGetVersion()
            out["cuda_runtime"] = f"{rt // 1000}.{rt % 1000 // 10}"
        except Exception:
            pass
        return out

    def synchronize(self, device: str, result: Any) -> None:
        import cupy
        cupy.cuda.get_current_stream().synchronize()

    def event_timer(self, device: str) -> "CupyEvents | None":
        return CupyEvents() if device == "cuda" else None

    def own_latency(self, device: str, call: Any) -> dict[str, Any] | None:
        """``cupyx.profiler.benchmark``'s CPU times of ``call`` (its own events are recorded
        outside that clock; the synchronise is inside ``call``)."""
        if device != "cuda":
            return None
        from cupyx.profiler import benchmark
        r = benchmark(call, n_repeat=100_000, n_warmup=10, max_duration=OWN_TIMER_S)
        return {"tool": "cupyx.profiler.benchmark (cpu_times)", "median_s": float(np.median(r.cpu_times)),
                "calls": int(len(r.cpu_times)), "block": 1}

    def capture(self, device: str, run: Any) -> Any:
        """One ``run()`` recorded on a non-blocking stream (``Stream.begin_capture`` /
        ``end_capture``, CuPy's documented way to build a CUDA graph) and replayed with
        ``Graph.launch`` on the current stream, the one ``synchronize`` waits on. Every kernel
        here is compiled by the first call, and run() allocates nothing, so the capture holds
        only the launches. CUDA only."""
        if device != "cuda":
            return None
        import cupy
        stream = cupy.cuda.Stream(non_blocking=True)
        with stream:
            stream.begin_capture()
            try:
                run()
            finally:
                graph = stream.end_capture()
        stream.synchronize()
        return lambda: graph.launch(cupy.cuda.get_current_stream())

    def memory(self, device: str) -> dict[str, Any]:
        """Bytes held by CuPy's default memory pool: it keeps every block it ever allocated (until
        free_all_blocks), so this is its high-water mark (rounded up to 512-byte blocks)."""
        if device != "cuda":
            return {}
        import cupy
        pool = cupy.get_default_memory_pool()
        return {"device_peak_bytes": int(pool.total_bytes()),
                "device_memory_source": "cupy default memory pool total_bytes() (never released: "
                                        "its high-water mark)"}


class CupyEvents:
    description = "CUDA events (cupy.cuda.Event on the current stream) around run()"

    def __init__(self) -> None:
        import cupy
        self.cupy = cupy
        self.a, self.b = cupy.cuda.Event(), cupy.cuda.Event()

    def start(self) -> None:
        self.a.record(self.cupy.cuda.get_current_stream())

    def stop(self) -> None:
        self.b.record(self.cupy.cuda.get_current_stream())

    def elapsed_s(self) -> float:
        self.b.synchronize()
        return self.cupy.cuda.get_elapsed_time(self.a, self.b) * 1e-3    # milliseconds


BACKEND = CupyBackend()
