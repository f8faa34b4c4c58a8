"""MLX: NumPy-style arrays evaluated lazily; every timed computation goes through ``mx.compile``.

MLX records operations into a graph and computes only what ``mx.eval`` (or ``mx.async_eval``)
asks for. ``mx.compile`` traces a function once per input signature, merges common work and fuses
chains of elementwise operations into one kernel; on the CPU that kernel is C++ that MLX compiles
with the system's ``g++ -O3`` on first use (into ``$TMPDIR/mlx/<version>/cpu``, hence
``cache_environment``) and without g++ the compiled function silently runs unfused
(``info()['cpu_fusion']`` says which). MLX is imported lazily: the driver imports every backend
package without loading frameworks. The package is named like the framework; every module in it
imports MLX absolutely (``import mlx.core``), which never finds this package.

Timing and laziness. ``run()`` builds the graph and hands it to ``mx.async_eval``, the MLX
counterpart of an asynchronous kernel launch: the computation starts on the stream at once and
``synchronize`` waits for it with ``mx.eval`` of the result alone: on arrays already scheduled,
MLX's eval waits on each array's completion event (``array::wait``, signalled in the stream after
the work that computes it, which follows every earlier run's work there), so the values are final
when it returns; ``mx.synchronize`` (a second blocking wait on the whole stream) only where there
is no result to wait on. Without it a
pipelined batch of k calls would compute only the one whose result is synchronised: the other
k - 1 graphs are dropped unevaluated.

Precision. float64 exists on the CPU only (MLX's documentation: "Arrays with type float64 only
work with CPU operations"). ``mx.array`` turns a float64 NumPy array into float32 unless given
the dtype, so ``put`` always names it. On the x86-64 CPU build, ``mx.exp``, ``mx.sin`` and
``mx.cos`` evaluate float64 arrays through float32 polynomials (docs/findings.md); ``exp`` and
``sin`` below use operations MLX evaluates in float64 (libm's pow and tan) for float64 arrays.
"""
from __future__ import annotations

import importlib.metadata
import math
import shutil
import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np

from scenarios.base import dtype_of

from ..base import Backend, Precision, not_installed, visible_gpus

CUDA_INSTALL = "pip uninstall -y mlx-cpu && pip install 'mlx[cuda12]' (CUDA 13: 'mlx[cuda13]')"
NO_FLOAT64_GPU = ("MLX has no float64 on a GPU (its documentation: float64 arrays only work with "
                  "CPU operations)")


def mlx_device(device: str) -> Any:
    import mlx.core as mx
    return mx.cpu if device == "cpu" else mx.gpu


def mlx_dtype(precision: Precision) -> Any:
    """MLX's dtype of the cell's precision (this backend's one map from Precision)."""
    import mlx.core as mx
    return {Precision.FLOAT32: mx.float32, Precision.FLOAT64: mx.float64}[precision]


def put(array: Any, precision: Precision) -> Any:
    """A host array (or scalar) as an evaluated MLX array of the cell's dtype, on the default
    device (``setup`` sets it)."""
    import mlx.core as mx
    out = mx.array(np.asarray(array, dtype=dtype_of(precision)), dtype=mlx_dtype(precision))
    mx.eval(out)
    return out


def download(array: Any, precision: Precision) -> np.ndarray:
    """A host copy of an MLX array, of the cell's dtype."""
    return np.array(array, dtype=dtype_of(precision), copy=True)


def exp(x: Any) -> Any:
    """exp(x), float64-accurate for float64 ``x``: pow(fl(e), x), whose only error beyond libm's
    pow is |x| * 2^-53 relative (from rounding e); mx.exp for float32."""
    import mlx.core as mx
    if x.dtype == mx.float64:
        return mx.power(mx.array(math.e, dtype=mx.float64), x)
    return mx.exp(x)


def sin(x: Any) -> Any:
    """sin(x), float64-accurate for float64 ``x``: the half-angle identity 2t/(1 + t^2) with
    t = tan(x/2) (libm's tan; x/2 is exact), a few ulps; mx.sin for float32."""
    import mlx.core as mx
    if x.dtype == mx.float64:
        t = mx.tan(x * 0.5)
        return (2.0 * t) / (1.0 + t * t)
    return mx.sin(x)


def transcendentals(precision: Precision) -> str:
    """How exp and sin are evaluated in this precision (for info())."""
    if precision == Precision.FLOAT64:
        return ("float64: exp as pow(e, x), sin as 2t/(1+t^2), t = tan(x/2) "
                "(mx.exp/mx.sin round through float32)")
    return "mx.exp, mx.sin"


def cpu_fusion() -> str:
    """Whether mx.compile can fuse on the CPU: MLX compiles fused kernels with g++ (Linux) and
    skips fusion silently without it."""
    if sys.platform != "linux":
        return "fused kernels (platform compiler)"
    return "fused kernels compiled by g++" if shutil.which("g++") else "unfused: no g++ on PATH"


