"""Dr.Jit: a tracing JIT; every run() traces array expressions and evaluates them as fused kernels.

Dr.Jit records operations on its arrays lazily and compiles what ``dr.eval`` asks for into one
kernel per evaluation (kernels are cached by their IR, in memory and on disk, so a repeated run()
traces again but compiles nothing). Its types carry device and precision: ``drjit.llvm`` (CPU,
vectorised through the system's libLLVM, over a thread pool) or ``drjit.cuda``, ``Float`` (float32)
or ``Float64``, and the ``.ad`` submodules for arrays that take part in reverse-mode AD. So nothing
is process-global here but one flag: each kernel picks its types from the cell's device and precision.

Scalars (SAXPY's ``a``, the physical constants) go in as ``dr.opaque`` arrays of one element:
Dr.Jit folds Python scalars into the kernel as literals, which would compile one kernel per value
and let the simplifier fold them with each other. Dr.Jit's defaults are kept, but for one:
FastMath (on by default) is off, as every ranked figure of this comparison is IEEE arithmetic
(docs/ports.md, "Rules applied to every port"): Taichi's and quadrants' fast-math defaults are
turned off alike. Dr.Jit's shipped default is measured as the ``fastmath`` variant, shown on the
pages and never ranked. In float64 it would also be wrong, not only approximate: on CUDA it makes
the reciprocal an approximate PTX instruction in float64 too (about 20 bits), and with it the
reverse-mode derivatives of log, division and sqrt (docs/findings.md, entry 9).

The CPU needs a libLLVM at run time (found on the default path or through DRJIT_LIBLLVM_PATH), of
version 17 or newer: Dr.Jit 1.5 compiles ``dr.maximum``/``dr.minimum`` of floats to LLVM's
``llvm.maximum``/``llvm.minimum`` intrinsics, which the x86 code generator of LLVM 15 and 16
cannot select; the worker process then aborts (docs/findings.md).
"""
from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..base import Backend, Precision, cuda_build_hint, not_installed

# x86 instruction selection of llvm.maximum/llvm.minimum arrived in LLVM 17 (llvm-project #53353)
MIN_LLVM = 17
LLVM_INSTALL = ("apt-get install -y libllvm19 (Debian 12; or point DRJIT_LIBLLVM_PATH at a "
                f"libLLVM >= {MIN_LLVM})")


def jit_module(device: str, ad: bool = False) -> Any:
    """``drjit.llvm`` or ``drjit.cuda`` (their ``.ad`` variants with ``ad``): the array types."""
    name = "drjit.cuda" if device == "cuda" else "drjit.llvm"
    return importlib.import_module(name + (".ad" if ad else ""))


def real_type(device: str, precision: Precision, ad: bool = False) -> Any:
    """The cell's floating-point array type: ``Float`` (float32) or ``Float64`` (this backend's
    one map from Precision)."""
    return getattr(jit_module(device, ad), {Precision.FLOAT32: "Float", Precision.FLOAT64: "Float64"}[precision])


def fast_math() -> dict[str, bool]:
    """The FastMath flag the cell's kernels were traced under (for the record's info)."""
    import drjit as dr
    return {"fast_math": bool(dr.flag(dr.JitFlag.FastMath))}


def upload(array: np.ndarray, cls: Any) -> Any:
    """A host array as an evaluated Dr.Jit array of ``cls`` (flattened, contiguous)."""
    import drjit as dr
    out = cls(np.ascontiguousarray(np.asarray(array).reshape(-1)))
    dr.eval(out)
    return out


def scalar(value: Any, cls: Any) -> Any:
    """A run-time scalar: an evaluated one-element array, never a literal folded into the kernel."""
    import drjit as dr
    return dr.opaque(cls, float(value))


