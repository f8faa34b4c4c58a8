"""Taichi backend (a port of the Warp reference).

Taichi is imported lazily: the driver imports this module without the framework to list backends.
Kernels use Taichi's default float type (``float`` annotations and literals), which ``setup`` sets
to the cell's precision; each worker process runs exactly one precision, so no kernel is ever
compiled for two. Except projectile.py, each scenario module defines its kernels and ``Kernel``
class once, in ``build(ti)``, a factory over the framework module: Quadrants (backends/quadrants),
Taichi's maintained fork, has the same API under the name ``quadrants`` and calls the same factory.
Here ``build(taichi)`` runs on the first use of the module's ``Kernel`` (``built_on_first_use``),
not at import, so that the Quadrants backend can import the factory without Taichi.
"""
from __future__ import annotations

import importlib
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from ..base import Backend, Precision, not_installed


# The deepest autodiff stacks (adstacks) Taichi may use, by device. The projectile's fused backward
# kernel needs steps + 1 entries per stack; Taichi cannot size stacks for a run-time trip count and
# would fall back to 32, overflowing silently. Stacks are allocas: the CPU thread's own stack,
# per-thread local memory on CUDA, where 4096 fails to launch (CUDA_ERROR_INVALID_VALUE, H200) and
# 1024 runs. setup() passes this ceiling to ti.init; the projectile kernel then compiles its
# backward kernel for the depth its rollout needs (steps + margin, projectile.py), since the
# driver reserves local memory for that depth in every resident thread. Longer rollouts take the
# one-launch-per-step path.
AD_STACK_SIZE = {"cpu": 4096, "cuda": 1024}


def _quiet() -> None:
    # No network version check from inside a benchmark worker.
    os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


# The helpers below take the framework's module name, "taichi" or "quadrants" (Taichi's fork,
# same API): backends/quadrants uses them too. Each imports the framework only when called.

def framework_config_info(framework: str) -> dict[str, Any]:
    """How this process's Taichi (or Quadrants) was initialised, for the kernels' info()."""
    cfg = importlib.import_module(f"{framework}.lang.impl").current_cfg()
    return {"fast_math": bool(cfg.fast_math), "arch": str(cfg.arch).rsplit(".", 1)[-1]}


def framework_arch(framework: str, device: str):
    fw = importlib.import_module(framework)
    return fw.cuda if device == "cuda" else fw.cpu


def cuda_unavailable(framework: str, title: str, **init_options: Any) -> str | None:
    """None if the framework starts on CUDA (``init`` with ``init_options``), else why not, in
    one line; the framework is reset either way."""
    fw = importlib.import_module(framework)
    try:
        # enable_fallback=False: init would otherwise quietly start on the CPU instead.
        fw.init(arch=fw.cuda, enable_fallback=False, **init_options)
    except Exception as exc:  # no driver / no device / unsupported arch
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return f"{title} CUDA arch did not initialise: {first}"
    finally:
        fw.reset()
    return None


def built_on_first_use(module_globals: dict[str, Any], build: Callable[[ModuleType], Sequence[Any]],
                       names: Sequence[str]) -> Callable[[str], Any]:
    """A scenario module's ``__getattr__``: on the first access to one of ``names`` (the module's
    kernels and its ``Kernel``), ``build(taichi)`` and store what it returns, in that order, as
    module globals (so later accesses, and tests that list a module's kernels, see them). Not at
    import: backends/quadrants imports these modules for ``build`` alone and must not import
    Taichi (a second runtime in its worker, and none at all in a Quadrants-only install)."""
    def __getattr__(name: str) -> Any:
        if name not in names:
            raise AttributeError(f"module {module_globals['__name__']!r} has no attribute {name!r}")
        import taichi
        module_globals.update(zip(names, build(taichi), strict=True))
        return module_globals[name]
    return __getattr__


def config_info() -> dict[str, Any]:
    """How this process's Taichi was initialised, for the kernels' info()."""
    return framework_config_info("taichi")


def real_type(fw: ModuleType, precision: Precision) -> Any:
    """The default float type of the cell's precision, for Taichi or Quadrants (``fw``: the
    framework module): these two backends' one map from Precision."""
    return {Precision.FLOAT32: fw.f32, Precision.FLOAT64: fw.f64}[precision]


def ti_arch(device: str):
    return framework_arch("taichi", device)


class TaichiBackend(Backend):
    name = "taichi"
    package = "taichi"
    gradient_method = "ad"
    variants = ("default", "fastmath")
    # projectile.py: segments recomputed; one launch per step (no adstack)
    scenario_variants = {"projectile": ("checkpoint", "per_step")}
    ad_stack_limit: int | None = None  # the ceiling setup() passed to ti.init (AD_STACK_SIZE)
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
        return {"cpu": None,
                "cuda": cuda_unavailable("taichi", "Taichi", offline_cache=False, log_level="error")}

    def versions(self) -> dict[str, str]:
        import taichi as ti
        return {"taichi": ".".join(map(str, ti.__version__))}

    def setup(self, device: str, precision: Precision, variant: str) -> None:
        known = self.variants + tuple(v for vs in self.scenario_variants.values() for v in vs)
        if variant not in known:
            raise ValueError(f"taichi variant must be one of {', '.join(known)}, got {variant!r}")
        _quiet()
        import taichi as ti
        self.ad_stack_limit = AD_STACK_SIZE[device]
        ti.init(arch=ti_arch(device), enable_fallback=False,
                default_fp=real_type(ti, precision), default_ip=ti.i32,
                # Taichi defaults to fast_math=True; the comparison uses IEEE arithmetic and reports
                # fast math as its own variant.
                fast_math=(variant == "fastmath"),
                # No on-disk kernel cache: first_call_s then always includes compilation, and
                # concurrent workers never share (or race on) a cache directory.
                offline_cache=False,
                ad_stack_size=self.ad_stack_limit, random_seed=0, log_level="warn")

    def synchronize(self, device: str, result: Any) -> None:
        import taichi as ti
        ti.sync()


BACKEND = TaichiBackend()