class Program:
    """``mx.compile(fn)``: traced and compiled (the CPU's g++ included) inside its first call, so
    compilation stays in the driver's first-call time. ``traces`` counts how often MLX ran the
    Python function to trace it (once per input signature; a compiled call runs no Python)."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        import mlx.core as mx
        self.traces = 0

        def traced(*args: Any) -> Any:
            self.traces += 1
            return fn(*args)

        self.fn = mx.compile(traced)

    def __call__(self, *args: Any) -> Any:
        return self.fn(*args)


def launch(out: Any) -> Any:
    """Start computing ``out`` on its stream and return it (see the module docstring)."""
    import mlx.core as mx
    mx.async_eval(out)
    return out


def kernel_info(device: str, precision: str, program: Program | None = None,
                **extra: Any) -> dict[str, Any]:
    out: dict[str, Any] = {"compiled": "mx.compile", "launch": "mx.async_eval per run()",
                           "transcendentals": transcendentals(precision)}
    if program is not None:
        out["traces"] = program.traces
    if device == "cpu":
        out["cpu_fusion"] = cpu_fusion()
    return {**out, **extra}


class MlxBackend(Backend):
    name = "mlx"
    package = "mlx"
    gradient_method = "ad"
    display_order, color = 8, "#393b79"     # tab10 is taken by the others: a dark indigo
    # projectile "step": mx.compile of one step, not the iteration; particles "rollout": of the
    # whole rollout, not one step
    scenario_variants = {"projectile": ("step",), "particles": ("rollout",)}
    related_packages = ("mlx-cpu", "mlx-cuda-12", "mlx-cuda-13", "mlx-metal")

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # MLX keeps the CPU's compiled kernels (.cpp and .so) under temp_directory_path()/mlx, and
        # the CUDA JIT's PTX there too unless MLX_PTX_CACHE_DIR (a user's own, here replaced) says
        return {"TMPDIR": str(cache_dir / "mlx-tmp"), "MLX_PTX_CACHE_DIR": str(cache_dir / "mlx-ptx")}

    def available(self) -> dict[str, str | None]:
        reason = not_installed("mlx.core", self.package, extra="mlx")
        if reason:
            return {"cpu": reason, "cuda": reason}
        import mlx.core as mx
        cuda_module = getattr(mx, "cuda", None)         # absent from older MLX releases
        if cuda_module is not None and cuda_module.is_available():
            return {"cpu": None, "cuda": None}
        return {"cpu": None, "cuda": self._no_cuda_reason()}

    def _no_cuda_reason(self) -> str:
        """Why MLX cannot use CUDA: a build without the backend (the install command), or a CUDA
        build that sees no GPU."""
        builds = self.versions()
        cuda_builds = [d for d in builds if d.startswith("mlx-cuda")]
        if not cuda_builds:
            other = next((d for d in ("mlx-cpu", "mlx-metal") if d in builds), "mlx")
            return (f"this MLX build has no CUDA backend ({other} {builds.get(other, '?')}); "
                    f"on Linux with an NVIDIA GPU install: {CUDA_INSTALL}")
        seen = visible_gpus()
        return (f"MLX's CUDA build ({', '.join(cuda_builds)}) sees no usable GPU "
                f"(mlx.core.cuda.is_available() is False; the driver sees {seen} NVIDIA GPU(s))")

    def precision_unavailable(self, precision: str, device: str) -> str | None:
        """Why ``precision`` cannot run on ``device`` (decided without importing MLX), or None."""
        return NO_FLOAT64_GPU if precision == Precision.FLOAT64 and device != "cpu" else None

    def versions(self) -> dict[str, str]:
        out = {}
        for dist in ("mlx", *self.related_packages):
            try:
                out[dist] = importlib.metadata.version(dist)
            except importlib.metadata.PackageNotFoundError:
                pass
        return out

    def setup(self, device: str, precision: str, variant: str) -> None:
        why = self.precision_unavailable(precision, device)
        if why:
            raise RuntimeError(why)
        import mlx.core as mx
        mx.set_default_device(mlx_device(device))

    def ensure_context(self, device: str) -> None:
        import mlx.core as mx
        mx.eval(mx.zeros(1, stream=mlx_device(device)))

    def synchronize(self, device: str, result: Any) -> None:
        import mlx.core as mx
        if result is not None:
            mx.eval(result)
        else:
            mx.synchronize()

    def memory(self, device: str) -> dict[str, Any]:
        """MLX's allocator peak on a GPU; on the CPU host memory is measured by the worker."""
        if device != "cuda":
            return {}
        import mlx.core as mx
        return {"device_peak_bytes": int(mx.get_peak_memory()),
                "device_memory_source": "mlx get_peak_memory()"}


BACKEND = MlxBackend()
