"""Trivial launch in CuPy: a ``cupy.ElementwiseKernel`` ``out = x + 1`` over n (default 1) elements.

What one CuPy kernel call costs: the ElementwiseKernel's per-call argument handling plus the
launch (the graph regime shows the launch alone).
"""
from __future__ import annotations

import functools
from typing import Any

from . import ctype, kernel_info
from .copy import Kernel as CopyKernel


@functools.cache
def elementwise(precision: str) -> Any:
    import cupy
    return cupy.ElementwiseKernel(f"{precision} x", f"{precision} out",
                                  f"out = x + ({ctype(precision)})1.0", name=f"plus_one_{precision}")


class Kernel(CopyKernel):
    """The copy's shape (x into a preallocated out) with out = x + 1."""
    make = staticmethod(elementwise)

    def info(self) -> dict[str, Any]:
        return kernel_info(kernel="cupy.ElementwiseKernel")
