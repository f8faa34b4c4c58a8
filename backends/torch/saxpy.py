"""SAXPY in PyTorch: out = a*x + y written into the preallocated output.

Eager on CUDA: one kernel, ``torch.add(y, x, alpha=a, out=out)``, which nvcc contracts to one
FMA per element, as Warp, Numba and CuPy do on CUDA. Two kernels (a multiply into ``out``, then
an in-place add) read and write ``out`` twice: 5 array passes instead of 3, which held eager
PyTorch far below the same-run memcpy on CUDA (docs/measurement.md). Eager on the CPU: those two kernels, because ATen's CPU
kernel evaluates y + alpha*x with a fused multiply-add, a different rounding from the scenario's
a*x + y that the other CPU ports compute. "compile": one fused kernel written straight into ``out``; "compile_graphs": that kernel
replayed as a CUDA graph.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel
from scenarios.saxpy import SaxpyParams
from ..base import Device
from scenarios.base import Precision


def _saxpy(a, x, y, out):
    out.copy_(a * x + y)


class Kernel(ScenarioKernel):
    def __init__(self, params: SaxpyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        check_variant(variant)
        self.variant = variant
        self.a, self.x, self.y = (put(inputs[k], precision, device) for k in ("a", "x", "y"))
        self.out = empty((params.n,), precision, device)
        self.fn = compiled(_saxpy, variant, static=(self.a, self.x, self.y, self.out))
        self.fused = device == "cuda"
        self.alpha = float(inputs["a"])   # already rounded to the precision: exact in either

    def run(self) -> Any:
        import torch
        if self.fn is not None:
            self.fn(self.a, self.x, self.y, self.out)
        elif self.fused:
            torch.add(self.y, self.x, alpha=self.alpha, out=self.out)
        else:
            torch.mul(self.x, self.a, out=self.out).add_(self.y)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant)
