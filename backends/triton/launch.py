"""Trivial launch in Triton: ``out = x + 1`` over n (default 1) elements, one plain launch.

What one Triton kernel call costs: ``kernel[grid](...)``, the launcher's argument handling and
specialisation lookup plus the launch (the graph regime shows the launch alone). No autotuner
in front of it (its per-call key lookup would be extra, and there is nothing to tune at n = 1):
one fixed block of LAUNCH_BLOCK elements with 4 warps.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import triton
import triton.language as tl

from . import download, empty, kernel_info, launch_options, put
from ..base import ScenarioKernel
from scenarios.launch import LaunchParams
from ..base import Device
from scenarios.base import Precision

LAUNCH_BLOCK, LAUNCH_WARPS = 1024, 4


@triton.jit
def plus_one_kernel(x_ptr, out_ptr, n, BLOCK_SIZE: tl.constexpr):
    offs = tl.program_id(0) * BLOCK_SIZE + tl.arange(0, BLOCK_SIZE)      # n <= 2^20
    mask = offs < n
    tl.store(out_ptr + offs, tl.load(x_ptr + offs, mask=mask) + 1.0, mask=mask)


class Kernel(ScenarioKernel):
    def __init__(self, params: LaunchParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.x = put(inputs["x"], precision, device)
        self.out = empty((params.n,), precision, device)
        self.n = params.n
        self.grid = (triton.cdiv(params.n, LAUNCH_BLOCK),)
        self.opts = {**launch_options(), "num_warps": LAUNCH_WARPS}

    def run(self) -> Any:
        plus_one_kernel[self.grid](self.x, self.out, self.n, BLOCK_SIZE=LAUNCH_BLOCK, **self.opts)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(block_size=LAUNCH_BLOCK, num_warps=LAUNCH_WARPS, grid=list(self.grid))
