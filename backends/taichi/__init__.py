"""Taichi backend (a port of the Warp reference).

Taichi is imported lazily: the driver imports this module without the framework to list backends.
Kernels in the scenario modules are defined once at module level and use Taichi's default float
type (``float`` annotations and literals), which ``setup`` sets to the cell's precision; each worker
process runs exactly one precision, so no kernel is ever compiled for two.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..base import Backend, not_installed


# Depth of Taichi's autodiff stacks, process-global and fixed at ti.init. The projectile's fused
# backward kernel needs steps + 1 entries per stack; Taichi cannot size stacks for a runtime trip
# count and would fall back to 32, overflowing silently. Stacks are allocas: the CPU thread's own
# stack, per-thread local memory on CUDA, where 4096 fails to launch (CUDA_ERROR_INVALID_VALUE,
# H200) and 1024 runs. Longer rollouts take the one-launch-per-step path (see projectile.py).
AD_STACK_SIZE = {"cpu": 4096, "cuda": 1024}


def _quiet() -> None:
    # No network version check from inside a benchmark worker.
    os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


def config_info() -> dict[str, Any]:
    """How this process's Taichi was initialised, for the kernels' info()."""
    from taichi.lang import impl
    cfg = impl.current_cfg()
    return {"fast_math": bool(cfg.fast_math), "arch": str(cfg.arch).rsplit(".", 1)[-1]}


def ti_arch(device: str):
    import taichi as ti
    return ti.cuda if device == "cuda" else ti.cpu


class TaichiBackend(Backend):
    name = "taichi"
    package = "taichi"
    gradient_method = "ad"
    variants = ("default", "fastmath")
    scenario_variants = {"projectile": ("checkpoint",)}   # segments recomputed (projectile.py)
    display_order, color = 1, "C1"

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # setup() also passes offline_cache=False to ti.init; the variable covers Taichi's default
        return {"TI_OFFLINE_CACHE_FILE_PATH": str(cache_dir / "taichi"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

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
        known = self.variants + tuple(v for vs in self.scenario_variants.values() for v in vs)
        if variant not in known:
            raise ValueError(f"taichi variant must be one of {', '.join(known)}, got {variant!r}")
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
                ad_stack_size=AD_STACK_SIZE[device], random_seed=0, log_level="warn")

    def synchronize(self, device: str, result: Any) -> None:
        import taichi as ti
        ti.sync()


BACKEND = TaichiBackend()
