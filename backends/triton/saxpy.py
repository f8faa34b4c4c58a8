"""SAXPY in Triton, ``out = a * x + y``: the vector-add tutorial's kernel, block size autotuned.

One program per block of BLOCK_SIZE elements, masked loads and stores for the tail; Triton
vectorises the accesses itself (16-byte loads and stores where it can prove alignment: it
specialises on pointers and on n divisible by 16). ``a * x + y`` contracts to one FMA
(``enable_fp_fusion=True``), as in Warp, Numba and CuPy. ``a`` is loaded from a one-element
tensor of the cell's dtype (a Python float argument would be fp32).

Block size and warps: ``triton.autotune`` over CONFIGS, keyed on n (and the dtypes), so the first
call of a cell compiles and times every config (that is in its first-call time) and later calls
launch the fastest through the autotuner; ``info()`` reports the choice. Its benchmark allocates
Triton's L2-flush buffer (256 MB) through PyTorch, so the cell's device-memory peak includes it.
The element offsets are int64, so n up to 2^31-1 cannot overflow. Under the interpreter the first
config runs (autotuning would time NumPy).
copy.py reuses ``Kernel`` (and with it ``elementwise``) with its own kernel.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np
import triton
import triton.language as tl

from . import download, empty, interpreting, kernel_info, launch_options, put, tuned
from ..base import ScenarioKernel
from scenarios.saxpy import SaxpyParams
from ..base import Device
from scenarios.base import Precision

# (BLOCK_SIZE, num_warps): 4 to 16 elements a thread, the range Triton's own pointwise heuristics use
CONFIGS = ((1024, 4), (2048, 4), (2048, 8), (4096, 8))


@triton.jit
def saxpy_kernel(a_ptr, x_ptr, y_ptr, out_ptr, n, BLOCK_SIZE: tl.constexpr):
    offs = tl.program_id(0).to(tl.int64) * BLOCK_SIZE + tl.arange(0, BLOCK_SIZE)
    mask = offs < n
    a = tl.load(a_ptr)
    x = tl.load(x_ptr + offs, mask=mask)
    y = tl.load(y_ptr + offs, mask=mask)
    tl.store(out_ptr + offs, a * x + y, mask=mask)


@functools.cache
def autotuned(kernel: Any) -> Any:
    """``kernel`` under ``triton.autotune`` over CONFIGS keyed on n; the plain kernel with the
    first config's block size when interpreted."""
    if interpreting():
        return kernel
    return triton.autotune(configs=[triton.Config({"BLOCK_SIZE": b}, num_warps=w) for b, w in CONFIGS],
                           key=["n"])(kernel)


def elementwise(kernel: Any, n: int, *args: Any) -> tuple[Any, Any]:
    """(launch, tuned kernel) for a 1-D elementwise kernel over n elements taking ``*args``."""
    fn = autotuned(kernel)
    opts = launch_options()
    if interpreting():
        block = CONFIGS[0][0]
        blocks = (triton.cdiv(n, block),)
        return (lambda: fn[blocks](*args, n, BLOCK_SIZE=block)), fn

    def grid(meta: dict) -> tuple[int]:
        return (triton.cdiv(n, meta["BLOCK_SIZE"]),)
    return (lambda: fn[grid](*args, n, **opts)), fn


class Kernel(ScenarioKernel):
    """``kernel`` over the inputs named in ``operands``, then a preallocated out, launched through
    ``elementwise`` (copy.py reuses it with its own)."""
    kernel, operands = saxpy_kernel, ("a", "x", "y")

    def __init__(self, params: SaxpyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.args = [put(inputs[k], precision, device) for k in self.operands]
        self.out = empty((params.n,), precision, device)
        self.launch, self.fn = elementwise(self.kernel, params.n, *self.args, self.out)

    def run(self) -> Any:
        self.launch()
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(configs=[list(c) for c in CONFIGS], **tuned(self.fn))
