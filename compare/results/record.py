"""A cell's record: what happened when one cell ran, immutable, read and written in one place.

Format history (a results file's ``format_version``; ``compare.results.store.Store.read`` loads every
version below and saves the newest; users load these files with pandas, so keys are kept):

  2 - (2026-11-23) one file shape for every suite: ``{"format_version": 2, "suite": "run" |
      "sweep" | "stress", "runs": [...], "records": [...], "analysis": {...}}``. A run record's
      distance to the reference backend is ``error.vs_reference``, with ``error.reference`` naming
      the backend and ``error.vs_reference_device`` its device (was ``error.vs_warp``,
      ``error.vs_warp_device``); a sweep record's ``sweep``, ``role`` and ``knob`` moved under
      ``tags`` (the bandwidth sweep's role became its scenario's ``measures``, was the scenario's
      name). Fields added since without a new version (absent from older files, read as null):
      ``hardware``, ``host_cores``, ``run`` (the run that measured the record: its ``created``
      time, ``commit`` and whether the tree was ``dirty``), ``time.events`` (device events, a
      separate pass; before it an event-timed record's own figures were the events),
      ``time.null``, ``time.own_timer``, ``time.processes`` (compare.running.repeats); in a
      stress file, each provenance run's ``git_dirty`` and a merged run entry's ``environments``
      (every run its rows come from); a run entry's ``sitting`` (``{"start", "end"}``: the sitting
      checks, ``compare.measuring.sitting``; later ``quiet``, the reference the start was judged
      against, null where there was none), ``noisy_sitting`` and ``noisy_sitting_reasons``, its
      CUDA yardstick's ``launch_latency_iqr_s``, and ``run.noisy_sitting`` in its records (and in a
      stress provenance run); ``cell_floor`` (a CUDA cell's own launch floor, probed in its worker
      ``before`` the framework's set-up and ``after`` the timed regimes, ``compare.running.cell_floor``:
      each probe's ``latency_s``, ``latency_iqr_s``, ``pipelined_s``, ``launches``, ``k``,
      ``batches``, ``spent_s``, ``context``, ``error``; and ``how``).
  1 - no ``format_version``: ``results.json`` is ``{"environment", "records"}``, ``sweep.json``
      ``{"runs", "records"}``, ``stress.json`` ``{"environment", "provenance", "rows", "series"}``.
      Each suite's format upgrades its records (``compare.results.formats``).

The measured blocks are typed parts (``compare.results.record_parts``: ``Timing`` with its ``Regime``s,
``Noise`` and ``HostProfile``, ``Check``, ``Memory``, ``Gradient``, ``Hardware``, ``Throughput``,
``Converged``; ``CellFloor`` in ``compare.results.record_floor``), built where they are measured and read by attribute; each is also a read-only mapping of its JSON object, so the format is unchanged.

``Record.from_json`` is the one validating loader: every record a reader sees (report, resume,
merge, the site, the sweep and stress pages) and every record the engine stores went through it,
so each field a later step formats, compares, divides or indexes has its type and range
(``compare.results.records``); a malformed one is a ``RecordError`` naming the field. ``to_json`` gives
back the same object (key order included), so a file loaded and saved again is the same bytes.
"""
from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable, Mapping   # not typing's: isinstance through its alias is slow
from typing import Any

from compare.results import records
from compare.results.record_floor import CellFloor
from compare.results.record_parts import (PARTS, SCALARS, Check, Converged, Gradient, Hardware, Memory, Part, Regime,
                                          Throughput, Timing, plain)
from compare.spec import Identity, key as cell_key
from scenarios.base import Precision

FORMAT_VERSION = 2
TYPED: Mapping[str, type[Part]] = {**PARTS, "cell_floor": CellFloor}     # the record fields that are parts
Block = Mapping[str, Any]      # a read-only JSON object; its lists are tuples


class RecordError(ValueError):
    """A record no reader could use: one line naming the first field that is wrong."""


def _freeze(v: Any, field: str, depth: int = 1) -> Any:
    """``v`` read-only; a block nested past ``records.MAX_DEPTH`` is refused here, where the
    recursion would otherwise end in a RecursionError (this and every later reader recurse)."""
    if type(v) in SCALARS:          # most of a record: no isinstance walk for them
        return v
    if isinstance(v, (Mapping, list, tuple)) and depth > records.MAX_DEPTH:
        raise RecordError(f"{field} is nested more than {records.MAX_DEPTH} levels deep")
    if isinstance(v, Mapping):
        return types.MappingProxyType({k: _freeze(x, field, depth + 1) for k, x in v.items()})
    if isinstance(v, (list, tuple)):
        return tuple(_freeze(x, field, depth + 1) for x in v)
    return v




