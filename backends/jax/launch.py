"""Trivial launch in JAX: one jitted x + 1 over n (default 1) elements, output donated back."""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, jax_device, put
from ..base import ScenarioKernel


def _plus_one(x, out):
    del out  # donated: its buffer receives the result
    return x + 1


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        import jax.numpy as jnp
        dev = jax_device(device)
        self.x = put(inputs["x"], precision, dev)
        self.out = jnp.empty_like(self.x, device=dev)
        self.program = Program(_plus_one, donate=(1,))

    def run(self) -> Any:
        self.out = self.program(self.x, self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": np.asarray(self.out)}

    def info(self) -> dict[str, Any]:
        return self.program.info()
