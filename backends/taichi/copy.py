"""Device copy in Taichi: a parallel-for, out[i] = x[i] (the bandwidth roofline).

Fields, as in saxpy.py (no per-launch argument marshalling); a kernel rather than
``field.copy_from`` so the copy is the same kind of code as the scenarios' kernels.

``build(ti)`` defines the kernel and ``Kernel`` for ``ti``, the ``taichi`` module here and the
``quadrants`` one in backends/quadrants/copy.py (Taichi's fork, the same API).
"""
# (no "from __future__ import annotations": Taichi reads kernel annotations as objects)

import functools
from types import ModuleType
from typing import Any

import numpy as np

from . import built_on_first_use, framework_config_info
from ..base import ScenarioKernel
from scenarios.copy import CopyParams
from ..base import Device
from scenarios.base import Precision


@functools.cache
def build(ti: ModuleType) -> tuple[Any, type[ScenarioKernel]]:
    """(the kernel, ``Kernel``) in ``ti``: ``taichi`` or ``quadrants``."""

    @ti.kernel
    def _copy(x: ti.template(), out: ti.template()):
        for i in out:
            out[i] = x[i]

    class Kernel(ScenarioKernel):
        def __init__(self, params: CopyParams, inputs: dict[str, np.ndarray], device: Device,
                     precision: Precision, variant: str) -> None:
            self.x, self.out = (ti.field(float, shape=params.n) for _ in range(2))
            self.x.from_numpy(inputs["x"])

        def run(self) -> None:
            _copy(self.x, self.out)

        def outputs(self) -> dict[str, np.ndarray]:
            return {"out": self.out.to_numpy()}

        def info(self) -> dict[str, Any]:
            return {"storage": "field", "copy": "kernel out[i] = x[i]",
                    **framework_config_info(ti.__name__)}

    return _copy, Kernel


# _copy, Kernel = build(taichi), on first use (see built_on_first_use)
__getattr__ = built_on_first_use(globals(), build, ("_copy", "Kernel"))
