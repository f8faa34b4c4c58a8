"""A CUDA cell's own launch floor: the record's ``cell_floor`` part (``compare.running.cell_floor`` probes it).

The run's yardstick (``Hardware``, the record's ``hardware``) is taken once, at the start of a run;
the launch floor moves within a sitting, so a cell timed minutes later is divided by a floor of
another moment (docs/results/h100/evidence/units). ``cell_floor`` is the same empty kernel probed
in the cell's own worker: ``before`` its framework's set-up (seconds before the timed window) and
``after`` its timed regimes (inside the window). A part of its own module, beside
``compare.results.record_parts`` (which is at its size limit); ``compare.results.record`` registers it.
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar, Mapping

from compare.results.record_parts import Part


@dataclasses.dataclass(frozen=True, eq=False)
class FloorProbe(Part):
    """One probe: the empty kernel's launch + synchronise (median, IQR) and pipelined launch, per
    launch, the samples behind them, what the probe cost and the context it launched on."""
    latency_s: float | None = None
    latency_iqr_s: float | None = None
    pipelined_s: float | None = None
    launches: int | None = None          # latency samples
    k: int | None = None                 # launches per pipelined batch
    batches: int | None = None           # pipelined batches (the median leaves the first out)
    spent_s: float | None = None         # the whole probe: driver, context and module included
    context: str | None = None           # the CUDA context it launched on, in words
    error: str | None = None             # why it has no figures (a probe never fails the cell)

    @property
    def figures(self) -> bool:
        """Whether the probe measured both floors (a failed or cut probe may have neither)."""
        return all(isinstance(v, (int, float)) and v > 0 for v in (self.latency_s, self.pipelined_s))


@dataclasses.dataclass(frozen=True, eq=False)
class CellFloor(Part):
    """The record's ``cell_floor``: the probe before the framework's set-up, the one after the
    timed regimes, and how they were taken."""
    before: FloorProbe | None = None
    after: FloorProbe | None = None
    how: str | None = None
    NESTED: ClassVar[Mapping[str, type[Part]]] = {"before": FloorProbe, "after": FloorProbe}


__all__ = ["CellFloor", "FloorProbe"]
