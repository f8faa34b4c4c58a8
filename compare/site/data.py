"""One machine's stored results, as the site reads them, and the figures it takes from a record.

A machine's store is a folder of suite files (results.json, sweep.json, stress.json; any may be
missing) in the common format of compare/results/store.py; files may also be named one by one. Records of
the run and sweep suites are pooled for the questions that both can answer (a SAXPY at the
largest n may come from either); the stress suite's analysis feeds the stability page.
"""
from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any, Iterable, Mapping, cast

import scenarios
from compare.measuring import noise
from compare.running import repeats
from compare.results.environment import PublishLog, RunEnvironment
from compare.results.record import Record
from compare.spec import BUSY_TAG, ParamValue
from compare.results.store import SUITES, Store, StoreError, run_environments
from compare.sweep.points import sweeps

PUBLISH_LOG = "publish.json"


@dataclasses.dataclass(frozen=True)
class Machine:
    """The records of one machine, by suite, with the runs (environments) that made them."""
    sources: tuple[Path, ...]
    run: tuple[Record, ...]
    sweep: tuple[Record, ...]
    stress: Store | None
    runs: tuple[RunEnvironment, ...]
    publish: PublishLog | None      # DIR/publish.json, where ``compare publish`` made the records
    # the shared-host experiment (``run --busy``): cells timed idle and with cores kept busy by
    # other processes, tagged ``busy_cores``; its row alone reads them, no other reader sees them
    busy: tuple[Record, ...] = ()

    @property
    def records(self) -> list[Record]:
        """Sweep records first, so that where both suites measured a cell the run suite's record
        (the dedicated measurement) is the later one, which the rows keep."""
        return [*self.sweep, *self.run]

    @property
    def frameworks(self) -> list[str]:
        """Every backend named by a record, in the backend registry's order."""
        import backends
        seen = {r.backend for r in self.records}
        if self.stress is not None:
            seen |= {r.backend for r in self.stress.records}
        order = list(backends.BACKENDS)
        return [b for b in order if b in seen] + sorted(seen - set(order))

    def devices(self) -> list[str]:
        """Devices with at least one ok timed record, CUDA first."""
        have = {r.device for r in self.records if r.status == "ok" and r.time}
        return [d for d in ("cuda", "cpu") if d in have] + sorted(have - {"cuda", "cpu"})

    @property
    def primary_device(self) -> str:
        devs = self.devices()
        return devs[0] if devs else "cpu"

    def gpu_name(self) -> str | None:
        for env in self.runs:
            for g in env.get("gpus") or []:
                if isinstance(g, dict) and g.get("name"):
                    return str(g["name"])
        return None

    def cpu_name(self) -> str:
        """'Intel Xeon (2 cores)': the model as the OS names it, less its trademark signs and a
        trailing 'Processor' (the report's default title, so no store needs one given by hand)."""
        env: RunEnvironment = next((e for e in self.runs if e.get("cpu")), RunEnvironment())
        model = re.sub(r"\((R|TM)\)|\s+(CPU\s+)?Processor$", "", str(env.get("cpu", "CPU")), flags=re.I)
        return f"{' '.join(model.split()) or 'CPU'} ({env.get('cores', '?')} cores)"

    def name(self) -> str:
        """The machine in words: its GPU where CUDA cells ran, else its CPU."""
        gpu = self.gpu_name()
        return gpu if gpu and self.primary_device == "cuda" else self.cpu_name()


def _suite_files(path: Path) -> list[Path]:
    if path.is_dir():
        found = [path / f for f in SUITES.values() if (path / f).is_file()]
        if not found:
            raise StoreError(f"{path}: no results.json, sweep.json or stress.json in this folder")
        return found
    return [path]


