"""Device copy in JAX: one jitted jnp.copy written into the previous call's (donated) output.

XLA emits the copy itself (a copy thunk or loop): the input is not donated, so the output can
never alias it, and ``info`` checks that the output buffer is not the input's.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, jax_device, put
from ..base import ScenarioKernel
from scenarios.copy import CopyParams
from ..base import Device
from scenarios.base import Precision


def _copy(x, out):
    import jax.numpy as jnp
    del out  # donated: its buffer receives the copy
    return jnp.copy(x)


class Kernel(ScenarioKernel):
    """One jitted program from x into the donated out (launch.py reuses it with its own)."""
    body = staticmethod(_copy)

    def __init__(self, params: CopyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import jax.numpy as jnp
        dev = jax_device(device)
        self.x = put(inputs["x"], precision, dev)
        self.out = jnp.empty_like(self.x, device=dev)
        self.program = Program(self.body, donate=(1,))

    def run(self) -> Any:
        self.out = self.program(self.x, self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": np.asarray(self.out)}

    def info(self) -> dict[str, Any]:
        distinct = self.out.unsafe_buffer_pointer() != self.x.unsafe_buffer_pointer()
        return {**self.program.info(), "copy": "jnp.copy", "distinct_output_buffer": distinct}
