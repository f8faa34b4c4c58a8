"""Device copy in Quadrants: a parallel-for, out[i] = x[i] (the bandwidth roofline).

The Taichi port's kernel with ``ti`` renamed ``qd``.

Fields, as in saxpy.py (no per-launch argument marshalling); a kernel rather than
``field.copy_from`` so the copy is the same kind of code as the scenarios' kernels.
"""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import numpy as np
import quadrants as qd

from . import config_info
from ..base import ScenarioKernel


@qd.kernel
def _copy(x: qd.template(), out: qd.template()):
    for i in out:
        out[i] = x[i]


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.x, self.out = (qd.field(float, shape=params.n) for _ in range(2))
        self.x.from_numpy(inputs["x"])

    def run(self) -> None:
        _copy(self.x, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.to_numpy()}

    def info(self) -> dict[str, Any]:
        return {"storage": "field", "copy": "kernel out[i] = x[i]", **config_info()}