@dataclasses.dataclass(frozen=True)
class Record:
    """One cell's result. Blocks are None where the record has none (a skipped cell has no time);
    docs/commands.md, "What each column means", says what the figures in them are."""
    # identity: the same cell run twice has one ``key``
    scenario: str
    backend: str
    device: str                         # a name: a file may hold a device this version lacks
    precision: Precision
    status: str                         # ok | mismatch | error | skipped
    variant: str = "default"
    params: Block | None = None         # the scenario's resolved parameters
    tags: Block | None = None           # a suite's own identity of the cell (sweep kind, role, knob)
    reason: str = ""                    # why not ok ('' when ok)
    # what was measured, when the cell ran
    time: Timing | None = None          # first call, latency, throughput and graph regimes, noise
    error: Check | None = None          # against the float64 oracle and the reference backend
    work: Mapping[str, float] | None = None     # bytes, items, flops per call
    throughput: Throughput | None = None    # work per second; the hardware floor and fraction
    memory: Memory | None = None        # peak host RSS, device bytes
    gradient: Gradient | None = None    # how a gradient was obtained and its errors
    converged: Converged | None = None  # the error sweep's distance to a converged reference
    hardware: Hardware | None = None    # the yardstick the cell was judged against
    cell_floor: CellFloor | None = None     # the cell's own launch floor, probed in its worker
    info: Block | None = None           # the kernel's own notes
    versions: Block | None = None       # the framework's packages
    host: str | None = None
    host_load_1m: float | None = None
    host_cores: int | None = None
    machine: str | None = None          # which machine, where records of several were merged
    run: Block | None = None            # the run that measured it: created, commit, dirty
    traceback: str | None = None        # a failed cell's
    extra: Block = dataclasses.field(default_factory=dict)     # keys this version does not name, as found
    # the stored object's keys in their order, so saving writes what was read
    layout: tuple[str, ...] = dataclasses.field(default=(), compare=False, repr=False)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            # a key this version does not name is refused by its own name
            if isinstance(v, Part):
                continue
            v = (types.MappingProxyType({k: _freeze(x, records.show_key(k)) for k, x in v.items()})
                 if f.name == "extra" else _freeze(v, f.name))
            if f.name in TYPED and isinstance(v, Mapping):     # a typed part, from its JSON
                v = TYPED[f.name].from_json(v)
            object.__setattr__(self, f.name, v)
        if not isinstance(self.precision, Precision):     # checked on load (compare.results.records)
            object.__setattr__(self, "precision", Precision(self.precision))
        if not self.layout:         # built in code: the fields it has, in declaration order
            have = tuple(f for f in NAMED if getattr(self, f) is not None)
            object.__setattr__(self, "layout", have + tuple(self.extra))

    @classmethod
    def from_json(cls, obj: Any, upgrade: Callable[[dict[str, Any]], dict[str, Any]] | None = None,  # stored JSON
                  check: Callable[[dict[str, Any]], str | None] | None = None) -> Record:   # of stored JSON
        """The record a JSON object holds, validated; ``upgrade`` turns an older format's record
        into today's (applied once its basic shape is known good), ``check`` is its suite's own
        check (``compare.results.formats``) after the common schema's."""
        problem = records.shape_problem(obj)
        if problem is None and upgrade is not None:
            obj = upgrade(obj)
        problem = problem or records.record_problem(obj)
        if problem is None and check is not None:
            problem = check(obj)
        if problem is not None:
            raise RecordError(problem)
        named = {k: v for k, v in obj.items() if k in NAMED}
        return cls(**named, extra={k: v for k, v in obj.items() if k not in NAMED}, layout=tuple(obj))

    def to_json(self) -> dict[str, Any]:     # the stored file's / worker's JSON
        """The record as the JSON object it was read from (plain dicts and lists)."""
        return {k: plain(getattr(self, k) if k in NAMED else self.extra[k]) for k in self.layout}

    def replace(self, **changes: Any) -> Record:
        """A copy with some named fields changed; a field the record lacked is added last."""
        layout = self.layout + tuple(k for k in changes if k not in self.layout)
        return dataclasses.replace(self, **changes, layout=layout)

    @property
    def fd_agreement(self) -> float | None:
        """The share of the checked gradients that agree with float64 finite differences, where measured."""
        share = self.gradient.fd_agreement if self.gradient else None
        return float(share) if isinstance(share, (int, float)) else None

    @property
    def process_count(self) -> int:
        """How many worker processes timed the cell (1 for a record without repeats)."""
        n = self.time.processes.count if self.time and self.time.processes else None
        return n if isinstance(n, int) and not isinstance(n, bool) else 1

    @property
    def key(self) -> str:
        """The cell's identity as a string (``compare.spec.key``)."""
        return cell_key(self.identity)

    @property
    def identity(self) -> Identity:
        """Scenario, backend, device, precision, variant, and the params and tags it has, as
        plain JSON: what names the cell (its key, its saved arrays' file)."""
        ident = Identity(scenario=self.scenario, backend=self.backend, device=self.device, precision=self.precision,
                         variant=self.variant, params=plain(self.params))
        if self.tags is not None:
            ident["tags"] = plain(self.tags)
        return ident


NAMED = tuple(f.name for f in dataclasses.fields(Record) if f.name not in ("extra", "layout"))

__all__ = ["Block", "CellFloor", "Check", "Converged", "FORMAT_VERSION", "Gradient", "Hardware", "Memory", "Record",
           "RecordError", "Regime", "Throughput", "Timing", "plain"]
