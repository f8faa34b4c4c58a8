"""One typed cell for every suite (all, sweep, stress), and one record schema.

A *cell* is one scenario x backend x device x precision x variant at given parameters: a frozen
``Cell`` built once when a suite plans its run (its parameters resolved into the scenario's own
dataclass, its device and precision enums) and handed unchanged to the engine, the worker and the
kernel. It crosses the process boundary (a worker, a Dask task) through one pair,
``Cell.to_dict`` / ``Cell.from_dict``. Besides what to run it says how to time it. ``tags``
carries a suite's own identity of the cell (a sweep's kind, role and knob; a stress experiment),
so two suites can run the same cell for different reasons and keep both records.

Its record is ``compare.results.record.Record`` (the fields, their checks and the format's history).
"""
from __future__ import annotations

import dataclasses
import json
import math
from typing import Any, NotRequired, TypedDict, TypeVar

import scenarios
from backends.base import Device
from scenarios.base import ParamError, Precision

STATUSES = ("ok", "mismatch", "error", "skipped")
IDENTITY = ("scenario", "backend", "device", "precision", "variant")
# a rerun (--resume) keeps these and retries the rest (a crash, timeout or kill is not a result)
KEPT_ON_RESUME = ("ok", "mismatch", "skipped")


class SpecError(ValueError):
    """A malformed cell or record; one line naming the first problem."""


ParamValue = int | float | str | bool | None      # a scenario parameter's value (its Params' fields)


class Identity(TypedDict):
    """What names a cell in every record, as plain JSON (``Cell.identity``, ``Record.identity``)."""
    scenario: str
    backend: str
    device: str
    precision: str
    variant: str
    params: dict[str, ParamValue]
    tags: NotRequired[dict[str, Any]]     # a suite's own, as its stored records keep them (sweep knob, stress)


BUSY_TAG = "busy_cores"     # tags: a cell timed while this many other processes keep cores busy

_E = TypeVar("_E", Device, Precision)


def _enum(kind: type[_E], f: str, value: Any) -> _E:
    try:
        return kind(value)
    except ValueError:
        raise SpecError(f"cell spec: {f} must be one of {', '.join(kind)}, got {str(value)!r}") from None


def _identity(scenario: Any, backend: Any, device: Any, precision: Any, variant: Any) -> tuple[Device, Precision]:
    """The cell's identity (``IDENTITY``, in its order) checked, and its device and precision as
    enums: the first bad field is a SpecError naming it. ``Cell.__post_init__`` runs it, and
    ``Cell.make`` where strings become a cell (so the enums it builds with are typed)."""
    for f, v in zip(IDENTITY, (scenario, backend, device, precision, variant)):
        if not isinstance(v, str) or not v:
            raise SpecError(f"cell spec: {f} must be a non-empty string, got {v!r}")
    return _enum(Device, "device", device), _enum(Precision, "precision", precision)


