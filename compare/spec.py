"""One typed cell spec and one record schema for every suite (all, sweep, stress).

A *cell* is one scenario x backend x device x precision x variant at given parameters. Its spec
says what to run and how to time it; its record says what happened. ``tags`` carries a suite's
own identity of the cell (a sweep's kind, role and knob; a stress experiment), so two suites can
run the same cell for different reasons and keep both records.

Record (``format_version`` 2; users load these with pandas, so the keys are stable; docs/commands.md
"What each column means" documents them):
    scenario, backend, device, precision, variant, params, tags   identity
    status        ok | mismatch | error | skipped
    reason        why not ok ('' when ok)
    time          {first_call_s, median_s, iqr_s, min_s, repeats, wall: {...}, setup_s, ...} | None
    error         {vs_oracle, tolerance, vs_reference, reference, ...} | None
    work, throughput, memory, info, versions, host, gradient        when the cell ran

``record_problem`` checks this shape; compare/records.py then checks, when a file is read, every
field inside it that a later step reads (types, ranges, the params by their scenario).
"""
from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

FORMAT_VERSION = 2
STATUSES = ("ok", "mismatch", "error", "skipped")
IDENTITY = ("scenario", "backend", "device", "precision", "variant")
# a rerun (--resume) keeps these and retries the rest (a crash, timeout or kill is not a result)
KEPT_ON_RESUME = ("ok", "mismatch", "skipped")


class SpecError(ValueError):
    """A malformed spec or record; one line naming the first problem."""


@dataclasses.dataclass(frozen=True)
class CellSpec:
    scenario: str
    backend: str
    device: str
    precision: str
    variant: str = "default"
    params: dict[str, Any] = dataclasses.field(default_factory=dict)   # overrides or resolved
    quick: bool = False                 # apply the scenario's quick overrides first
    tags: dict[str, Any] = dataclasses.field(default_factory=dict)
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
    save_inputs: bool = False           # also the inputs (--save-arrays)

    def __post_init__(self) -> None:
        for f in IDENTITY:
            if not isinstance(getattr(self, f), str) or not getattr(self, f):
                raise SpecError(f"cell spec: {f} must be a non-empty string, got {getattr(self, f)!r}")
        if not isinstance(self.params, dict) or not isinstance(self.tags, dict):
            raise SpecError("cell spec: params and tags must be mappings")
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

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "CellSpec":
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - fields)
        if unknown:
            raise SpecError(f"cell spec: unknown key {unknown[0]!r}")
        try:
            return cls(**d)
        except TypeError as exc:
            raise SpecError(f"cell spec: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def key(rec_or_spec: dict[str, Any]) -> str:
    """The identity of a cell (spec or record) as a string: the same cell run twice has one key."""
    return json.dumps([rec_or_spec.get(f, "default" if f == "variant" else None) for f in IDENTITY]
                      + [rec_or_spec.get("params"), rec_or_spec.get("tags") or {}],
                      sort_keys=True, default=str)


def record_problem(rec: Any) -> str | None:
    """The first way ``rec`` is not a record of this schema, or None."""
    if not isinstance(rec, dict):
        return f"a record must be an object, got {type(rec).__name__}"
    for f in ("scenario", "backend", "device", "precision"):
        if not isinstance(rec.get(f), str):
            return f"record field {f!r} must be a string, got {rec.get(f)!r}"
    if rec.get("status") not in STATUSES:
        return f"record status must be one of {', '.join(STATUSES)}, got {rec.get('status')!r}"
    for f in OBJECT_FIELDS:
        if rec.get(f) is not None and not isinstance(rec[f], dict):
            return f"record field {f!r} must be an object or null, got {type(rec[f]).__name__}"
    if not isinstance(rec.get("variant", "default"), str) or not isinstance(rec.get("reason", ""), str):
        return "record fields 'variant' and 'reason' must be strings"
    for f, keys in NUMBER_FIELDS.items():
        for k in keys:
            v = (rec.get(f) or {}).get(k)
            if v is not None and not _number(v):
                return f"record field {f}.{k} must be a number or null, got {v!r}"
    return None


# Record fields that are objects (or null), and the figures inside them that are numbers (or
# null, or the strings 'nan', 'inf', '-inf' that jsonable writes for non-finite floats).
OBJECT_FIELDS = ("params", "time", "error", "tags", "work", "throughput", "memory", "info", "versions",
                 "gradient", "converged")
NUMBER_FIELDS = {"time": ("first_call_s", "median_s", "iqr_s", "min_s"),
                 "error": ("vs_oracle", "tolerance", "vs_reference")}


def _number(v: Any) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) or v in ("nan", "inf", "-inf")
