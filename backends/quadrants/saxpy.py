"""SAXPY in Quadrants: one parallel-for iteration per element.

The Taichi port's kernel with ``ti`` renamed ``qd``; nothing else differs. Storage: fields, as
there (measured on Taichi 1.7, 2-core CPU: fields beat ndarrays by 10-30 % at n = 1e5..1e6, no
per-launch argument marshalling, the extent visible to the compiler; bit-identical results).
"""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import numpy as np
import quadrants as qd

from . import config_info
from ..base import ScenarioKernel


@qd.kernel
def _saxpy(a: float, x: qd.template(), y: qd.template(), out: qd.template()):
    # Fields are template arguments: one compilation per Kernel instance, none per run().
    for i in out:
        out[i] = a * x[i] + y[i]


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.a = float(inputs["a"])   # already rounded; becomes the kernel's default_fp argument
        self.x, self.y, self.out = (qd.field(float, shape=params.n) for _ in range(3))
        self.x.from_numpy(inputs["x"])
        self.y.from_numpy(inputs["y"])

    def run(self) -> None:
        _saxpy(self.a, self.x, self.y, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.to_numpy()}

    def info(self) -> dict[str, Any]:
        return {"storage": "field", **config_info()}
