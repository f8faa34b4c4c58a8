"""What every scenario provides: parameters, inputs, a float64 oracle and a derived error check.

A scenario knows nothing about frameworks. A backend's kernel file receives the inputs this module
makes (already rounded to the cell's precision) and returns outputs named as in ``outputs``.

A scenario holds physics only, and knows nothing of the suites either: what they do with it is
found by scenario name beside them (sweep points in compare/sweep/points/<name>.py and
converged errors in compare/sweep/converged.py, stress experiments in compare/stress/<name>.py,
the report's picture in compare/render/figures/<name>.py). tests/test_layout.py checks that nothing here imports ``backends`` or
``compare``.
"""
from __future__ import annotations

import dataclasses
import enum
import functools
import typing
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np


class Precision(enum.StrEnum):
    """A cell's floating-point precision. A ``StrEnum``: it equals, prints and serialises as its
    name ("float32"), so records, keys and file names keep the same strings."""
    FLOAT32 = "float32"
    FLOAT64 = "float64"

    @property
    def scalar(self) -> type[np.floating]:
        """The NumPy scalar type (np.float32 or np.float64): inputs, outputs and checks."""
        return np.float32 if self is Precision.FLOAT32 else np.float64

    @property
    def itemsize(self) -> int:
        return np.dtype(self.scalar).itemsize


# the names, as plain strings (what a command line, a record and a message show)
PRECISIONS: tuple[str, ...] = tuple(p.value for p in Precision)

# Unit roundoff u = 2^-p (p = significand bits incl. the hidden one): |fl(x) - x| <= u |x|.
UNIT_ROUNDOFF: dict[Precision, float] = {Precision.FLOAT32: 2.0**-24, Precision.FLOAT64: 2.0**-53}


class ParamError(ValueError):
    """Bad scenario parameter; its message is one line naming the parameter and the allowed range."""


def as_precision(value: str) -> Precision:
    """``value`` as a Precision, or a one-line ParamError naming the allowed ones."""
    try:
        return Precision(value)
    except ValueError:
        raise ParamError(f"precision must be one of {', '.join(PRECISIONS)}, got {value!r}") from None


def dtype_of(value: str) -> type[np.floating]:
    """The NumPy scalar type of a precision (a Precision or its name)."""
    return as_precision(value).scalar


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


# ---- which items of a large cell the check looks at -------------------------------------------
SAMPLE_SEED = 0     # seeds the sample of a scenario without a ``seed`` parameter


def sample_seed(params: Any) -> int:
    """The sample's seed: the scenario's own ``seed`` where it has one, else SAMPLE_SEED, so
    the same cell always checks the same rows."""
    return int(getattr(params, "seed", SAMPLE_SEED))


def sample_rows(n: int, k: int, seed: int, extremes_from: typing.Iterable[np.ndarray] = ()) -> np.ndarray:
    """Sorted unique int64 rows of ``n`` for a sampled check: row 0, row n-1, the rows holding
    the minimum and the maximum of every column (along axis 0) of each array in
    ``extremes_from``, then rows drawn by default_rng(seed) without replacement from the rest
    until there are k in all (more only where those forced rows alone exceed k).

    Why not evenly spaced: a stride can line up with a port's own pattern (a block size, a
    wrap-around) and miss every row it gets wrong; a seeded draw cannot, and stays repeatable.
    The forced rows are where range and boundary errors show (first, last, extreme inputs)
    and where a broken row shows (extreme outputs: np.argmin/argmax return a NaN's row)."""
    forced = [0, n - 1]
    for a in extremes_from:
        a = np.asarray(a)
        if a.ndim and a.shape[0] == n and a.size:
            cols = a.reshape(n, -1)
            forced += np.argmin(cols, axis=0).tolist() + np.argmax(cols, axis=0).tolist()
    f = np.unique(np.asarray(forced, np.int64))
    free = n - f.size
    j = np.random.default_rng(seed).choice(free, max(0, min(k - f.size, free)), replace=False)
    # the j-th row not forced is j plus the forced rows at or before it (f - arange is sorted)
    j = j + np.searchsorted(f - np.arange(f.size), j, side="right")
    return np.union1d(f, j.astype(np.int64))


class Sample(typing.NamedTuple):
    """What a sampled check looks at (``Scenario.sample``): the sampled inputs and outputs, the
    items checked, the items in all, what an item is ('' where unnamed), the draw's seed and the
    rows (of ``sample_rows``) the check looks at."""

    inputs: dict[str, np.ndarray]
    outputs: dict[str, np.ndarray]
    checked: int
    total: int
    item: str
    seed: int
    rows: np.ndarray

    def text(self) -> str:
        """The record's ``error.checked_items``."""
        what = f" {self.item}" if self.item else ""
        return (f"{self.checked} of {self.total}{what} "
                f"(seeded random: row 0, last, extremes + random, seed {self.seed})")


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


@functools.cache
def _hints(params_type: type) -> dict[str, Any]:
    """A Params dataclass's resolved field types, once per class (every stored record's
    parameters pass ``Scenario.params`` when read)."""
    return typing.get_type_hints(params_type)


