"""SAXPY in Dr.Jit: one array expression ``a * x + y``, evaluated as one fused kernel per call.

``a`` is an opaque one-element array (a run-time value, not a literal in the kernel). Dr.Jit
emits a multiply and an add (no ``contract`` flag on the LLVM side, so no FMA there); each call
traces the expression again, hits the kernel cache and writes a fresh output from Dr.Jit's
caching allocator (a freed buffer of the same size is reused, so a steady call allocates no new
device memory).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import download, fast_math, real_type, scalar, upload
from ..base import ScenarioKernel
from scenarios.saxpy import SaxpyParams
from ..base import Device
from scenarios.base import Precision


class Kernel(ScenarioKernel):
    def __init__(self, params: SaxpyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        cls = real_type(device, precision)
        self.dtype, self.n = np.dtype(precision), params.n
        self.a = scalar(inputs["a"], cls)
        self.x, self.y = upload(inputs["x"], cls), upload(inputs["y"], cls)
        self.out: Any = None

    def run(self) -> Any:
        import drjit as dr
        self.out = self.a * self.x + self.y
        dr.eval(self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out, self.dtype, (self.n,))}

    def info(self) -> dict[str, Any]:
        return {"kernel": "dr.eval(a * x + y)", **fast_math()}
