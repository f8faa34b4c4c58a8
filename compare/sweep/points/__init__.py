"""What each scenario contributes to the measurement sweeps (docs/measurement.md).

A scenario holds physics; what is swept, how the sweep pages speak of it and what its converged
error is are the sweeps' business, so they live here: one module of this package per scenario,
named after it, whose ``SWEEPS`` is that scenario's ``Sweeps``. A scenario without a module takes
part in no sweep. The suite finds rows by role and tags, never by scenario name, and the only
place a scenario's name appears is its module's file name.
"""
from __future__ import annotations

import importlib
import pkgutil
from typing import Any, ClassVar

import numpy as np

import scenarios
from compare.sweep.converged import dt_reference
from scenarios.base import Precision

CHECK_SAMPLE = 1 << 16     # items checked against the oracle in large per-item sweep cells

Point = dict[str, Any]


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
        """The points of sweep ``kind`` ('bandwidth', 'error', 'scaling', 'horizon') on ``device``.

        Each point: {'params': {...}, 'knob': {'name', 'value'}} (knob optional), plus optional
        cell-spec options ('check_sample', 'save_outputs') and 'reference' (what
        ``converged_error`` compares against, e.g. the dt of a converged rollout: a property of
        the sweep, not of the cell, so it is handed back to ``converged_error``, never stored
        in the cell's identity)."""
        return []

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """Error of an error-sweep cell against a converged float64 reference of the same quantity:
        {'error': ..., 'metric': ..., 'reference': {...}, ...}, or None when it cannot be measured
        (e.g. the outputs were not kept). ``params``: the cell's parameters; ``record``: its
        record; ``cache``: a dict the suite keeps for a whole run, for memoising references;
        ``reference``: the point's 'reference' (None: the scenario's default)."""
        return None

    def against_dt_reference(self, params: dict[str, Any], outputs: dict[str, np.ndarray],
                             cache: dict[Any, Any], reference: dict[str, Any] | None, default_dt: float,
                             converge: Any, error: Any, t: float, names: tuple[str, ...]) -> dict[str, Any]:
        """The error of ``outputs[names]`` at simulated time ``t`` against a float64 rollout at
        the point's reference dt (``default_dt`` without one): ``converge`` computes a reference,
        ``error(*outputs, *reference)`` compares (compare/sweep/converged.py)."""
        ref, info = dt_reference(cache, scenarios.get(self.scenario), params, reference, default_dt, converge,
                                 lambda a, b: error(*a, *b)["error"], t)
        return {**error(*(outputs[k] for k in names), *ref), "metric": self.error_metric, "reference": info}

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
