"""Triton: kernels written with ``@triton.jit`` (block-level Python), tensors from PyTorch.

Why these choices:
  * CUDA only for timing. Triton compiles for GPUs; on the CPU it runs kernels only in its
    interpreter (``TRITON_INTERPRET=1``), which executes every program of the grid one after
    another in NumPy: a correctness tool, not a CPU backend. So ``available()`` never offers the
    CPU to ``compare`` (its cells are skips naming the interpreter), and under
    ``TRITON_INTERPRET=1`` not CUDA either (the kernels would be the interpreter's, not compiled).
    tests/backends/test_triton.py runs the kernels under the interpreter on the CPU for parity.
  * Precision. Triton types a Python float kernel argument as fp32, so a float64 kernel would see
    rounded constants: scalar inputs travel in a small device tensor of the cell's dtype (``put``)
    and are loaded in the kernel. Literals in kernel code (``0.35``) are materialised in the dtype
    of the tensor they meet, i.e. rounded once from the double, as CuPy's ``R(0.35)``.
  * IEEE arithmetic (fmath.py): Triton lowers float32 ``/``, ``tl.sqrt`` and ``tl.exp`` to
    approximate PTX (``div.full``, ``sqrt.approx``, ``ex2.approx``); the kernels call libdevice's
    correctly rounded division and square root and its exp/log/sin (what CUDA C's ``/``,
    ``sqrtf``, ``expf`` are under nvcc/NVRTC defaults, as in the CuPy port).
  * FMA contraction is requested explicitly at every launch (``enable_fp_fusion=True``), as Warp's,
    Numba's and NVRTC's defaults contract (Triton 3.10 turns its own default off), and libdevice
    is linked without flush-to-zero (``enable_reflect_ftz=False``; Triton's default flushes float32
    subnormals in div_rn, sqrt_rn, exp ..., CUDA C's does not).
  * Launches go on PyTorch's current stream, so the CUDA hooks are PyTorch's (``TorchCuda``:
    context, synchronize, ``capture`` as ``torch.cuda.graph``, events, the allocator's memory
    figure; Triton allocates nothing itself here).
Importing this package does not import triton or torch (the driver imports every backend package).
"""
from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..base import DEFAULT_VARIANT, cuda_build_hint, not_installed
from ..torch import TorchCuda   # Triton takes its tensors and stream from PyTorch

CPU_REASON = ("Triton compiles for GPUs only; its CPU interpreter (TRITON_INTERPRET=1: NumPy, one "
              "program at a time) is for correctness and is not timed (tests/backends/test_triton.py runs "
              "the parity cases under it)")
INTERPRETER_REASON = ("TRITON_INTERPRET=1 is set: kernels would run in Triton's interpreter "
                      "(correctness only), not compiled for the GPU; unset it to time CUDA")
# Contract a*b + c into one FMA at every launch (Warp's, Numba's and NVRTC's CUDA defaults).
FP_FUSION = True
_TRUE = ("1", "true", "on", "yes")


def interpreting() -> bool:
    """Whether ``@triton.jit`` makes interpreted functions in this process (TRITON_INTERPRET)."""
    return os.environ.get("TRITON_INTERPRET", "0").strip().lower() in _TRUE


def torch_device(device: str) -> Any:
    """The tensors' device; the CPU only under the interpreter (which runs on host tensors)."""
    import torch
    if device == "cuda":
        return torch.device("cuda", 0)
    if not interpreting():
        raise RuntimeError("Triton runs kernels on the CPU only in its interpreter: set TRITON_INTERPRET=1")
    return torch.device("cpu")


def put(array: Any, precision: str | np.dtype, device: str) -> Any:
    """Upload a copy of a host array (a scalar becomes shape (1,)) with an explicit dtype."""
    import torch
    host = np.array(np.atleast_1d(np.asarray(array)), dtype=np.dtype(precision), order="C", copy=True)
    return torch.from_numpy(host).to(torch_device(device))


def empty(shape: tuple[int, ...], precision: str | np.dtype, device: str) -> Any:
    import torch
    dtype = getattr(torch, np.dtype(precision).name)            # float32, float64, uint8
    return torch.empty(shape, dtype=dtype, device=torch_device(device))


def download(t: Any) -> np.ndarray:
    return t.detach().cpu().numpy().copy()


def launch_options() -> dict[str, Any]:
    """Compile options every launch passes: FMA contraction on, and libdevice without
    flush-to-zero (CUDA C's default; Triton's own is FTZ). An option this Triton does not know is
    left out (a launch with an unknown keyword raises); ``info()`` records what was passed."""
    opts = {"enable_fp_fusion": FP_FUSION, "enable_reflect_ftz": False}
    if interpreting():                 # the interpreter drops launch options
        return opts
    from triton.backends.nvidia.compiler import CUDAOptions
    return {k: v for k, v in opts.items() if k in CUDAOptions.__dataclass_fields__}


def kernel_info(**facts: Any) -> dict[str, Any]:
    return {"kernel": "triton.jit", "interpreter": interpreting(), "launch_options": launch_options(),
            **facts}


def tuned(kernel: Any) -> dict[str, Any]:
    """What ``triton.autotune`` chose (after the first call), for ``info()``."""
    cfg = getattr(kernel, "best_config", None)
    if cfg is None:
        return {}
    return {"autotuned": {**cfg.kwargs, "num_warps": cfg.num_warps}}


class TritonBackend(TorchCuda):
    name = "triton"
    package = "triton"
    gradient_method = "adjoint"          # hand-written discrete adjoint (as CuPy, Numba): no autodiff
    display_order, color = 7, "C8"
    related_packages = ("torch",)

    def cache_environment(self, cache_dir: Path) -> dict[str, str]:
        # Triton's kernel cache (its cubins; autotuning results are not cached on disk by default)
        return {"TRITON_CACHE_DIR": str(cache_dir / "triton"),
                "CUDA_CACHE_PATH": str(cache_dir / "cuda-driver-jit")}

    def available(self) -> dict[str, str | None]:
        reason = not_installed("triton", self.package, extra="triton") or \
            not_installed("torch", "torch", extra="triton")
        if reason:
            return {"cpu": CPU_REASON, "cuda": reason}
        return {"cpu": CPU_REASON, "cuda": INTERPRETER_REASON if interpreting() else self._cuda_reason()}

    @staticmethod
    def _cuda_reason() -> str | None:
        import torch
        if torch.cuda.is_available():
            return None
        if torch.version.cuda is None:
            return cuda_build_hint(f"this PyTorch build has no CUDA support (torch {torch.__version__}), "
                                   "and Triton takes its tensors from PyTorch")
        return cuda_build_hint(f"no CUDA device visible to PyTorch (torch {torch.__version__})")

    def versions(self) -> dict[str, str]:
        out = {}
        for dist in ("triton", "torch"):
            try:
                out[dist] = importlib.metadata.version(dist)
            except importlib.metadata.PackageNotFoundError:
                pass
        try:
            import torch
            out["torch_cuda"] = str(torch.version.cuda)
        except Exception:
            pass
        return out

    def setup(self, device: str, precision: str, variant: str) -> None:
        if variant != DEFAULT_VARIANT:
            raise ValueError(f"Triton has no variant {variant!r}")
        if device == "cuda":
            import torch
            torch.cuda.set_device(torch_device(device))


BACKEND = TritonBackend()