@dataclasses.dataclass(frozen=True)
class Cell:
    """One cell: what to run (identity, typed; ``params`` the scenario's resolved Params) and how
    to time it. Build it with the resolved parameters, or with ``make`` from overrides."""
    scenario: str
    backend: str
    device: Device
    precision: Precision
    variant: str = "default"
    params: Any = None                  # the scenario's Params dataclass, resolved (None: defaults)
    tags: dict[str, Any] = dataclasses.field(default_factory=dict)  # as stored in its records
    warmup: int = 2                     # timing.steady_state: untimed calls after the first
    repeat: int = 10                    # ... then at least this many timed calls
    min_time: float = 0.2               # ... and at least this many timed seconds
    max_time: float = 10.0              # stop early past this with at least 3 calls
    timer: str = "auto"                 # 'auto': device events where the backend has them; 'wall'
    cache: str = "cold"                 # 'cold': empty kernel caches for the first call; 'warm'
    throughput: bool = True             # also time the throughput (and graph) regimes
    check_sample: int = 0               # check k sampled items of large per-item cells (sample_rows)
    host_profile: int = 0               # >0: cProfile the throughput regime, keep this many functions
    save_outputs: bool = True           # hand the outputs back (cross-backend comparison)
    own_timer: bool = True              # cross-check our clock with the framework's own timer (False:
                                        # a suite none of whose pages reads it, the sweeps)
    save_inputs: bool = False           # also the inputs (--save-arrays)
    check: bool = True                  # False: a repeat process of a checked cell, its figures alone
                                        # (no download, oracle, host profile, null call or own timer)
    cache_dir: str = ""                 # cold caches in this directory, which outlives the process: empty,
                                        # this process fills it; filled, it starts from them ('kept')

    def __post_init__(self) -> None:
        device, precision = _identity(*(getattr(self, f) for f in IDENTITY))
        object.__setattr__(self, "device", device)
        object.__setattr__(self, "precision", precision)
        try:
            sc = scenarios.get(self.scenario)
        except ParamError as exc:
            raise SpecError(f"cell spec: {exc}") from None
        if self.params is None:
            object.__setattr__(self, "params", sc.params())
        if not isinstance(self.params, sc.Params):
            raise SpecError(f"cell spec: params must be a resolved {sc.Params.__name__}, "
                            f"got {type(self.params).__name__} (Cell.make resolves overrides)")
        if not isinstance(self.tags, dict):
            raise SpecError("cell spec: tags must be a mapping")
        if not (isinstance(self.repeat, int) and self.repeat >= 1):
            raise SpecError(f"cell spec: repeat must be an integer >= 1, got {self.repeat!r}")
        for f in ("min_time", "max_time"):
            v = getattr(self, f)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise SpecError(f"cell spec: {f} must be finite and >= 0, got {v!r}")
        for f in ("warmup", "check_sample", "host_profile"):
            v = getattr(self, f)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                raise SpecError(f"cell spec: {f} must be an integer >= 0, got {v!r}")
        if self.timer not in ("auto", "wall") or self.cache not in ("cold", "warm"):
            raise SpecError(f"cell spec: timer must be auto|wall and cache cold|warm, got {self.timer!r}, {self.cache!r}")
        if not isinstance(self.cache_dir, str) or (self.cache_dir and self.cache != "cold"):
            raise SpecError(f"cell spec: cache_dir must be a path (with cache cold), got {self.cache_dir!r}")

    @classmethod
    def make(cls, scenario: str, backend: str, device: str, precision: str, variant: str = "default",
             params: Any = None, quick: bool = False, **settings: Any) -> "Cell":
        """A cell whose ``params`` may be overrides (a mapping: the scenario's defaults, then its
        quick overrides with ``quick``, then these; coerced and validated) or already resolved."""
        if not isinstance(params, (dict, type(None))) and not quick:
            return cls(scenario, backend, *_identity(scenario, backend, device, precision, variant),
                       variant, params, **settings)
        try:
            sc = scenarios.get(scenario)
        except ParamError as exc:
            raise SpecError(f"cell spec: {exc}") from None
        if params is not None and not isinstance(params, dict):
            params = dataclasses.asdict(params)
        resolved = sc.params(params, quick=quick)
        return cls(scenario, backend, *_identity(scenario, backend, device, precision, variant),
                   variant, resolved, **settings)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Cell":     # worker / Dask JSON
        """The decode of ``to_dict`` (in a worker, a Dask task). A hand-written dict may also
        give ``params`` as overrides and ``quick`` (see ``make``)."""
        if not isinstance(d, dict):
            raise SpecError(f"cell spec: must be an object, got {type(d).__name__}")
        fields = {f.name for f in dataclasses.fields(cls)} | {"quick"}
        unknown = sorted(set(d) - fields)
        if unknown:
            raise SpecError(f"cell spec: unknown key {unknown[0]!r}")
        if not isinstance(d.get("params", {}), (dict, type(None))):
            raise SpecError("cell spec: params and tags must be mappings")
        try:
            return cls.make(**d)
        except TypeError as exc:
            raise SpecError(f"cell spec: {exc}") from None

    def to_dict(self) -> dict[str, Any]:     # worker / Dask JSON
        """Plain JSON types: the parameters as a mapping, device and precision as their names."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out.update(device=str(self.device), precision=str(self.precision),
                   params=dataclasses.asdict(self.params), tags=dict(self.tags))
        return out

    def identity(self) -> Identity:
        """What every record of this cell carries to say which cell it is (``key`` of it), in
        plain JSON types as a record holds it."""
        ident = Identity(scenario=self.scenario, backend=self.backend, device=str(self.device),
                         precision=str(self.precision), variant=self.variant, params=dataclasses.asdict(self.params))
        if self.tags:
            ident["tags"] = self.tags
        return ident

    def key(self) -> str:
        return key(self.identity())


def key(rec_or_spec: Identity | dict[str, Any]) -> str:   # or a stored record's JSON (samecheck)
    """The identity of a cell (spec or record) as a string: the same cell run twice has one key."""
    return json.dumps([rec_or_spec.get(f, "default" if f == "variant" else None) for f in IDENTITY]
                      + [rec_or_spec.get("params"), rec_or_spec.get("tags") or {}],
                      sort_keys=True, default=str)
