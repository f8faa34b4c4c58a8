"""One typed cell spec and one record schema for every suite (all, sweep, stress).

A *cell* is one scenario x backend x device x precision x variant at given parameters. Its spec
says what to run and how to time it; its record says what happened. ``tags`` carries a suite's
own identity of the cell (a sweep's kind, role and knob; a stress experiment), so two suites can
run the same cell for different reasons and keep both records.

Its record is ``compare.record.Record`` (the fields, their checks and the format's history).
"""
from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

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
