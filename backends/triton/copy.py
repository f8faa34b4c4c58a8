"""Device copy in Triton: an elementwise kernel ``out = x`` with SAXPY's autotuned block sizes.

A kernel rather than ``Tensor.copy_`` (a cudaMemcpy) so the copy is the same kind of code as the
scenarios' kernels: the bandwidth a bandwidth-bound Triton kernel reaches (saxpy.py's launch,
configurations and int64 offsets).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import triton
import triton.language as tl

from . import download, empty, kernel_info, put, tuned
from ..base import ScenarioKernel
from .saxpy import CONFIGS, elementwise


@triton.jit
def copy_kernel(x_ptr, out_ptr, n, BLOCK_SIZE: tl.constexpr):
    offs = tl.program_id(0).to(tl.int64) * BLOCK_SIZE + tl.arange(0, BLOCK_SIZE)
    mask = offs < n
    tl.store(out_ptr + offs, tl.load(x_ptr + offs, mask=mask), mask=mask)


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.x = put(inputs["x"], precision, device)
        self.out = empty((params.n,), precision, device)
        self.launch, self.fn = elementwise(copy_kernel, params.n, self.x, self.out)

    def run(self) -> Any:
        self.launch()
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(copy="kernel out[i] = x[i]", configs=[list(c) for c in CONFIGS], **tuned(self.fn))
