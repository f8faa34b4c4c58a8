"""Trivial launch in Warp: out[i] = x[i] + 1 over n (default 1) threads.

The copy's ``Kernel`` (copy.py: the same arrays, launcher and download) with this kernel.
"""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

import functools

import warp as wp

from .copy import Kernel as CopyKernel


@functools.cache
def _plus_one(scalar):
    @wp.kernel(module="unique")
    def plus_one(x: wp.array(dtype=scalar), out: wp.array(dtype=scalar)):
        i = wp.tid()
        out[i] = x[i] + scalar(1.0)
    return plus_one


class Kernel(CopyKernel):
    make = staticmethod(_plus_one)

    def info(self) -> dict:
        return {}
