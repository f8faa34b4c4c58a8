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
from collections.abc import Iterator, Mapping   # not typing's: isinstance through its alias is slow
from typing import Any, ClassVar, Self


SCALARS = frozenset({str, float, int, bool, type(None)})     # JSON's scalars: returned as they are, first


def frozen(v: Any) -> Any:
    """``v`` read-only: objects as mappings, lists as tuples (other values as they are)."""
    if type(v) in SCALARS:
        return v
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


def _field(sub: type[Part] | None, v: Any) -> Any:
    """A field's value read from JSON: the part ``sub`` its object is (or a tuple, one per object
    of its list), else ``v`` read-only."""
    if sub is not None and isinstance(v, Mapping):
        return v if isinstance(v, sub) else sub.from_json(v)
    if sub is not None and isinstance(v, (list, tuple)) and all(isinstance(x, Mapping) for x in v):
        return tuple(x if isinstance(x, sub) else sub.from_json(x) for x in v)
    return frozen(v)


@dataclasses.dataclass(frozen=True, eq=False)
class Part(Mapping[str, Any]):     # a read-only view of a stored JSON object
    """A JSON object with named, typed fields. ``layout`` is the object's keys in their order
    (which are present, null or not); ``extra`` holds the keys no field names."""
    extra: Mapping[str, Any] = dataclasses.field(default_factory=dict, kw_only=True, repr=False)  # stored JSON
    layout: tuple[str, ...] = dataclasses.field(default=(), kw_only=True, repr=False)
    NESTED: ClassVar[Mapping[str, type[Part]]] = {}      # field -> the part its object (or each object of its list) is
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
            else:
                kw[f] = _field(cls.NESTED.get(f), v)
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
    how they were ordered, and each figure over them (``FIGURES``); ``failed`` repeat processes counted;
    ``capped``: why it ran in fewer processes than the others."""
    count: int = 0
    order: str | None = None
    interval: str | None = None
    latency: Figure | None = None
    throughput: Figure | None = None
    graph: Figure | None = None
    events: Figure | None = None
    first_result: Figure | None = None
    failed: int | None = None
    capped: str | None = None     # why the cell stopped before the others (compare.suites.driver.CAPPED)
    FIGURES: ClassVar[tuple[str, ...]] = ("latency", "throughput", "graph", "events", "first_result")
    NESTED: ClassVar[Mapping[str, type[Part]]] = {k: Figure for k in FIGURES}

    def figure(self, name: str) -> Figure | None:
        """A figure by name (one of ``FIGURES``), None where no process measured it."""
        f = getattr(self, name, None) if name in self.FIGURES else None
        return f if isinstance(f, Figure) else None


@dataclasses.dataclass(frozen=True, eq=False)
class NoiseReason(Part):
    """One reason a cell's timings are noisy: the regime it concerns ('' for the whole cell) and why."""
    regime: str = ""
    why: str = ""


@dataclasses.dataclass(frozen=True, eq=False)
class Noise(Part):
    """A ``time.noise`` block (compare.measuring.noise.verdict): whether the timings are noisy,
    why, and the host meter's figures (cores, seconds measured, the cell's and others' use)."""
    noisy: bool | None = None
    reasons: tuple[NoiseReason, ...] | None = None
    cores: int | None = None
    measured_s: float | None = None
    own_cores: float | None = None
    others_cores: float | None = None
    NESTED: ClassVar[Mapping[str, type[Part]]] = {"reasons": NoiseReason}


