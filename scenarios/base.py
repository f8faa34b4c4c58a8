"""What every scenario provides: parameters, inputs, a float64 oracle and a derived error check.

A scenario knows nothing about frameworks. A backend's kernel file receives the inputs this module
makes (already rounded to the cell's precision) and returns outputs named as in ``outputs``.
"""
from __future__ import annotations

import dataclasses
import typing
from typing import Any, ClassVar

import numpy as np

if typing.TYPE_CHECKING:
    from .numerics import Experiment

PRECISIONS: tuple[str, ...] = ("float32", "float64")

# Unit roundoff u = 2^-p (p = significand bits incl. the hidden one): |fl(x) - x| <= u |x|.
UNIT_ROUNDOFF: dict[str, float] = {"float32": 2.0**-24, "float64": 2.0**-53}


class ParamError(ValueError):
    """Bad scenario parameter; its message is one line naming the parameter and the allowed range."""


def dtype_of(precision: str) -> type[np.floating]:
    if precision not in PRECISIONS:
        raise ParamError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    return np.float32 if precision == "float32" else np.float64


def precision_of(array: np.ndarray) -> str:
    """The precision name of an input array (inputs arrive already rounded)."""
    return "float32" if np.asarray(array).dtype == np.float32 else "float64"


@dataclasses.dataclass
class Check:
    """One comparison of outputs against a reference.

    ``error`` and ``tolerance`` are in the scenario's own metric (documented where it is defined);
    ``ok`` is ``error <= tolerance`` for every checked quantity and every value finite.
    ``details`` holds the per-quantity figures (e.g. gradient error) that go into the records.
    """

    error: float
    tolerance: float
    ok: bool
    details: dict[str, Any] = dataclasses.field(default_factory=dict)


def require(cond: bool, message: str) -> None:
    if not cond:
        raise ParamError(message)


def _coerce(name: str, value: Any, typ: Any) -> Any:
    """Turn a CLI string (or a Python value) into the field's type, with a one-line error."""
    origin = typing.get_origin(typ)
    if origin is typing.Literal:
        choices = typing.get_args(typ)
        if value not in choices:
            raise ParamError(f"{name} must be one of {', '.join(map(str, choices))}, got {value!r}")
        return value
    try:
        if typ is bool:
            if isinstance(value, bool):
                return value
            low = str(value).lower()
            if low in ("1", "true", "yes", "on"):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError
        if typ is int:
            if isinstance(value, bool):
                raise ValueError
            if isinstance(value, str):
                f = float(value.replace("_", ""))
                if not f.is_integer():
                    raise ValueError
                return int(f)
            if isinstance(value, float) and not value.is_integer():
                raise ValueError
            return int(value)
        if typ is float:
            if isinstance(value, bool):
                raise ValueError
            return float(value)
        if typ is str:
            return str(value)
    except (TypeError, ValueError, OverflowError):
        pass
    kind = {int: "an integer", float: "a number", bool: "a boolean", str: "a string"}.get(typ, str(typ))
    raise ParamError(f"{name} must be {kind}, got {value!r}")


