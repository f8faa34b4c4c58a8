"""JAX: every timed computation is one jax.jit program; gradients by reverse-mode AD.

JAX is imported lazily (inside functions), because the driver imports every backend package
without loading frameworks. Precision is process-global in JAX (the ``jax_enable_x64`` flag), which
is why ``setup`` sets it per worker process and before any array exists.
"""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Callable, Sequence

from ..base import Backend, Precision, cuda_build_hint, not_installed

# Platform names JAX may register a CUDA GPU under (newer jaxlib: "cuda"; older: "gpu").
_GPU_PLATFORMS = ("cuda", "gpu")


def jax_device(device: str) -> Any:
    """The jax.Device for the driver's device name ('cpu' or 'cuda')."""
    import jax
    if device == "cpu":
        return jax.devices("cpu")[0]
    errors = []
    for platform in _GPU_PLATFORMS:
        try:
            return jax.devices(platform)[0]
        except RuntimeError as exc:
            errors.append(str(exc).strip().splitlines()[0])
    raise RuntimeError(f"no CUDA device visible to JAX ({errors[-1]})")


def jax_dtype(precision: Precision) -> Any:
    """JAX's dtype of the cell's precision (this backend's one map from Precision)."""
    import jax.numpy as jnp
    return {Precision.FLOAT32: jnp.float32, Precision.FLOAT64: jnp.float64}[precision]


# Time steps per while-loop iteration of the particle and projectile loops: on a GPU each trip
# of an XLA while loop costs a fixed host/device round, which unrolling amortises, and a longer
# unroll lengthens compiles; on the CPU unrolling does not pay (docs/measurement.md, "JAX's loop
# unrolling", has the measurements behind both numbers).
UNROLL = {"cpu": 1, "cuda": 16}


def put(array: Any, precision: Precision, device: Any) -> Any:
    """Upload a host array (or scalar) as a committed device array of the cell's dtype."""
    import jax
    import numpy as np
    return jax.device_put(np.asarray(array, dtype=np.dtype(jax_dtype(precision))), device)


class Program:
    """A jax.jit function, compiled ahead of time on its first call.

    Compiling inside the first call keeps compilation in the driver's first-call time (the
    constructor is not timed as compute) and leaves the executable at hand for its memory figures.
    ``donate`` names the arguments whose buffers the program may reuse for its outputs: the caller
    passes the previous call's outputs back there, so a steady-state call allocates nothing new.
    ``keep_unused`` is needed because those arguments are never read, and jit would otherwise
    prune them (and with them the aliasing).
    """

    def __init__(self, fn: Callable[..., Any], donate: Sequence[int] = ()) -> None:
        import jax
        self.donate = tuple(donate)
        self.jitted = jax.jit(fn, donate_argnums=self.donate, keep_unused=True)
        self.compiled: Any = None
        self.donated: bool | None = None

    def __call__(self, *args: Any) -> Any:
        if self.compiled is not None:
            return self.compiled(*args)
        import jax
        with warnings.catch_warnings():
            # A platform that cannot alias buffers falls back to fresh outputs; info() reports it.
            warnings.filterwarnings("ignore", message=".*donated buffers were not usable.*")
            self.compiled = self.jitted.lower(*args).compile()
            out = self.compiled(*args)
        donated = [leaf for i in self.donate for leaf in jax.tree_util.tree_leaves(args[i])]
        self.donated = bool(donated) and all(leaf.is_deleted() for leaf in donated)
        return out

    def info(self) -> dict[str, Any]:
        out: dict[str, Any] = {"compiled": "jit (AOT on first call)", "donated": self.donated}
        stats = self.compiled.memory_analysis() if self.compiled is not None else None
        if stats is not None:
            out["temp_bytes"] = int(stats.temp_size_in_bytes)
            out["argument_bytes"] = int(stats.argument_size_in_bytes)
            out["output_bytes"] = int(stats.output_size_in_bytes)
            out["alias_bytes"] = int(stats.alias_size_in_bytes)
        return out