def load(paths: Iterable[Path]) -> Machine:
    """The stores at ``paths`` merged by suite (a later record of the same cell wins)."""
    merged: dict[str, Store] = {}
    sources: list[Path] = []
    publish: PublishLog | None = None
    for p in paths:
        p = Path(p)
        for f in _suite_files(p):
            s = Store.read(f)
            sources.append(f)
            if s.suite in merged:
                merged[s.suite].merge(s)
            else:
                merged[s.suite] = s
        log = (p if p.is_dir() else p.parent) / PUBLISH_LOG
        if log.is_file():
            from compare.results.store import read_bounded
            try:
                obj = json.loads(read_bounded(log, 16 * 2**20))
            except (OSError, ValueError, RecursionError) as exc:
                raise StoreError(f"cannot read {log}: {exc}") from None
            if not isinstance(obj, dict) or not isinstance(obj.get("parts", []), list):
                raise StoreError(f"{log}: not a publish log (an object with a list of parts)")
            publish = cast(PublishLog, obj)      # typed once read: its entries are read with get
    runs = [e for s in merged.values() for env in s.runs for e in run_environments(env)]     # a merge: its runs
    run = tuple(merged["run"].records) if "run" in merged else ()
    return Machine(tuple(sources), tuple(r for r in run if tag(r, BUSY_TAG) is None),
                   tuple(merged["sweep"].records) if "sweep" in merged else (),
                   merged.get("stress"), tuple(runs), publish, tuple(r for r in run if tag(r, BUSY_TAG) is not None))


# ---- figures of one record --------------------------------------------------------------------
def tag(rec: Record, name: str) -> Any:
    return (rec.tags or {}).get(name)


def num(x: Any) -> float | None:
    """A finite float, or None (the store writes non-finite numbers as strings)."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclasses.dataclass(frozen=True)
class Timing:
    """One regime's per-call time of one record: median, quartile bounds, repeats, noise; where
    the figure was measured in several worker processes (``time.processes``), ``median`` is the
    median of the processes' figures and ``ci`` its interval (docs/measurement.md)."""
    median: float
    lo: float
    hi: float
    repeats: int | None
    noisy: str = ""              # why the figure is not to be trusted as it stands ('' if fine)
    processes: int = 1           # independent worker processes behind ``median``
    ci: tuple[float, float] | None = None   # the median's interval across processes; None for one


REGIMES = ("latency", "throughput", "graph")


def timing(rec: Record, regime: str) -> Timing | None:
    """``regime``: 'latency' (one synchronised call), 'throughput' (k calls, one synchronise,
    per call), 'graph' (a captured call replayed), or 'first' (the first call, cold caches)."""
    t = rec.time
    if regime == "first":
        v = num(t.first_call_s) if t else None
        return Timing(v, v, v, 1) if v is not None else None
    several = across_processes(rec, regime)
    if several is not None:
        return several
    part = (t.regime(regime) if regime != "latency" else (t.latency or t)) if t else None
    if part is None:
        return None
    med, iqr = num(part.median_s), num(part.iqr_s)
    if med is None or med <= 0:
        return None
    iqr = iqr or 0.0
    reps = part.repeats if isinstance(part.repeats, int) else None
    # the spread and repeats of this regime, and what the run saw of the host (a record made
    # before time.noise existed has only the first two)
    why = noise.regime_reasons(part)
    why += [w for w in noise.reasons_for(rec, regime) if w not in why]
    return Timing(med, max(med - iqr / 2, 0.0), med + iqr / 2, reps, "; ".join(why))


def first_result(rec: Record) -> Timing | None:
    """Time to first result: set-up (the kernel's constructor) + the first call, the figure that
    is fair between ports that compile in one or the other (docs/measurement.md). None without
    ``time.setup_s`` (an older record: not comparable). Where cold processes were timed
    (``time.processes.first_result``), their median and its interval."""
    several = across_processes(rec, "first_result")
    if several is not None:
        return several
    setup, first = (num(rec.time.setup_s), num(rec.time.first_call_s)) if rec.time else (None, None)
    if setup is None or first is None:
        return None
    v = setup + first
    return Timing(v, v, v, 1)


PROCESS_SPREAD = 0.10       # a median whose interval strays further than this is noisy


def process_count(rec: Record) -> int:
    """How many worker processes timed the record's cell (1 for a record without repeats)."""
    return rec.process_count