@dataclasses.dataclass(frozen=True, eq=False)
class HostFunction(Part):
    """One function of a host profile: where it is, its own and cumulative seconds per call."""
    function: str | None = None
    where: str | None = None
    own_s: float | None = None
    cumulative_s: float | None = None
    calls: float | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class HostProfile(Part):
    """A ``time.host_profile`` block (--host-profile, compare.measuring.timing.host_profile): the
    top functions by own time in the throughput regime."""
    calls: int | None = None
    host_s: float | None = None
    profiled_s: float | None = None
    top: tuple[HostFunction, ...] | None = None
    NESTED: ClassVar[Mapping[str, type[Part]]] = {"top": HostFunction}


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
    noise: Noise | None = None           # whether the figures are noisy, why (compare.measuring.noise)
    processes: Processes | None = None   # over several worker processes (compare.running.repeats)
    phases: Mapping[str, float] | None = None
    host_profile: HostProfile | None = None  # where the host's time per call goes (--host-profile)
    NESTED: ClassVar[Mapping[str, type[Part]]] = {**{k: Regime for k in ("wall", "events", "latency", "throughput",
                                                                           "graph", "null")}, "own_timer": OwnTimer,
                                                 "processes": Processes, "noise": Noise, "host_profile": HostProfile}

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


Rate = float | str | None       # a figure per second as stored ('nan', 'inf' as jsonable writes them)


@dataclasses.dataclass(frozen=True, eq=False)
class Throughput(Part):
    """A cell's ``throughput`` block: its work per second (compare.running.worker) and, judged against
    the run's yardstick (compare.running.hardware.annotated), the floor it is held to and the fraction
    of it reached; other rates are extra keys."""
    items_per_s: Rate = None
    bytes_per_s: Rate = None
    flops_per_s: Rate = None
    gradients_per_s: Rate = None
    floor_s: float | None = None        # the stated floor of one call
    floor_kind: str | None = None
    floor: str | None = None            # the floor in words
    hw_fraction: float | None = None    # floor_s / the call's time


@dataclasses.dataclass(frozen=True, eq=False)
class ReferenceInfo(Part):
    """What a converged reference is (a ``converged.reference``): a note, and for a dt reference its
    dt, steps, simulated time and self-difference (its own error scale), for the sdf field its
    evaluation grid. Built in code, its JSON has the fields it has in the format's order."""
    note: str | None = None
    dt: float | None = None
    steps: int | None = None
    simulated_time_s: float | None = None
    self_difference: float | None = None
    eval_grid: int | None = None
    ORDER: ClassVar[tuple[str, ...]] = ("dt", "steps", "simulated_time_s", "self_difference", "eval_grid", "note")

    def __post_init__(self) -> None:
        if not self.layout:         # built in code (an empty object read has no field either)
            object.__setattr__(self, "layout", tuple(k for k in self.ORDER if getattr(self, k) is not None))


@dataclasses.dataclass(frozen=True, eq=False)
class Converged(Part):
    """An error-sweep cell's distance to a converged reference (``Sweeps.converged_error``): ``error``
    in ``metric``, the metric's other ``figures`` (e.g. rms, max: extra keys), and the reference.
    The record's ``converged`` block; built in code its JSON is error, figures, metric, reference."""
    error: float | str | None = None    # a figure as the record writes it ('nan', 'inf'); None: none
    metric: str = ""
    reference: ReferenceInfo | None = None
    NESTED: ClassVar[Mapping[str, type[Part]]] = {"reference": ReferenceInfo}

    def __post_init__(self) -> None:
        if not self.layout:
            object.__setattr__(self, "layout", ("error", *self.extra, "metric", "reference"))

    @classmethod
    def measured(cls, figures: Mapping[str, float], metric: str, reference: ReferenceInfo) -> Converged:
        """From an error function's figures: 'error', then the others in their order."""
        return cls.of(error=figures["error"], **{k: v for k, v in figures.items() if k != "error"},
                      metric=metric, reference=reference)

    @property
    def figures(self) -> Mapping[str, float]:
        """The metric's other figures (rms, max, ...), by name."""
        return self.extra


# the record fields that are parts
PARTS: Mapping[str, type[Part]] = {"time": Timing, "error": Check, "memory": Memory, "gradient": Gradient,
                                   "hardware": Hardware, "throughput": Throughput, "converged": Converged}

__all__ = ["Check", "Converged", "Figure", "Gradient", "Hardware", "HostFunction", "HostProfile", "Memory", "Noise",
           "NoiseReason", "OwnTimer", "PARTS", "Part", "Processes", "Rate", "ReferenceInfo", "Regime", "Throughput",
           "Timing", "frozen", "plain"]
