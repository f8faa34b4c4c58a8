"""The typed parts of a record (``compare.results.record.Record``): a cell's timings per regime, its check
against the oracle, its memory, its gradient and the hardware yardstick it was judged against.

The worker builds each part where it measures it (``Timing.of(...)``, ``Check.of(...)``) and the
record carries it unchanged to every reader, which reads attributes (``rec.time.latency.median_s``).
A part is also a read-only mapping of its JSON object, key order included, so a reader not yet
moved to attributes, and ``to_json``, see exactly the stored object: a key this version does not
name is kept (``extra``), a key that was absent stays absent, a null stays null. The format itself
is told at the top of ``compare.results.record``; ``compare.results.records`` checks it before a part is built.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import types
from typing import Any, ClassVar, Iterator, Mapping, Self


def frozen(v: Any) -> Any:
    """``v`` read-only: objects as mappings, lists as tuples (other values as they are)."""
    if isinstance(v, Part):
        return v
    if isinstance(v, Mapping):
        return types.MappingProxyType({k: frozen(x) for k, x in v.items()})
    if isinstance(v, list):
        return tuple(frozen(x) for x in v)
    return v


def plain(v: Any) -> Any:
    """A value as plain JSON types (dicts and lists), e.g. to ``json.dumps`` it."""
    if isinstance(v, Mapping):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, tuple):
        return [plain(x) for x in v]
    return v


@functools.cache
def _names(cls: type) -> frozenset[str]:
    """A part's field names (its JSON keys that are typed), once per class."""
    return frozenset(f.name for f in dataclasses.fields(cls)) - {"extra", "layout"}


@dataclasses.dataclass(frozen=True, eq=False)
class Part(Mapping[str, Any]):     # a read-only view of a stored JSON object
    """A JSON object with named, typed fields. ``layout`` is the object's keys in their order
    (which are present, null or not); ``extra`` holds the keys no field names."""
    extra: Mapping[str, Any] = dataclasses.field(default_factory=dict, kw_only=True, repr=False)  # stored JSON
    layout: tuple[str, ...] = dataclasses.field(default=(), kw_only=True, repr=False)
    NESTED: ClassVar[Mapping[str, type[Part]]] = {}      # field -> the part its object is
    RENAMED: ClassVar[Mapping[str, str]] = {}            # JSON key -> its field, where the key is a Mapping method

    @classmethod
    def names(cls) -> frozenset[str]:
        return _names(cls)

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> Self:     # stored / worker JSON
        """The part a (checked, ``compare.results.records``) JSON object holds, its keys kept in order."""
        names, kw, extra = cls.names(), {}, {}
        for k, v in obj.items():
            f = cls.RENAMED.get(k, k)
            if f not in names:
                extra[k] = frozen(v)
            elif (sub := cls.NESTED.get(f)) is not None and isinstance(v, Mapping):
                kw[f] = v if isinstance(v, sub) else sub.from_json(v)
            else:
                kw[f] = frozen(v)
        return cls(**kw, extra=types.MappingProxyType(extra), layout=tuple(obj))

    @classmethod
    def of(cls, **fields: Any) -> Self:
        """Built where it is measured: the fields given, in their order (a None given is a null
        in the JSON; a field not given is absent); unnamed ones are kept as extra keys."""
        return cls.from_json(fields)

    def to_json(self) -> dict[str, Any]:     # stored / worker JSON
        return {k: plain(self[k]) for k in self.layout}

    # the read-only mapping of the JSON object
    def __getitem__(self, k: str) -> Any:
        if k not in self.layout:
            raise KeyError(k)
        f = self.RENAMED.get(k, k)
        return getattr(self, f) if f in self.names() else self.extra[k]

    def __iter__(self) -> Iterator[str]:
        return iter(self.layout)

    def __len__(self) -> int:
        return len(self.layout)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({dict(self)!r})"


@dataclasses.dataclass(frozen=True, eq=False)
class Regime(Part):
    """One timing regime's per-call seconds (compare.measuring.timing): latency, throughput, graph, null,
    events; ``failed`` / ``unavailable`` say why a regime has no figures."""
    median_s: float | None = None
    iqr_s: float | None = None
    min_s: float | None = None
    repeats: int | None = None
    k: int | None = None                 # calls per batch (throughput, graph)
    host_s: float | None = None          # the host's share of a pipelined call
    how: str | None = None
    same_as: str | None = None           # a regime that is another's figures (one call lasts a batch)
    clock: str | None = None
    failed: str | None = None
    unavailable: str | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class OwnTimer(Part):
    """The framework's own timer of one call, alternated with ours (``compare.running.worker.own_latency``)."""
    tool: str | None = None
    median_s: float | None = None          # the tool's figure
    calls: int | None = None
    block: int | None = None               # calls per mean in the tool's statistic
    ours_s: float | None = None            # our clock in the tool's statistic, same stretches
    ours_call_s: float | None = None       # our latency statistic in those stretches
    ratio: float | None = None             # median of the rounds' ours / theirs
    rounds: int | None = None
    failed: str | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class Figure(Part):
    """One figure over several worker processes (``compare.running.repeats.summary``): every
    process's value (the JSON's ``values``), their median and its distribution-free interval at
    its coverage."""
    each: tuple[float, ...] = ()
    RENAMED: ClassVar[Mapping[str, str]] = {"values": "each"}
    median_s: float = math.nan
    ci_lo_s: float = math.nan
    ci_hi_s: float = math.nan
    confidence: float = 0.0


