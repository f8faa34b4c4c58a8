"""PyTorch: eager ATen ops written in place into preallocated tensors; gradients by autograd.

Variants: "default" is eager PyTorch; "compile" runs each scenario's compiled unit through
``torch.compile(mode="default", fullgraph=True, dynamic=False)`` (Inductor: C++/OpenMP on the CPU,
Triton on CUDA). "compile_graphs" is the same with ``mode="reduce-overhead"``: Inductor's kernels
replayed as CUDA graphs (CUDAGraph Trees), PyTorch's documented answer to launch-bound code; CUDA
only (on the CPU the mode has nothing to graph). Its graphs skip any function that mutates an
input that is not static, so every tensor a compiled unit reads or writes is a preallocated buffer
marked static (``torch._dynamo.mark_static_address``: never copied into the graph's own input
buffers, and a write into it, such as ``out.copy_``, stays inside the graph), and
``cudagraph_or_error`` turns a skipped graph into an error: the cell never runs unlabelled eager
kernels. A replay overwrites the outputs of the previous replay; every kernel reads the last
run's outputs only. Particles also has "graph": the eager rollout captured once by the port with
``torch.cuda.graph`` and replayed per run (CUDA only). The harness's graph regime (``capture``:
torch.cuda.graph around one ``run()``) covers the default and "compile" variants; it refuses a
kernel that replays graphs itself (a graph launch inside a capture).

Precision: every tensor is made with an explicit dtype (never the global default dtype) and every
constant is a 0-d tensor of the cell's dtype on the cell's device, so float32 stays float32 and a
compiled graph sees the constants as inputs (not literals it may fold). TF32 is switched off in
``setup`` and read back into every kernel's ``info()``. Under the compile variants Inductor's
Triton division is made IEEE (``eager_numerics.division_rounding``); its default there is an
approximate division.

No autograd context is entered per call: the tensors of the forward scenarios never require a
gradient, so autograd records nothing, and a per-call ``torch.inference_mode()`` costs about 3 us
of host time on every call (a loop enters it once, outside, if at all).

PyTorch is imported lazily (inside functions and the kernel modules): the driver imports every
backend package without loading frameworks. The package is ``backends.torch``; ``import torch``
inside it is absolute and gets PyTorch itself.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..base import OWN_TIMER_S, Backend, Precision, not_installed, visible_gpus

CPU_WHEEL = "pip install torch --index-url https://download.pytorch.org/whl/cpu"

VARIANTS = ("default", "compile", "compile_graphs")
# torch.compile's mode of each compiled variant
MODES = {"compile": "default", "compile_graphs": "reduce-overhead"}
GRAPHED = ("compile_graphs", "graph")      # variants whose run() replays CUDA graphs itself
CUDA_ONLY = {"compile_graphs": "torch.compile's reduce-overhead mode (CUDA graphs) exists on CUDA only",
             "graph": "torch.cuda.graph exists on CUDA only"}


def torch_device(device: str) -> Any:
    import torch
    return torch.device("cuda", 0) if device == "cuda" else torch.device("cpu")


def torch_dtype(precision: Precision) -> Any:
    """PyTorch's dtype of the cell's precision (this backend's one map from Precision)."""
    import torch
    return {Precision.FLOAT32: torch.float32, Precision.FLOAT64: torch.float64}[precision]


def put(array: Any, precision: str, device: str) -> Any:
    """Upload a host array (or scalar: a 0-d tensor) with the cell's dtype, set explicitly."""
    import torch
    host = np.array(array, dtype=np.dtype(precision), order="C")   # keeps 0-d as 0-d
    return torch.tensor(host, dtype=torch_dtype(precision), device=torch_device(device))


def empty(shape: tuple[int, ...], precision: str, device: str) -> Any:
    import torch
    return torch.empty(shape, dtype=torch_dtype(precision), device=torch_device(device))


def download(t: Any) -> np.ndarray:
    return t.detach().cpu().numpy().copy()


def compiled(fn: Callable[..., Any], variant: str, static: tuple[Any, ...] = ()) -> Callable[..., Any] | None:
    """A compiled variant's wrapper of a scenario's compiled unit (None for an uncompiled one).
    ``static``: the preallocated tensors the unit reads or writes, marked static under
    "compile_graphs" (see the module docstring)."""
    if variant not in MODES:
        return None
    import torch
    mark_static(variant, *static)
    return torch.compile(fn, mode=MODES[variant], fullgraph=True, dynamic=False)


def mark_static(variant: str, *tensors: Any) -> None:
    """Under "compile_graphs", mark preallocated tensors static (before the first compiled call)."""
    if variant == "compile_graphs":
        import torch
        for t in tensors:
            torch._dynamo.mark_static_address(t)


def check_variant(variant: str, extra: tuple[str, ...] = ()) -> None:
    if variant not in VARIANTS + extra:
        raise ValueError(f"PyTorch has no variant {variant!r} here (offered: {VARIANTS + extra})")


def numerics(compiled: bool = True) -> dict[str, Any]:
    """The process's precision switches as PyTorch reports them (recorded in every info()).
    Inductor's and Dynamo's only for a compiled kernel: importing them costs an eager cell
    seconds, and they do not touch eager execution."""
    import torch
    out: dict[str, Any] = {"tf32_matmul": bool(torch.backends.cuda.matmul.allow_tf32),
                           "tf32_cudnn": bool(torch.backends.cudnn.allow_tf32),
                           "float32_matmul_precision": torch.get_float32_matmul_precision()}
    if not compiled:
        return out
    from torch._dynamo.utils import counters
    # graphs Inductor skipped (an error under cudagraph_or_error): 0 wherever graphs ran
    out["cudagraph_skips"] = int(counters["inductor"]["cudagraph_skips"])
    try:
        from torch._inductor import config
        out["inductor_division_rounding"] = bool(config.eager_numerics.division_rounding)
    except Exception:  # an Inductor without the switch: the record says so
        out["inductor_division_rounding"] = None
    try:
        import torch._dynamo.config as dynamo
        out["dynamo_fail_on_recompile_limit_hit"] = bool(dynamo.fail_on_recompile_limit_hit)
    except Exception:
        out["dynamo_fail_on_recompile_limit_hit"] = None
    return out


def kernel_info(variant: str, **facts: Any) -> dict[str, Any]:
    how = {"default": "eager", "graph": "eager, captured by torch.cuda.graph and replayed"}.get(variant)
    how = how or f"torch.compile(mode={MODES[variant]!r}, fullgraph=True, dynamic=False)"
    return {"execution": how, **facts, **numerics(variant in MODES)}


class TorchCuda(Backend):
    """CUDA hooks of a backend whose kernels run on PyTorch tensors and PyTorch's current stream:
    this one, and Triton's (backends/triton), which launches on that stream."""

    def ensure_context(self, device: str) -> None:
        if device == "cuda":
            import torch
            torch.cuda.init()
            torch.cuda.synchronize(torch_device(device))   # creates the primary context now

    def synchronize(self, device: str, result: Any) -> None:
        if device == "cuda":
            import torch
            torch.cuda.synchronize(torch_device(device))

    def capture(self, device: str, run: Any) -> Any:
        """``torch.cuda.graph`` of one ``run()`` (after a warm-up call on a side stream, as the
        PyTorch CUDA-graph docs require; Triton has autotuned at the first call already),
        replayed with ``CUDAGraph.replay``; CUDA only."""
        if device != "cuda":
            return None
        if getattr(getattr(run, "__self__", None), "variant", None) in GRAPHED:
            raise RuntimeError("this variant's run() replays CUDA graphs itself: none is captured around it")
        import torch
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(side):
            run()
        torch.cuda.current_stream().wait_stream(side)
        graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(graph):
            run()
        return graph.replay

    def event_timer(self, device: str) -> "TorchEvents | None":
        return TorchEvents() if device == "cuda" else None

    def own_latency(self, device: str, call: Any) -> dict[str, Any] | None:
        """``torch.utils.benchmark.Timer.blocked_autorange``: the median of its blocks' mean call
        (``block`` calls a block), not of single calls."""
        import torch
        from torch.utils import benchmark
        # the Timer runs on one thread unless told: the cell's own thread count (CPU cells)
        m = benchmark.Timer(stmt="call()", globals={"call": call},
                            num_threads=torch.get_num_threads()).blocked_autorange(min_run_time=OWN_TIMER_S)
        return {"tool": "torch.utils.benchmark.Timer.blocked_autorange", "median_s": float(m.median),
                "calls": int(m.number_per_run * len(m.times)), "block": int(m.number_per_run)}

    def memory(self, device: str) -> dict[str, Any]:
        return allocator_memory(torch_device(device)) if device == "cuda" else {}


class TorchBackend(TorchCuda):
    name = "torch"
    package = "torch"
    gradient_method = "ad"
    variants = VARIANTS
    scenario_variants = {"particles": ("graph",)}     # the eager rollout as one captured CUDA graph
    display_order, color = 5, "C5"
    related_packages = ("triton",)

    def variant_unavailable(self, variant: str, device: str) -> str | None:
        return CUDA_ONLY.get(variant) if device != "cuda" else None

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # torch.compile's FX-graph/Inductor cache and Triton's kernel cache, and the CUDA driver's
        # PTX cache: empty per cell, so a compile variant's first call includes compilation.
        return {"TORCHINDUCTOR_CACHE_DIR": str(cache_dir / "inductor"),
                "TRITON_CACHE_DIR": str(cache_dir / "triton"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def available(self) -> dict[str, str | None]:
        # without an NVIDIA GPU the CPU wheel (about 200 MB), not the default CUDA one (several GB)
        reason = not_installed("torch", self.package, extra="torch", first="" if visible_gpus() else CPU_WHEEL)
        if reason:
            return {"cpu": reason, "cuda": reason}
        import torch
        if torch.cuda.is_available():
            cuda = None
        elif torch.version.cuda is None:
            cuda = f"this PyTorch build has no CUDA support (torch {torch.__version__})"
        else:
            cuda = f"no CUDA device visible to PyTorch (torch {torch.__version__}, CUDA {torch.version.cuda})"
        return {"cpu": None, "cuda": cuda}

    def versions(self) -> dict[str, str]:
        import torch
        out = {"torch": torch.__version__, "torch_cuda": str(torch.version.cuda)}
        if torch.cuda.is_available():
            out["cudnn"] = str(torch.backends.cudnn.version())
        return out

    def setup(self, device: str, precision: str, variant: str) -> None:
        import torch
        check_variant(variant, ("graph",))
        # No TF32 anywhere (no scenario multiplies matrices today; a future one must not get
        # 10-bit mantissas silently): full float32 matmul and convolution precision.
        torch.backends.cuda.matmul.allow_tf32 = False
        torch.backends.cudnn.allow_tf32 = False
        torch.set_float32_matmul_precision("highest")
        if variant in MODES:
            import torch._dynamo.config as dynamo
            from torch._inductor import config
            # IEEE x/y in Triton, as eager (info() records None where this Inductor lacks it)
            if hasattr(config, "eager_numerics"):
                config.eager_numerics.division_rounding = True
            # Never fall back to eager silently: the cell would be labelled "compile" and run
            # eager. Several cells in one process (the test suites) compile one function for
            # several shapes/dtypes, more than the default limit of 8 entries.
            # (names of torch 2.13; older releases call the limit cache_size_limit)
            limit = "recompile_limit" if hasattr(dynamo, "recompile_limit") else "cache_size_limit"
            setattr(dynamo, limit, 64)
            if hasattr(dynamo, "fail_on_recompile_limit_hit"):
                dynamo.fail_on_recompile_limit_hit = True
            # a graph reduce-overhead would skip is an error, not eager kernels labelled graphs
            # (CUDA only: on the CPU, where the variant is unavailable, every graph is skipped)
            if variant == "compile_graphs" and device == "cuda":
                config.triton.cudagraph_or_error = True
        if device == "cuda":
            torch.cuda.set_device(torch_device(device))


def allocator_memory(dev: Any) -> dict[str, Any]:
    """Peak bytes of PyTorch's CUDA caching allocator on ``dev`` (tensors, not its cached free
    blocks); also Triton's, whose kernels work on PyTorch tensors."""
    import torch
    return {"device_peak_bytes": int(torch.cuda.max_memory_allocated(dev)),
            "device_reserved_peak_bytes": int(torch.cuda.max_memory_reserved(dev)),
            "device_memory_source": "torch.cuda.max_memory_allocated (caching allocator)"}


class TorchEvents:
    description = "CUDA events (torch.cuda.Event on the current stream) around run()"

    def __init__(self) -> None:
        import torch
        self.torch = torch
        self.a = torch.cuda.Event(enable_timing=True)
        self.b = torch.cuda.Event(enable_timing=True)

    def start(self) -> None:
        self.a.record(self.torch.cuda.current_stream())

    def stop(self) -> None:
        self.b.record(self.torch.cuda.current_stream())

    def elapsed_s(self) -> float:
        self.b.synchronize()
        return self.a.elapsed_time(self.b) * 1e-3          # milliseconds


BACKEND = TorchBackend()
