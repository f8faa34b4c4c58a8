"""Kernel caches shared along a family of cells, one process each (a sweep's points).

A family is the cells of one backend, scenario, variant, device and precision: a sweep's points
of one curve, which differ in a parameter (size, step count, time step) and run the same kernels.
Where the suite says no page reads such a cell's first call (``Suite.shares_caches``), the
family's cells share one directory (``Cell.cache_dir``): the first to run starts from it empty
and fills it (its record's ``time.cache`` says cold), each later one starts from what the earlier
ones left (``kept:``), as a cell's repeat processes do (``driver.cold_once``). Only its first call
moves: the steady state runs the same kernels, whichever process compiled them. The engine runs
no two cells of one directory at the same time (``engine.cell_lane``), so each later cell finds
it complete. Why: a sweep's first calls are compiles that no page reads, and some last minutes
(docs/measurement.md, *Caches*).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

from compare.spec import IDENTITY, Cell


def family(cell: Cell) -> tuple[str, ...]:
    """The cells that run the same kernels: the identity but the parameters."""
    return tuple(str(getattr(cell, f)) for f in IDENTITY)


def share(cells: list[Cell], where: Path, shares: Callable[[Cell], bool]) -> list[Cell]:
    """``cells`` with one cache directory under ``where`` per family of two or more cells that
    ``shares`` admits; a warm cell, or one with its own directory already, as planned."""
    def admitted(c: Cell) -> bool:
        return c.cache == "cold" and not c.cache_dir and shares(c)
    count: dict[tuple[str, ...], int] = {}
    for c in cells:
        if admitted(c):
            count[family(c)] = count.get(family(c), 0) + 1
    names = {f: where / f"family-{n}" for n, f in enumerate(f for f, k in count.items() if k > 1)}
    return [dataclasses.replace(c, cache_dir=str(names[family(c)])) if admitted(c) and family(c) in names else c
            for c in cells]


__all__ = ["family", "share"]
