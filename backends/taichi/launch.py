"""Trivial launch in Taichi: a parallel-for over n (default 1) elements, out[i] = x[i] + 1.

The copy's ``Kernel`` (copy.py: the same fields, upload and download) with this kernel instead.
``build(ti)`` defines both for ``ti``, the ``taichi`` module here and the ``quadrants`` one in
backends/quadrants/launch.py (Taichi's fork, the same API).
"""
# (no "from __future__ import annotations": Taichi reads kernel annotations as objects)

import functools
from types import ModuleType
from typing import Any

from . import built_on_first_use, copy, framework_config_info
from ..base import ScenarioKernel


@functools.cache
def build(ti: ModuleType) -> tuple[Any, type[ScenarioKernel]]:
    """(the kernel, ``Kernel``) in ``ti``: ``taichi`` or ``quadrants``."""

    @ti.kernel
    def _plus_one(x: ti.template(), out: ti.template()):
        for i in out:
            out[i] = x[i] + 1.0

    class Kernel(copy.build(ti)[1]):
        def run(self) -> None:
            _plus_one(self.x, self.out)

        def info(self) -> dict[str, Any]:
            return {"storage": "field", **framework_config_info(ti.__name__)}

    return _plus_one, Kernel


# _plus_one, Kernel = build(taichi), on first use (see built_on_first_use)
__getattr__ = built_on_first_use(globals(), build, ("_plus_one", "Kernel"))