# XLA:GPU records a program's kernels into command buffers (CUDA graphs) and launches each as one
# graph. By default only runs of >= 5 fusions, library calls and custom calls are recorded, so a
# one-kernel program and the body of a loop (lax.scan/fori_loop lower to a while) launch kernel by
# kernel. The `graph` variant records every run (min size 1) and while/conditional loops as well
# (CUDA conditional nodes): JAX's graph fast path, set per process (the XLA flags documentation:
# https://openxla.org/xla/flags_guidance).
GRAPH_FLAGS = ("--xla_gpu_enable_command_buffer=FUSION,CUBLAS,CUBLASLT,CUSTOM_CALL,CUDNN,WHILE,CONDITIONAL"
               " --xla_gpu_graph_min_graph_size=1")


class JaxBackend(Backend):
    name = "jax"
    package = "jax"
    gradient_method = "ad"
    display_order, color = 2, "C2"
    related_packages = ("jaxlib", "jax-cuda12-plugin", "jax-cuda13-plugin")
    # graph: XLA command buffers (CUDA graphs) for every program, loops included (GRAPH_FLAGS)
    variants = ("default", "graph")
    # jax.checkpoint around segments of ~sqrt(steps) steps (backends/jax/projectile.py)
    scenario_variants = {"projectile": ("checkpoint",)}

    def variant_environment(self, variant: str) -> dict[str, str]:
        return {"XLA_FLAGS": GRAPH_FLAGS} if variant == "graph" else {}

    def variant_unavailable(self, variant: str, device: str) -> str | None:
        if variant == "graph" and device != "cuda":
            return "XLA command buffers (CUDA graphs) exist on CUDA only"
        return None

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # JAX's persistent compilation cache is off unless configured: keep it off
        return {"JAX_ENABLE_COMPILATION_CACHE": "false", "JAX_COMPILATION_CACHE_DIR": ""}

    def ensure_context(self, device: str) -> None:
        import jax
        jax.device_put(0.0, jax_device(device)).block_until_ready()

    def worker_environment(self) -> dict[str, str]:
        # JAX would otherwise grab 75% of GPU memory at start; measure what it needs instead
        return {"XLA_PYTHON_CLIENT_PREALLOCATE": "false"}

    def available(self) -> dict[str, str | None]:
        reason = not_installed("jax", self.package)
        if reason:
            return {"cpu": reason, "cuda": reason}
        try:
            jax_device("cuda")
            cuda = None
        except RuntimeError as exc:
            cuda = cuda_build_hint(str(exc).strip().splitlines()[0])
        return {"cpu": None, "cuda": cuda}

    def versions(self) -> dict[str, str]:
        import jax
        import jaxlib
        return {"jax": jax.__version__, "jaxlib": jaxlib.__version__}

    def setup(self, device: str, precision: str, variant: str) -> None:
        import os
        if variant == "graph" and GRAPH_FLAGS not in os.environ.get("XLA_FLAGS", ""):
            # the user's own XLA_FLAGS win over variant_environment: never time a non-graph run
            # as the graph variant
            raise RuntimeError(f"the graph variant needs XLA_FLAGS to contain {GRAPH_FLAGS!r}; "
                               f"it is {os.environ.get('XLA_FLAGS', '')!r}")
        import jax
        # Per process (each cell is its own worker) and before any array is created: arrays made
        # under the other setting would keep their dtype.
        jax.config.update("jax_enable_x64", precision == Precision.FLOAT64)
        jax.config.update("jax_default_device", jax_device(device))

    def synchronize(self, device: str, result: Any) -> None:
        import jax
        jax.block_until_ready(result)

    def memory(self, device: str) -> dict[str, Any]:
        """Peak bytes of JAX's GPU allocator (the worker disables preallocation); CPU: nothing."""
        if device != "cuda":
            return {}
        stats = jax_device(device).memory_stats() or {}
        if "peak_bytes_in_use" not in stats:
            return {"device_memory_source": "jax memory_stats() has no peak_bytes_in_use"}
        return {"device_peak_bytes": int(stats["peak_bytes_in_use"]),
                "device_memory_source": "jax memory_stats() peak_bytes_in_use"}


BACKEND = JaxBackend()
