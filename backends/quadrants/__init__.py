"""Quadrants backend: a port of the Taichi port (and so of the Warp reference) to Quadrants.

Quadrants (``pip install quadrants``, module ``quadrants``, conventionally ``qd``) is the
maintained fork of Taichi that Genesis uses; Taichi itself has had no release since 1.7.4. The
language is Taichi's with ``ti`` renamed ``qd`` (``qd.kernel``, ``qd.func``, ``qd.field``,
``qd.template()``, ``qd.static``, ``qd.select``, ``kernel.grad``). So saxpy, sdf, particles, copy
and launch are the Taichi kernels themselves, built with ``quadrants`` by the factory ``build`` of
backends/taichi/<scenario>.py; projectile.py has a step and rollout of its own (it drops the
Taichi 1.7 autodiff guards), says what differs and why, and builds the rest with ``quadrants`` from
backends/taichi/projectile_common.py. The differences that matter here:

* ``qd.init`` keeps Taichi's defaults where it matters: ``fast_math=True`` (we turn it off for the
  default variant, as for Taichi) and an on-disk cache (``offline_cache``), plus a second,
  source-level cache (``src_ll_cache``) that ``offline_cache=False`` leaves writing bookkeeping
  files: both are turned off so the first call includes compilation.
* Reverse-mode AD through a loop with a run-time trip count (the projectile's fused rollout) goes
  through Quadrants' *adstack* pipeline, opt-in with ``ad_stack_experimental_enabled=True``. Its
  stacks are sized per launch by a sizer that reads the loop bound (which must be a constant, a
  scalar integer field or an ndarray shape/entry, not a kernel scalar argument), so
  ``ad_stack_size`` stays 0 ("let the sizer decide") and there is no steps limit: the three
  silent Taichi 1.7 autodiff bugs the Taichi port guards against do not reproduce
  (docs/findings.md, projectile.py).

Quadrants is imported lazily: the driver imports this module without the framework to list
backends. Kernels use the default float type (``float`` annotations and literals), which ``setup``
sets to the cell's precision; each worker runs exactly one precision.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..base import Backend, Precision, not_installed
# Taichi's helpers, for either module name (the package's __init__ does not import Taichi)
from ..taichi import cuda_unavailable, framework_arch, framework_config_info, real_type


def _quiet() -> None:
    # No info-level log lines from the C++ core (Quadrants has no network version check).
    os.environ.setdefault("QD_LOG_LEVEL", "warn")


def config_info() -> dict[str, Any]:
    """How this process's Quadrants was initialised, for the kernels' info()."""
    return framework_config_info("quadrants")


def qd_arch(device: str):
    return framework_arch("quadrants", device)


def init_options(device: str, precision: Precision, variant: str) -> dict[str, Any]:
    """The qd.init keywords of a cell (tests use them to start Quadrants the same way)."""
    import quadrants as qd
    return dict(arch=qd_arch(device), enable_fallback=False,
                default_fp=real_type(qd, precision), default_ip=qd.i32,
                # Quadrants defaults to fast_math=True, like Taichi; IEEE unless the variant says
                fast_math=(variant == "fastmath"),
                # no on-disk caches: first_call_s includes compilation, workers never share one
                offline_cache=False, src_ll_cache=False,
                # reverse-mode AD through the projectile's run-time step loop (launch-time sized
                # adstacks; ad_stack_size=0 lets the sizer decide)
                ad_stack_experimental_enabled=True,
                random_seed=0)         # log level: QD_LOG_LEVEL (a keyword as well would warn)


class QuadrantsBackend(Backend):
    name = "quadrants"
    package = "quadrants"
    gradient_method = "ad"
    variants = ("default", "fastmath")
    # projectile.py: one launch per step (no adstack)
    scenario_variants = {"projectile": ("per_step",)}
    display_order, color = 6, "C6"     # after warp, taichi, jax, numba, cupy, torch; numpy is 9/C7

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # setup() also passes offline_cache=False and src_ll_cache=False to qd.init
        return {"QD_OFFLINE_CACHE_FILE_PATH": str(cache_dir / "quadrants"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def available(self) -> dict[str, str | None]:
        _quiet()
        reason = not_installed("quadrants", self.package, extra="quadrants")
        if reason:
            return {"cpu": reason, "cuda": reason}
        return {"cpu": None, "cuda": cuda_unavailable("quadrants", "Quadrants", offline_cache=False,
                                                      src_ll_cache=False)}

    def versions(self) -> dict[str, str]:
        import quadrants as qd
        return {"quadrants": ".".join(map(str, qd.__version__))}

    def setup(self, device: str, precision: str, variant: str) -> None:
        known = self.variants + tuple(v for vs in self.scenario_variants.values() for v in vs)
        if variant not in known:
            raise ValueError(f"quadrants variant must be one of {', '.join(known)}, "
                             f"got {variant!r}")
        _quiet()
        import quadrants as qd
        qd.init(**init_options(device, precision, variant))

    def synchronize(self, device: str, result: Any) -> None:
        import quadrants as qd
        qd.sync()


BACKEND = QuadrantsBackend()
