"""Device copy in Dr.Jit: ``dr.opaque(x)``, a forced copy of an evaluated array.

Dr.Jit elides the copies one would write as kernels: ``dr.copy(x)``, ``Float(x)`` and a gather
at ``dr.arange`` indices all return x's own variable, with no launch. A forced copy of an
evaluated array is Dr.Jit's device memory copy (jit_var_mem_copy: an asynchronous memcpy on the
CUDA stream, or a memcpy task on the LLVM thread pool), into a fresh buffer; ``info`` checks that
the output is not the input's variable.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import download, real_type, upload
from ..base import ScenarioKernel
from scenarios.copy import CopyParams
from ..base import Device
from scenarios.base import Precision


class Kernel(ScenarioKernel):
    """One evaluated expression of x per call (launch.py reuses it with its own ``expression``)."""

    def __init__(self, params: CopyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.dtype, self.n = np.dtype(precision), params.n
        self.x = upload(inputs["x"], real_type(device, precision))
        self.out: Any = None

    def expression(self, dr: Any) -> Any:
        return dr.opaque(self.x)

    def run(self) -> Any:
        import drjit as dr
        self.out = self.expression(dr)
        dr.eval(self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out, self.dtype, (self.n,))}

    def info(self) -> dict[str, Any]:
        return {"copy": "dr.opaque(x): Dr.Jit's device memcpy",
                "distinct_output_buffer": self.out is not None and self.out.index != self.x.index}