class Scenario:
    """Base class of the four scenarios. Subclasses set the class attributes and the methods."""

    name: ClassVar[str]
    title: ClassVar[str]
    Params: ClassVar[type]            # a dataclass with the seed's defaults; validate() checks ranges
    quick: ClassVar[dict[str, Any]] = {}   # overrides used by --quick (small sizes for CI)
    outputs: ClassVar[tuple[str, ...]]     # names of the arrays a backend returns
    has_gradient: ClassVar[bool] = False
    in_all: ClassVar[bool] = True          # False for measurement-only scenarios (launch, copy)
    item: ClassVar[str] = ""               # what one item is, for a sampled check's record
    # its error.ulps counts the roundings of one fusable operation (1: once, as an FMA; above: twice)
    ulps_count_roundings: ClassVar[bool] = False
    # the devices where a published row ranks its timings at its default parameters (None: every
    # one); elsewhere a cell at its defaults is timed only for its first result and its error
    timings_ranked_on: ClassVar[tuple[str, ...] | None] = None

    # ---- parameters -------------------------------------------------------------------------
    def params(self, overrides: Mapping[str, Any] | None = None, quick: bool = False):
        """Defaults, then quick overrides, then user overrides; coerced and validated."""
        fields = {f.name: f for f in dataclasses.fields(self.Params)}
        hints = _hints(self.Params)
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

    def timings_ranked(self, params: Any, device: str) -> bool:
        """Whether a published row may rank the timings of a cell of ``params`` on ``device``:
        every size but the defaults, and the defaults on ``timings_ranked_on``."""
        on = self.timings_ranked_on
        return on is None or str(device) in on or params != self.params()

    def describe_params(self) -> str:
        return ", ".join(f"{f.name}={f.default!r}" for f in dataclasses.fields(self.Params))

    def param_rules(self) -> list[tuple[str, Any, str]]:
        """(name, default, what a value must be) per parameter, for ``--help``. The rule is the
        validation's own words, found by offering values it refuses (no second copy to drift)."""
        hints = _hints(self.Params)
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

    def oracle(self, params, inputs: dict[str, np.ndarray], precision: Precision) -> dict[str, np.ndarray]:
        """Float64 NumPy reference computed from the (rounded) inputs; ``precision``: the one they
        were rounded to (the cell's), which sets any error bound the reference carries."""
        raise NotImplementedError

    def check(self, params, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray],
              reference: dict[str, np.ndarray], precision: str) -> Check:
        """Compare ``outputs`` with ``reference`` (the oracle) using the derived tolerance."""
        raise NotImplementedError

    def distance(self, params, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray],
                 other: dict[str, np.ndarray]) -> float:
        """The scenario's error metric between two backends' outputs (e.g. a port vs Warp)."""
        raise NotImplementedError

    def output_shapes(self, params) -> Mapping[str, tuple[int, ...] | None]:
        """The contract a kernel's ``outputs()`` must meet: exactly these names, each an array of
        this shape (None: any shape) with the cell's precision as dtype. The worker checks it and
        turns a violation into an ``error`` record naming it."""
        return {name: None for name in self.outputs}

    def footprint(self, params, precision: str, device: str = "cpu") -> float:
        """Bytes of host memory a cell's worker needs for its data at its peak (inputs, the
        framework's copies, outputs, oracle and check temporaries), beyond the interpreter and
        framework (compare.suites.run.WORKER_BASELINE_BYTES, per device). ``device``: where the
        framework's own working copies live (on a GPU they are not host memory). An upper bound: the run suite
        refuses sizes whose bound exceeds the available memory, and tests/planning/test_preflight.py
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
               ) -> Sample | None:
        """The part of a large cell the check looks at, or None to check everything. ``k``: the
        cell's ``check_sample`` (0: the scenario's default). The oracle of the sampled inputs
        must be the sample of the oracle.

        Default, for per-item scenarios (saxpy, copy, launch, particles without trajectories):
        every input and output array is indexed by item along axis 0 (scalars pass through); the
        rows of ``sample_rows`` (extremes of every input and output array: a NaN or a wild
        value a port writes into one row is always looked at) when k is set and below
        ``params.n``. Anything else is checked in full."""
        n = getattr(params, "n", None)
        if not k or n is None or n <= k:
            return None
        arrays = list(inputs.values()) + list(outputs.values())
        if any(np.ndim(a) and np.shape(a)[0] != n for a in arrays):
            return None
        seed = sample_seed(params)
        idx = sample_rows(n, k, seed, arrays)
        pick = lambda d: {key: (np.asarray(a)[idx] if np.ndim(a) else a) for key, a in d.items()}  # noqa: E731
        return Sample(pick(inputs), pick(outputs), int(idx.size), n, self.item, seed, idx)

    def scaled(self, params, factor: int):
        """The same parameters at 1/``factor`` of the cell's size, run first to predict how long a
        big cell takes (``compare.planning.calibrate``); None (the default) for a cell too small to need it."""
        return None

    def size_text(self, params) -> str:
        return ", ".join(f"{k}={getattr(params, k)}" for k in ("n", "width", "height", "steps")
                         if hasattr(params, k))

    def work(self, params, precision: str) -> dict[str, float]:
        """Useful work per run, for throughput figures and floors: {'bytes': the bytes a run must
        move to and from device memory, 'flops': the floating-point operations it must do,
        'items': ...}."""
        return {}

    def floor(self, params, precision: str, hardware: dict[str, Any]) -> dict[str, Any] | None:
        """The least time one run can take on this hardware (``compare.running.hardware``'s same-run
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