def download(x: Any, dtype: Any, shape: tuple[int, ...]) -> np.ndarray:
    """A Dr.Jit array as a NumPy array of ``dtype`` and ``shape`` (a copy on CUDA; on the CPU a
    view that keeps the Dr.Jit buffer alive, which no later run() writes into)."""
    out = np.asarray(x.numpy()).reshape(shape)
    if out.dtype != np.dtype(dtype):
        raise TypeError(f"Dr.Jit returned {out.dtype}, the cell's precision is {np.dtype(dtype)}")
    return out


class DrJitBackend(Backend):
    name = "drjit"
    package = "drjit"
    gradient_method = "ad"
    display_order, color = 8, "C9"
    # fastmath: Dr.Jit's shipped default (JitFlag.FastMath on); default cells run exact (setup)
    variants = ("default", "fastmath")
    # checkpoint: nested symbolic loops, sqrt(steps) segments; evaluated: one kernel per step
    # (backends/drjit/projectile.py says what each trades)
    scenario_variants = {"projectile": ("checkpoint", "evaluated")}

    def available(self) -> dict[str, str | None]:
        reason = not_installed("drjit", self.package, extra="drjit")
        if reason:
            return {"cpu": reason, "cuda": reason}
        import drjit as dr
        return {"cpu": self._llvm_reason(dr), "cuda": self._cuda_reason(dr)}

    @staticmethod
    def _llvm_reason(dr: Any) -> str | None:
        if not dr.has_backend(dr.JitBackend.LLVM):
            return f"Dr.Jit found no usable libLLVM for its CPU backend (install: {LLVM_INSTALL})"
        version = tuple(dr.detail.llvm_version())
        if version[0] < MIN_LLVM:
            return (f"Dr.Jit found libLLVM {'.'.join(map(str, version))}, whose x86 code generator "
                    f"aborts on the llvm.maximum/minimum that Dr.Jit emits for dr.maximum/"
                    f"dr.minimum (docs/findings.md; install: {LLVM_INSTALL})")
        return None

    @staticmethod
    def _cuda_reason(dr: Any) -> str | None:
        if dr.has_backend(dr.JitBackend.CUDA):
            return None
        return cuda_build_hint("no CUDA device visible to Dr.Jit (it loads the driver's libcuda.so)")

    def versions(self) -> dict[str, str]:
        import drjit as dr
        out = {"drjit": dr.__version__}
        if dr.has_backend(dr.JitBackend.LLVM):
            out["libllvm"] = ".".join(map(str, dr.detail.llvm_version()))
        return out

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # Dr.Jit's own on-disk cache (LLVM kernels) and the CUDA driver's PTX cache
        return {"DRJIT_CACHE_DIR": str(cache_dir / "drjit"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def ran_fast_math(self, precision: str, info: Mapping[str, Any] | None) -> bool:
        # Every kernel's info records the flag; a record without it predates that, when float32
        # cells ran Dr.Jit's FastMath default
        if info and "fast_math" in info:
            return info["fast_math"] is True
        return precision == "float32"

    def setup(self, device: str, precision: str, variant: str) -> None:
        import drjit as dr
        # the shipped default (FastMath on) only as its own variant; never in float64 (findings #9)
        dr.set_flag(dr.JitFlag.FastMath, variant == "fastmath" and precision == "float32")

    def ensure_context(self, device: str) -> None:
        import drjit as dr
        x = real_type(device, Precision.FLOAT32)(0.0) + 1.0     # initialises the backend, its context
        dr.eval(x)
        dr.sync_thread()

    def synchronize(self, device: str, result: Any) -> None:
        """run() has scheduled its kernels with ``dr.eval``; wait for the device (CUDA stream) or
        the LLVM thread pool to finish them."""
        import drjit as dr
        dr.sync_thread()

    def memory(self, device: str) -> dict[str, Any]:
        """Peak bytes of Dr.Jit's CUDA allocator (its watermark); nothing on the CPU."""
        if device != "cuda":
            return {}
        import drjit as dr
        return {"device_peak_bytes": int(dr.detail.malloc_watermark(dr.JitBackend.CUDA)),
                "device_memory_source": "drjit.detail.malloc_watermark (Dr.Jit's allocator)"}


BACKEND = DrJitBackend()
