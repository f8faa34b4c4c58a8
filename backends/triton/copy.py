"""Device copy in Triton: an elementwise kernel ``out = x`` with SAXPY's autotuned block sizes.

A kernel rather than ``Tensor.copy_`` (a cudaMemcpy) so the copy is the same kind of code as the
scenarios' kernels: the bandwidth a bandwidth-bound Triton kernel reaches. SAXPY's ``Kernel``
(saxpy.py: the same launch, configurations and int64 offsets) with this kernel over x alone.
"""
from __future__ import annotations

from typing import Any

import triton
import triton.language as tl

from . import kernel_info, tuned
from .saxpy import CONFIGS, Kernel as SaxpyKernel


@triton.jit
def copy_kernel(x_ptr, out_ptr, n, BLOCK_SIZE: tl.constexpr):
    offs = tl.program_id(0).to(tl.int64) * BLOCK_SIZE + tl.arange(0, BLOCK_SIZE)
    mask = offs < n
    tl.store(out_ptr + offs, tl.load(x_ptr + offs, mask=mask), mask=mask)


class Kernel(SaxpyKernel):
    kernel, operands = copy_kernel, ("x",)

    def info(self) -> dict[str, Any]:
        return kernel_info(copy="kernel out[i] = x[i]", configs=[list(c) for c in CONFIGS], **tuned(self.fn))