def across_processes(rec: Record, regime: str) -> Timing | None:
    """The regime's figure over several worker processes (``time.processes``; 'first' is the time
    to first result, set-up + first call), or None for a one-process record. The bounds are the
    median's interval; the figure is noisy where the interval strays more than PROCESS_SPREAD."""
    block = rec.time.processes.get(regime) if rec.time and rec.time.processes else None
    if not isinstance(block, Mapping):
        return None
    med, lo, hi = num(block.get("median_s")), num(block.get("ci_lo_s")), num(block.get("ci_hi_s"))
    if med is None or lo is None or hi is None or med <= 0:
        return None
    n = len(block.get("values") or ())
    cover = num(block.get("confidence")) or 0.0
    why = []
    if lo < (1 - PROCESS_SPREAD) * med or hi > (1 + PROCESS_SPREAD) * med:
        why.append(f"processes disagree: interval {100 * (lo / med - 1):+.0f} % to {100 * (hi / med - 1):+.0f} % "
                   "of the median")
    if cover < repeats.CONFIDENCE:
        why.append(f"{n} processes: interval at {100 * cover:.0f} % confidence")
    # an interval below the stated confidence (too few processes) separates nothing: the figure
    # is ranked as a one-process figure, its range kept for the page
    ci = (lo, hi) if cover >= repeats.CONFIDENCE else None
    return Timing(med, lo, hi, n, "; ".join(why), processes=n, ci=ci)


def per_call(rec: Record, regime: str) -> Timing | None:
    """Per-call time in ``regime``. A framework's own graph variant (a launch path its user
    writes, as JAX's XLA command buffers) counts in every regime like any variant, and its
    pipelined calls stand for the graph replay the harness cannot capture for it."""
    if regime == "graph" and rec.variant == "graph":
        return timing(rec, "throughput")
    return timing(rec, regime)


# The unit that travels between sittings (docs/results/h100/evidence/units): a per-call figure
# over its own run's empty-kernel launch (each record keeps its run's yardstick in ``hardware``);
# graph replay travels in seconds and has none.
FLOOR_OF = {"latency": "launch_latency_s", "throughput": "launch_pipelined_s"}
# A CUDA cell's own floor (``cell_floor``, compare.running.cell_floor) where the record has one:
# its ``before`` probe alone, not the mean with ``after``. ``before`` runs on the primary context
# before the cell's first kernel (before the framework's set-up, or at its window's opening), as
# the run's yardstick does; ``after`` runs on the framework's context after its regimes, so the
# framework's own state (its context and flags, its threads) would enter the divisor and flatter
# a framework that slows every launch. ``after`` stays in the record: how far the floor moved.
OWN_FLOOR_OF = {"latency": "latency_s", "throughput": "pipelined_s"}


def floor_of(rec: Record, regime: str) -> tuple[float, bool] | None:
    """The launch floor ``regime``'s per-call figure is divided by, and whether it is the cell's
    own (else its run's yardstick); None where the regime has no such unit or the record no floor."""
    key = FLOOR_OF.get(regime)
    before = rec.cell_floor.before if key and rec.cell_floor else None
    own = num(getattr(before, OWN_FLOOR_OF[regime], None)) if key and before else None
    run = num(getattr(rec.hardware, key, None)) if key and rec.hardware else None
    return (own, True) if own else (run, False) if run else None


def own_floor(rec: Record | None, regime: str) -> bool:
    """Whether ``rec``'s ``regime`` figure is divided by its cell's own floor (not its run's yardstick)."""
    got = floor_of(rec, regime) if rec is not None else None
    return bool(got and got[1])


def floors(rec: Record, regime: str, t: Timing | None = None) -> float | None:
    """``regime``'s per-call figure (``t``, else read here) in launch floors: the latency over the
    empty launch + synchronise, pipelined calls over the pipelined empty launch, of the cell's own
    floor where it has one, else of its run's yardstick (``floor_of``). None where the regime has
    no such unit or the record no floor (a CPU run, an older one)."""
    got = floor_of(rec, regime)
    t = t or per_call(rec, regime)
    return t.median / got[0] if t is not None and got else None


def defaults(scenario: str) -> dict[str, ParamValue]:
    sc = scenarios.SCENARIOS.get(scenario)
    return dataclasses.asdict(sc.params()) if sc is not None else {}


def at_defaults(rec: Record) -> bool:
    """The record ran the scenario at its default parameters (the README's default sizes)."""
    d = defaults(rec.scenario)
    p = rec.params or {}
    return all(p.get(k, v) == v for k, v in d.items())


def beyond_defaults(rec: Record) -> bool:
    """Larger than its scenario's default size: a row about large sizes never reads the default
    size (a store without a large part or sweep leaves that row empty, not the small row again)."""
    return size(rec) > _size(defaults(rec.scenario))


def size(rec: Record) -> float:
    """The record's problem size: n, batch or pixels, whichever the scenario has."""
    return _size(rec.params or {})


