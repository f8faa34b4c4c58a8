"""Trivial launch in Dr.Jit: ``x + 1`` over n (default 1) elements, evaluated (one kernel).

The copy's ``Kernel`` (copy.py: the same upload, per-call evaluation and download) with this
expression.
"""
from __future__ import annotations

from typing import Any

from .copy import Kernel as CopyKernel


class Kernel(CopyKernel):
    def expression(self, dr: Any) -> Any:
        return self.x + 1.0

    def info(self) -> dict[str, Any]:
        return {}
