"""SAXPY in PyTorch: out = a*x + y as a multiply into the preallocated output, then an in-place add.

Eager: two elementwise kernels (torch.mul(..., out=), add_). Not ``torch.add(y, x, alpha=a)``:
ATen's CPU kernel evaluates y + alpha*x with a fused multiply-add, a different rounding from the
scenario's a*x + y. "compile": one fused kernel written straight into ``out``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel


def _saxpy(a, x, y, out):
    out.copy_(a * x + y)


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        check_variant(variant)
        self.variant = variant
        self.a, self.x, self.y = (put(inputs[k], precision, device) for k in ("a", "x", "y"))
        self.out = empty((params.n,), precision, device)
        self.fn = compiled(_saxpy) if variant == "compile" else None

    def run(self) -> Any:
        import torch
        with torch.inference_mode():
            if self.fn is not None:
                self.fn(self.a, self.x, self.y, self.out)
            else:
                torch.mul(self.x, self.a, out=self.out).add_(self.y)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant)