def _size(p: Mapping[str, Any]) -> float:
    for k in ("n", "batch"):
        if isinstance(p.get(k), (int, float)):
            return float(p[k])
    if isinstance(p.get("width"), int) and isinstance(p.get("height"), int):
        return float(p["width"] * p["height"])
    return 0.0


def device_bytes(rec: Record) -> float | None:
    """Device memory above the framework's context (NVML), the one metric every backend shares."""
    return num(rec.memory.device_bytes) if rec.memory else None


def item_rate(rec: Record, regime: str = "throughput") -> float | None:
    """Work items per second in ``regime`` (particle-steps, trajectory-gradients, elements)."""
    words = sweeps(rec.scenario).labels
    work = (rec.work or {}).get(words.get("rate_work", "items"))
    t = per_call(rec, regime) or timing(rec, "latency")
    w = num(work)
    return w / t.median if w is not None and t is not None else None


def hw_fraction(rec: Record) -> float | None:
    return num(rec.throughput.hw_fraction) if rec.throughput else None


# Where neither a record nor its run names the GPU's L2 size: a bound for the H100/H200 class
# (50 MB of L2 on both; 60 MB leaves room for what a working set's count of bytes leaves out).
L2_BOUND = {"H100": 60e6, "H200": 60e6}
L2_KEYS = ("l2_bytes", "l2_cache_bytes", "l2_cache_size")


def l2_bytes(rec: Record, runs: Iterable[RunEnvironment] = ()) -> tuple[float, str] | None:
    """The L2 cache of the record's GPU and where it was read: an L2 field of the record's
    yardstick, else of its run's environment (``hardware[device]`` or a GPU entry), else the
    stated bound for a GPU of a class in L2_BOUND by name. None off CUDA or where unknown."""
    if rec.device != "cuda":
        return None
    envs = [e for e in runs if isinstance(e, Mapping)]
    own = rec.hardware if isinstance(rec.hardware, Mapping) else {}
    places: list[Mapping[str, object]] = [own]     # a yardstick or a GPU entry: read by the L2 keys
    for e in envs:
        hw = e.get("hardware")
        places += [hw[rec.device]] if isinstance(hw, Mapping) and isinstance(hw.get(rec.device), Mapping) else []
        gpus = e.get("gpus")
        places += [g for g in gpus if isinstance(g, Mapping)] if isinstance(gpus, (list, tuple)) else []
    for place in places:
        for k in L2_KEYS:
            v = num(place.get(k))
            if v:
                return v, k
    names = [str(p.get("gpu") or p.get("name") or "") for p in places]
    for cls, bound in L2_BOUND.items():
        if any(cls in n for n in names):
            return bound, f"stated {bound / 1e6:.0f} MB bound for the {cls} class"
    return None


def fraction_label(rec: Record, runs: Iterable[RunEnvironment] = ()) -> str:
    """Why a hardware fraction is not a plain fraction of memory bandwidth: 'cache' where the
    working set (``work.bytes``) fits the GPU's L2, so it is served from cache, not from the
    DRAM the copy yardstick measures, and where it exceeds 1 on CUDA with no working set or L2
    known to say otherwise; 'above copy' where it exceeds 1 with a working set beyond the L2 (a
    read-heavier mix than the copy's) or on a CPU (judged against a copy of its own size already:
    docs/measurement.md); '' where the fraction stands as it is."""
    f = hw_fraction(rec)
    if f is None:
        return ""
    work = num((rec.work or {}).get("bytes"))
    l2 = l2_bytes(rec, runs)
    if l2 is not None and work is not None and work < l2[0]:
        return "cache"
    if f <= 1:
        return ""
    # above the copy: cache, unless the working set is known not to fit (or there is no GPU L2)
    beyond = l2 is not None and work is not None and work >= l2[0]
    return "above copy" if beyond or rec.device != "cuda" else "cache"


def scope(recs: list[Record]) -> str:
    """The sizes a row read, in words (``n = 268435456``)."""
    seen = []
    for r in recs:
        sc = r.scenario
        s = size(r)
        words = f"{sc} at defaults" if at_defaults(r) else f"{sc} {_size_words(r, s)}"
        if words not in seen:
            seen.append(words)
    return "; ".join(seen)


def _size_words(r: Record, s: float) -> str:
    p = r.params or {}
    k = "n" if "n" in p else "batch" if "batch" in p else "size"
    e = math.log2(s) if s > 0 else 0
    return f"{k} = 2^{e:.0f}" if s > 0 and e == int(e) else f"{k} = {s:g}"
