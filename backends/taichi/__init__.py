"""Taichi backend (a port of the Warp reference).

Taichi is imported lazily: the driver imports this module without the framework to list backends.
Kernels in the scenario modules are defined once at module level and use Taichi's default float
type (``float`` annotations and literals), which ``setup`` sets to the cell's precision; each worker
process runs exactly one precision, so no kernel is ever compiled for two.
"""
from __future__ import annotations

import os
from typing import Any

from ..base import Backend, not_installed


def _quiet() -> None:
    # No network version check from inside a benchmark worker.
    os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


def ti_arch(device: str):
    import taichi as ti
    return ti.cuda if device == "cuda" else ti.cpu


class TaichiBackend(Backend):
    name = "taichi"
    package = "taichi"
    gradient_method = "ad"
    variants = ("default", "fastmath")

    def available(self) -> dict[str, str | None]:
        _quiet()
        reason = not_installed("taichi", self.package)
        if reason:
            return {"cpu": reason, "cuda": reason}
        import taichi as ti
        cuda: str | None = None
        try:
            # enable_fallback=False: ti.init would otherwise quietly start on the CPU instead.
            ti.init(arch=ti.cuda, enable_fallback=False, offline_cache=False, log_level="error")
        except Exception as exc:  # no driver / no device / unsupported arch
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            cuda = f"Taichi CUDA arch did not initialise: {first}"
        finally:
            ti.reset()
        return {"cpu": None, "cuda": cuda}

    def versions(self) -> dict[str, str]:
        import taichi as ti
        return {"taichi": ".".join(map(str, ti.__version__))}

    def setup(self, device: str, precision: str, variant: str) -> None:
        _quiet()
        import taichi as ti
        ti.init(arch=ti_arch(device), enable_fallback=False,
                default_fp=ti.f32 if precision == "float32" else ti.f64, default_ip=ti.i32,
                # Taichi defaults to fast_math=True; the comparison uses IEEE arithmetic and reports
                # fast math as its own variant.
                fast_math=(variant == "fastmath"),
                # No on-disk kernel cache: first_call_s then always includes compilation, and
                # concurrent workers never share (or race on) a cache directory.
                offline_cache=False,
                random_seed=0, log_level="warn")

    def synchronize(self, device: str, result: Any) -> None:
        import taichi as ti
        ti.sync()


BACKEND = TaichiBackend()
