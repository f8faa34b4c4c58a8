"""What each scenario contributes to the measurement sweeps (docs/measurement.md).

A scenario holds physics; what is swept, how the sweep pages speak of it and what its converged
error is are the sweeps' business, so they live here: one module of this package per scenario,
named after it, whose ``SWEEPS`` is that scenario's ``Sweeps``. A scenario without a module takes
part in no sweep. The suite finds rows by role and tags, never by scenario name, and the only
place a scenario's name appears is its module's file name.
"""
from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from typing import Callable, ClassVar, Mapping

import numpy as np

import scenarios
from compare.results.record import Record
from compare.sweep.converged import Cache, Converged, Param, Reference, Solution, dt_reference
from scenarios.base import Precision, Scenario

CHECK_SAMPLE = 1 << 16     # items checked against the oracle in large per-item sweep cells
Outputs = dict[str, np.ndarray]       # a cell's output arrays, by name (the worker hands them back)


@dataclasses.dataclass(frozen=True)
class Knob:
    """What a sweep point varies, as the page names it: the parameter and its value (None where
    the cell itself says it: the precision, the variant)."""
    name: str
    value: Param | None = None

    def to_json(self) -> dict[str, Param | None]:
        """The cell's ``tags.knob`` (stored with the record; the page reads it back)."""
        return {"name": self.name, "value": self.value}


@dataclasses.dataclass(frozen=True)
class Point:
    """One point of a sweep: the scenario parameters it sets (the rest are the scenario's
    defaults; the suite resolves them), the knob it varies (None: nothing to show), its
    converged-error reference (None: the scenario's default), and what it sets in its cell's spec
    (``compare.spec.Cell``; the defaults are the spec's)."""
    params: Mapping[str, Param]
    knob: Knob | None = None
    reference: Reference | None = None
    check_sample: int = 0          # check a sample of this many items (large per-item cells)
    save_outputs: bool = True      # False: the outputs are not handed back (large cells)


class Sweeps:
    """A scenario's part in the sweeps. Default: none.

    ``measures``: the generic role the bandwidth sweep and its page find rows by: 'launch'
    (trivial-launch overhead yardstick), 'copy' (bandwidth roofline yardstick), 'bandwidth' (the
    size sweep). ``error_metric``: what ``converged_error`` measures, in words. ``labels``: the
    words the sweep page and plots use for this scenario, all optional: 'name' (display name;
    default the scenario name), 'bytes' (how the bytes per call are counted), 'error_axis'
    (time-against-error y label; '{floor}' is replaced by the value an exact 0 is drawn at), for
    the scaling sweep 'items' (what the swept size counts), 'per_run' (the parameter counted per
    run, e.g. steps), 'item_rate' (the work item), 'rate_work' (the ``work()`` key the rate
    counts), and for the horizon sweep 'horizon_items' and 'horizon_memory'
    (compare/sweep/horizon.py)."""
    scenario: str = ""                     # the scenario's name: its module's, set by the registry
    measures: ClassVar[str | None] = None
    error_metric: ClassVar[str] = ""
    labels: ClassVar[dict[str, str]] = {}
    # ``compare publish``'s kernel-dominated sizes: log2 n per device (and for --quick), the
    # variants worth timing there, and whether the oracle checks a sample (per-item scenarios)
    large: ClassVar[dict[str, tuple[int, ...]]] = {}
    large_quick: ClassVar[tuple[int, ...]] = ()
    large_variants: ClassVar[tuple[str, ...]] = ("default",)
    large_sampled: ClassVar[bool] = False

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        """The points of sweep ``kind`` ('bandwidth', 'error', 'scaling', 'horizon') on ``device``
        (``quick``: the few, small points of --quick)."""
        return []

    def converged_error(self, params: Mapping[str, Param], outputs: Outputs | None, record: Record,
                        cache: Cache, reference: Reference | None = None) -> Converged | None:
        """Error of an error-sweep cell against a converged float64 reference of the same
        quantity, or None when it cannot be measured (e.g. the outputs were not kept).
        ``params``: the cell's parameters; ``record``: its record; ``cache``: kept by the suite
        for a whole run, for memoising references; ``reference``: the point's (None: the
        scenario's default)."""
        return None

    def against_dt_reference(self, params: Mapping[str, Param], outputs: Outputs, cache: Cache,
                             reference: Reference | None, default_dt: float,
                             converge: Callable[[Scenario, Mapping[str, Param], float, int], Solution],
                             error: Callable[..., dict[str, float]], t: float,
                             names: tuple[str, ...]) -> Converged:
        """The error of ``outputs[names]`` at simulated time ``t`` against a float64 rollout at
        the point's reference dt (``default_dt`` without one): ``converge`` computes a reference,
        ``error(*outputs, *reference)`` compares (compare/sweep/converged.py)."""
        ref, info = dt_reference(cache, scenarios.get(self.scenario), params, reference, default_dt, converge,
                                 lambda a, b: error(*a, *b)["error"], t)
        return Converged.measured(error(*(outputs[k] for k in names), *ref), self.error_metric, info)

    def state_bytes_per_step(self, precision: Precision) -> float | None:
        """Bytes of state one item carries per step: the least a tape storing every step keeps
        (the horizon sweep draws it beside each framework's measured memory). Default: none."""
        return None


def _registry() -> dict[str, Sweeps]:
    """Each scenario's ``Sweeps``, from the module named after it, in the scenarios' order."""
    found = {m.name for m in pkgutil.iter_modules(__path__)}
    reg: dict[str, Sweeps] = {}
    for name in scenarios.SCENARIOS:
        if name in found:
            reg[name] = importlib.import_module(f"{__name__}.{name}").SWEEPS
            reg[name].scenario = name
    return reg


SWEEPS: dict[str, Sweeps] = _registry()
NONE = Sweeps()


def sweeps(scenario: str) -> Sweeps:
    """``scenario``'s part in the sweeps (none for a scenario without a module)."""
    return SWEEPS.get(scenario, NONE)
