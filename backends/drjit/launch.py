"""Trivial launch in Dr.Jit: ``x + 1`` over n (default 1) elements, evaluated (one kernel)."""
from __future__ import annotations

from typing import Any

import numpy as np

from . import download, real_type, upload
from ..base import ScenarioKernel


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.dtype, self.n = np.dtype(precision), params.n
        self.x = upload(inputs["x"], real_type(device, precision))
        self.out: Any = None

    def run(self) -> Any:
        import drjit as dr
        self.out = self.x + 1.0
        dr.eval(self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out, self.dtype, (self.n,))}