class Scenario:
    """Base class of the four scenarios. Subclasses set the class attributes and the methods."""

    name: ClassVar[str]
    title: ClassVar[str]
    Params: ClassVar[type]            # a dataclass with the seed's defaults; validate() checks ranges
    quick: ClassVar[dict[str, Any]] = {}   # overrides used by --quick (small sizes for CI)
    outputs: ClassVar[tuple[str, ...]]     # names of the arrays a backend returns
    has_gradient: ClassVar[bool] = False
    in_all: ClassVar[bool] = True          # False for measurement-only scenarios (launch, copy)
    # Measurement sweeps (compare/sweep, docs/measurement.md). ``measures``: the generic role the
    # sweep page finds rows by: 'launch' (trivial-launch overhead yardstick), 'copy' (bandwidth
    # roofline yardstick), 'bandwidth' (the size sweep). ``error_metric``: what ``converged_error``
    # measures, in words. ``sweep_labels``: the words the sweep page and plots use for this
    # scenario, all optional: 'name' (display name; default the scenario name), 'bytes' (how the
    # bytes per call are counted), 'error_axis' (time-against-error y label; '{floor}' is replaced
    # by the value an exact 0 is drawn at), and for the scaling sweep 'items' (what the swept size
    # counts), 'per_run' (the parameter counted per run, e.g. steps), 'item_rate' (the work item).
    measures: ClassVar[str | None] = None
    error_metric: ClassVar[str] = ""
    sweep_labels: ClassVar[dict[str, str]] = {}

    # ---- parameters -------------------------------------------------------------------------
    def params(self, overrides: dict[str, Any] | None = None, quick: bool = False):
        """Defaults, then quick overrides, then user overrides; coerced and validated."""
        fields = {f.name: f for f in dataclasses.fields(self.Params)}
        hints = typing.get_type_hints(self.Params)
        values: dict[str, Any] = {}
        merged = dict(self.quick) if quick else {}
        merged.update(overrides or {})
        for key, raw in merged.items():
            if key not in fields:
                raise ParamError(
                    f"unknown parameter {key!r} for scenario {self.name} "
                    f"(known: {', '.join(fields)})")
            values[key] = _coerce(key, raw, hints[key])
        p = self.Params(**values)
        p.validate()
        return p

    def describe_params(self) -> str:
        return ", ".join(f"{f.name}={f.default!r}" for f in dataclasses.fields(self.Params))

    def param_rules(self) -> list[tuple[str, Any, str]]:
        """(name, default, what a value must be) per parameter, for ``--help``. The rule is the
        validation's own words, found by offering values it refuses (no second copy to drift)."""
        hints = typing.get_type_hints(self.Params)
        out = []
        for f in dataclasses.fields(self.Params):
            kind = {int: "an integer", float: "a number", bool: "a boolean", str: "a string"}.get(hints[f.name], "")
            rule = f"must be {kind}" if kind else ""
            for probe in ("?", "1e300", "-1e300", "-1", "0", "nan", "inf"):
                try:
                    self.params({f.name: probe})
                except ParamError as exc:
                    msg = str(exc).split(", got")[0]
                    if msg.startswith(f"{f.name} must") and not msg.endswith(f"must be {kind}"):
                        rule = msg[len(f.name) + 1:]
                        break
            out.append((f.name, f.default, rule))
        return out

    # ---- data -------------------------------------------------------------------------------
    def inputs(self, params, precision: str) -> dict[str, np.ndarray]:
        """Deterministic inputs, already rounded to ``precision``."""
        raise NotImplementedError

    def oracle(self, params, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Float64 NumPy reference computed from the (rounded) inputs."""
        raise NotImplementedError

    def check(self, params, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray],
              reference: dict[str, np.ndarray], precision: str) -> Check:
        """Compare ``outputs`` with ``reference`` (the oracle) using the derived tolerance."""
        raise NotImplementedError

    def distance(self, params, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray],
                 other: dict[str, np.ndarray]) -> float:
        """The scenario's error metric between two backends' outputs (e.g. a port vs Warp)."""
        raise NotImplementedError

    def output_shapes(self, params) -> dict[str, tuple[int, ...] | None]:
        """The contract a kernel's ``outputs()`` must meet: exactly these names, each an array of
        this shape (None: any shape) with the cell's precision as dtype. The worker checks it and
        turns a violation into an ``error`` record naming it."""
        return {name: None for name in self.outputs}

    def footprint(self, params, precision: str, device: str = "cpu") -> float:
        """Bytes of host memory a cell's worker needs for its data at its peak (inputs, the
        framework's copies, outputs, oracle and check temporaries), beyond the interpreter and
        framework (compare.run_suite.WORKER_BASELINE_BYTES, per device). ``device``: where the
        framework's own working copies live (on a GPU they are not host memory). An upper bound: the run suite
        refuses sizes whose bound exceeds the available memory, and tests/test_reliability.py
        checks it against measured peaks."""
        return 0.0

    def output_bytes(self, params, precision: str) -> float:
        """Bytes of the outputs a cell hands back (``output_shapes`` at the cell's precision;
        an output of undeclared shape counts 0)."""
        item = np.dtype(dtype_of(precision)).itemsize
        return float(sum(int(np.prod(s)) * item for s in self.output_shapes(params).values() if s is not None))

    def input_bytes(self, params, precision: str) -> float:
        """Bytes of the inputs (what --save-arrays writes beside the outputs). Default: as many as
        the outputs (true of the per-item scenarios); a scenario with more overrides it."""
        return self.output_bytes(params, precision)

    def sample(self, params, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray], k: int
               ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], int, int, str] | None:
        """The part of a large cell the check looks at: (inputs, outputs, items checked, items in
        all, what an item is), or None to check everything. ``k``: the cell's ``check_sample``
        (0: the scenario's default). The oracle of the sampled inputs must be the sample of the
        oracle.

        Default, for per-item scenarios (saxpy, copy, launch, particles without trajectories):
        every input and output array is indexed by item along axis 0 (scalars pass through); k
        evenly spaced items, first and last included, when k is set and below ``params.n``.
        Anything else is checked in full."""
        n = getattr(params, "n", None)
        if not k or n is None or n <= k:
            return None
        arrays = list(inputs.values()) + list(outputs.values())
        if any(np.ndim(a) and np.shape(a)[0] != n for a in arrays):
            return None
        idx = np.unique(np.linspace(0, n - 1, k).round().astype(np.int64))
        pick = lambda d: {key: (np.asarray(a)[idx] if np.ndim(a) else a) for key, a in d.items()}  # noqa: E731
        return pick(inputs), pick(outputs), int(idx.size), n, ""

    def size_text(self, params) -> str:
        return ", ".join(f"{k}={getattr(params, k)}" for k in ("n", "width", "height", "steps")
                         if hasattr(params, k))

    def work(self, params, precision: str) -> dict[str, float]:
        """Useful work per run, for throughput figures and floors: {'bytes': the bytes a run must
        move to and from device memory, 'flops': the floating-point operations it must do,
        'items': ...}."""
        return {}

    def floor(self, params, precision: str, hardware: dict[str, Any]) -> dict[str, Any] | None:
        """The least time one run can take on this hardware (``compare.hardware``'s same-run
        yardstick): {'kind', 'seconds', 'derivation'}, or None where nothing is stated.

        Default: the larger of the bandwidth floor (``work()['bytes']`` at the measured copy
        bandwidth) and the FLOP floor (``work()['flops']`` at the vendor's stated peak rate for
        this precision). A scenario bound by something else (a serial chain, a launch) overrides.
        """
        w = self.work(params, precision)
        floors = []
        if w.get("bytes") and hardware.get("copy_bytes_per_s"):
            floors.append({"kind": "bandwidth", "seconds": w["bytes"] / hardware["copy_bytes_per_s"],
                           "derivation": f"{w['bytes']:.4g} bytes at the same-run copy bandwidth"})
        peak = (hardware.get("peak_flops") or {}).get(precision)
        if w.get("flops") and peak:
            floors.append({"kind": "flops", "seconds": w["flops"] / peak,
                           "derivation": f"{w['flops']:.4g} FLOP at the stated peak {peak / 1e12:.3g} TFLOP/s "
                                         f"({hardware['peak_flops'].get('source', '')})"})
        return max(floors, key=lambda f: f["seconds"]) if floors else None

    # ---- measurement sweeps ---------------------------------------------------------------
    def sweep_points(self, kind: str, device: str, quick: bool) -> list[dict[str, Any]]:
        """The points of measurement sweep ``kind`` ('bandwidth', 'error', 'scaling') on ``device``.

        Each point: {'params': {...}, 'knob': {'name', 'value'}} (knob optional), plus optional
        cell-spec options ('check_sample', 'save_outputs') and 'reference' (what
        ``converged_error`` compares against, e.g. the dt of a converged rollout: a property of
        the sweep, not of the cell, so it is handed back to ``converged_error``, never stored
        in the cell's identity). Default: the scenario takes part in no sweep of that kind."""
        return []

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """Error of an error-sweep cell against a converged float64 reference of the same quantity:
        {'error': ..., 'metric': ..., 'reference': {...}, ...}, or None when it cannot be measured
        (e.g. the outputs were not kept). ``params``: the cell's parameters; ``record``: its
        record; ``cache``: a dict the suite keeps for a whole run, for memoising references;
        ``reference``: the point's 'reference' from ``sweep_points`` (None: the scenario's
        default)."""
        return None

    def state_bytes_per_step(self, precision: str) -> float | None:
        """Bytes of state one item carries per step: the least a tape storing every step keeps
        (the horizon sweep draws it beside each framework's measured memory). Default: none."""
        return None

    # ---- report -----------------------------------------------------------------------------
    def figure(self, runs: list[tuple[dict[str, Any], dict[str, np.ndarray]]]) -> Any:
        """A matplotlib Figure of this scenario's results for the report, or None.

        ``runs``: (record, outputs) of every cell that kept its outputs, reference backend first.
        The scenario draws what its results mean (it owns the oracle), the driver only saves it."""
        return None

    # ---- stress suite (compare/stress, docs/stress.md) ---------------------------------------
    def ulp_cases(self, quick: bool) -> list[tuple[dict[str, Any], str, str]]:
        """Cases of the stress suite's float32 ulp-distribution experiment: (parameter overrides,
        output whose elements are measured in ulps, setting label). Default: none."""
        return []

    def stress_experiments(self) -> dict[str, "Experiment"]:
        """This scenario's own stress experiments by name (``scenarios.numerics.Experiment``), run
        through the context the suite hands them. Default: none."""
        return {}


SWEEP_CHECK_SAMPLE = 1 << 16     # items checked against the oracle in large per-item sweep cells
REF_FACTOR = 16                  # converged dt references: smallest swept dt / REF_FACTOR


def dt_reference(cache: dict[Any, Any], scenario: str, params: dict[str, Any],
                 reference: dict[str, Any] | None, default_dt: float, solve, distance,
                 simulated_time: float) -> tuple[Any, dict[str, Any]]:
    """A converged float64 reference over ``simulated_time`` at the sweep point's reference time
    step (``reference["dt"]``, else ``default_dt``) for ``params`` without their dt and steps,
    memoised in ``cache``, and what it is: ``solve(base_params, dt, steps)`` computes it; its
    ``self_difference`` is ``distance(coarse, reference)`` to the same at 2 dt (its own error
    scale, which must be far below the errors it measures)."""
    import json
    dt = (reference or {}).get("dt") or default_dt
    base = {k: v for k, v in params.items() if k not in ("dt", "steps")}
    key = (scenario, json.dumps(base, sort_keys=True), dt)
    if key not in cache:
        steps = round(simulated_time / dt)
        ref = solve(base, dt, steps)
        coarse = solve(base, 2 * dt, round(simulated_time / (2 * dt)))
        cache[key] = (ref, {"dt": dt, "steps": steps, "simulated_time_s": simulated_time,
                            "self_difference": distance(coarse, ref),
                            "note": "float64 NumPy rollout; self_difference: same metric "
                                    "against a reference at 2 dt (its own error scale)"})
    return cache[key]


def run_label(record: dict[str, Any]) -> str:
    v = record.get("variant", "default")
    return f"{record['backend']}/{record['device']}/{record['precision']}" + ("" if v == "default" else f"/{v}")


def pick_runs(runs: list[tuple[dict[str, Any], dict[str, np.ndarray]]], limit: int
              ) -> list[tuple[dict[str, Any], dict[str, np.ndarray]]]:
    """One float32 default-variant run per (backend, device) if there are any, else the first runs."""
    seen, out = set(), []
    for rec, o in runs:
        key = (rec["backend"], rec["device"])
        if rec["precision"] == "float32" and rec.get("variant", "default") == "default" and key not in seen:
            seen.add(key); out.append((rec, o))
    return (out or runs)[:limit]
