"""Trivial launch in Quadrants: a parallel-for over n (default 1) elements, out[i] = x[i] + 1.

The Taichi port's kernel with ``ti`` renamed ``qd``."""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import numpy as np
import quadrants as qd

from . import config_info
from ..base import ScenarioKernel


@qd.kernel
def _plus_one(x: qd.template(), out: qd.template()):
    for i in out:
        out[i] = x[i] + 1.0


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.x, self.out = (qd.field(float, shape=params.n) for _ in range(2))
        self.x.from_numpy(inputs["x"])

    def run(self) -> None:
        _plus_one(self.x, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.to_numpy()}

    def info(self) -> dict[str, Any]:
        return {"storage": "field", **config_info()}