@dataclasses.dataclass(frozen=True, eq=False)
class Processes(Part):
    """A ``time.processes`` block: a cell timed in ``count`` worker processes (compare.running.repeats),
    how they were ordered, and each figure over them (``FIGURES``); ``failed`` repeat processes counted."""
    count: int = 0
    order: str | None = None
    interval: str | None = None
    latency: Figure | None = None
    throughput: Figure | None = None
    graph: Figure | None = None
    events: Figure | None = None
    first_result: Figure | None = None
    failed: int | None = None
    FIGURES: ClassVar[tuple[str, ...]] = ("latency", "throughput", "graph", "events", "first_result")
    NESTED: ClassVar[Mapping[str, type[Part]]] = {k: Figure for k in FIGURES}

    def figure(self, name: str) -> Figure | None:
        """A figure by name (one of ``FIGURES``), None where no process measured it."""
        f = getattr(self, name, None) if name in self.FIGURES else None
        return f if isinstance(f, Figure) else None


@dataclasses.dataclass(frozen=True, eq=False)
class Timing(Part):
    """A cell's ``time`` block: the first call, the latency (the block's own median, iqr, min),
    the other regimes, and how the clocks were set up (docs/measurement.md)."""
    # every time block has these five (compare.results.records): the defaults stand for no key at all
    first_call_s: float = math.nan
    median_s: float = math.nan
    iqr_s: float = math.nan
    min_s: float = math.nan
    repeats: int = 0
    warmup: int | None = None
    timed_total_s: float | None = None
    wall: Regime | None = None
    events: Regime | None = None
    events_error: str | None = None
    latency: Regime | None = None
    throughput: Regime | None = None
    graph: Regime | None = None
    null: Regime | None = None
    own_timer: OwnTimer | None = None
    setup_s: float | None = None
    download_s: float | None = None
    clock: str | None = None
    timer: str | None = None
    first_call_clock: str | None = None
    cache: str | None = None
    window: tuple[float, ...] | None = None      # epoch seconds the timed window opened and closed
    noise: Mapping[str, Any] | None = None     # stored JSON (compare.measuring.noise.Noise when measured)
    processes: Processes | None = None   # over several worker processes (compare.running.repeats)
    phases: Mapping[str, float] | None = None
    host_profile: Mapping[str, Any] | None = None  # where the host's time per call goes (--host-profile)
    NESTED: ClassVar[Mapping[str, type[Part]]] = {**{k: Regime for k in ("wall", "events", "latency", "throughput",
                                                                           "graph", "null")}, "own_timer": OwnTimer,
                                                 "processes": Processes}

    def regime(self, name: str) -> Regime | None:
        """A regime by name ('latency', 'throughput', 'graph', 'null', 'events')."""
        r = getattr(self, name, None) if name in self.NESTED else None
        return r if isinstance(r, Regime) else None


@dataclasses.dataclass(frozen=True, eq=False)
class Check(Part):
    """A cell's ``error`` block: its distance to the float64 oracle against the tolerance, and to
    the reference backend; the scenario's own details are extra keys (``Check.details``)."""
    vs_oracle: float | str | None = None       # 'nan', 'inf', '-inf' as jsonable writes them
    tolerance: float | str | None = None
    vs_reference: float | str | None = None
    reference: str | None = None
    vs_reference_device: str | None = None
    metric: str | None = None
    checked_items: str | None = None
    ill_conditioned: int | None = None

    @property
    def details(self) -> Mapping[str, Any]:     # the scenario's own, as stored
        """The scenario's own figures (``Scenario.check``'s details), by their names."""
        return self.extra


@dataclasses.dataclass(frozen=True, eq=False)
class Memory(Part):
    """A cell's ``memory`` block: peak host RSS, the cell's own host bytes; the backend's device
    figures and NVML's are extra keys (their names are the backend's)."""
    peak_host_rss_bytes: int | None = None
    host_bytes: int | None = None
    device_bytes: int | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class Gradient(Part):
    """How a differentiable cell's gradient was obtained, and its errors."""
    method: str | None = None
    value: Any = None                          # a figure or a tuple of them
    reference: str | None = None
    reference_value: Any = None
    vs_oracle: float | str | None = None
    vs_oracle_rel: float | str | None = None
    vs_fd64_rel: float | str | None = None
    tolerance: Any = None
    fd_agreement: float | str | None = None
    fd_resolved: float | str | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class Hardware(Part):
    """The yardstick a cell was judged against (compare.running.hardware): copy bandwidth, launch cost."""
    copy_bytes_per_s: float | None = None
    copy_how: str | None = None
    copy_bytes: float | None = None
    copy_median_s: float | None = None
    launch_latency_s: float | None = None
    launch_pipelined_s: float | None = None
    gpu: str | None = None
    error: str | None = None


# the record fields that are parts
PARTS: Mapping[str, type[Part]] = {"time": Timing, "error": Check, "memory": Memory, "gradient": Gradient,
                                   "hardware": Hardware}

__all__ = ["Check", "Figure", "Gradient", "Hardware", "Memory", "OwnTimer", "PARTS", "Part", "Processes", "Regime", "Timing", "frozen", "plain"]
