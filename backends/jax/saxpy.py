"""SAXPY in JAX: one jitted elementwise expression, writing into the previous call's output."""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, jax_device, put
from ..base import ScenarioKernel
from scenarios.saxpy import SaxpyParams
from ..base import Device
from scenarios.base import Precision


def _saxpy(a, x, y, out):
    del out  # donated: its buffer receives the result
    return a * x + y


class Kernel(ScenarioKernel):
    def __init__(self, params: SaxpyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import jax.numpy as jnp
        dev = jax_device(device)
        self.a, self.x, self.y = (put(inputs[k], precision, dev) for k in ("a", "x", "y"))
        self.out = jnp.empty_like(self.x, device=dev)
        self.program = Program(_saxpy, donate=(3,))

    def run(self) -> Any:
        self.out = self.program(self.a, self.x, self.y, self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": np.asarray(self.out)}

    def info(self) -> dict[str, Any]:
        return self.program.info()
