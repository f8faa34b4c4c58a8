"""What a results file must hold for every later step to read it: one validation, at load time.

Every record a reader gets (``report``, ``sweep report``, ``stress --merge``, ``--resume`` of every
suite, stress's own file and ``site``) and every record the engine stores is built by
``compare.results.record.Record.from_json``, which calls ``shape_problem`` and ``record_problem``;
``compare.results.store.Store.read`` adds ``store_problem`` for a file's runs and findings, before anything
is written. The first problem becomes one line naming the file, the record (or run, or finding)
and the field. Every field that a reader formats, compares, sorts, divides or indexes is checked
here for type and range; fields no reader looks at (``info``, ``versions``, a run's ``backends``)
pass through untouched. The stored format does not change: this module only refuses. It knows no
suite: a suite's own checks (what the sweep page indexes, what the stress page parses) belong to
its ``Format``, registered in ``compare.results.formats``, which ``Store.read`` applies after these.

A record's parameters are checked by its scenario (``Scenario.params``: the types and ranges a
run accepts), so a size no run could have used never reaches a reader. ``arrays_problem`` guards the
one path that allocates from a record's sizes, the pictures drawn from ``--save-arrays`` outputs:
the saved arrays must have the shapes the record's parameters declare, and the cell must fit in
the memory available, or the arrays are not used.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import re
from collections.abc import Callable, Mapping
from typing import Any

from compare.spec import STATUSES

# ---- the schema language ----------------------------------------------------------------------
Check = Callable[[Any], bool]


@dataclasses.dataclass(frozen=True)
class Leaf:
    what: str                       # in words, for the refusal: "a string", "a number >= 0"
    ok: Check


@dataclasses.dataclass(frozen=True)
class Obj:
    fields: Mapping[str, Node] = dataclasses.field(default_factory=dict)   # name -> node
    required: tuple[str, ...] = ()
    rest: Node | None = None        # the node of every other key (None: not read, anything goes)
    null: bool = True               # null may stand for the object (readers write `x or {}`)


@dataclasses.dataclass(frozen=True)
class Seq:
    item: Node
    null: bool = True


@dataclasses.dataclass(frozen=True)
class Either:
    what: str
    options: tuple[Node, ...]


Node = Leaf | Obj | Seq | Either      # a schema: what one JSON value must be


def _real(v: Any) -> bool:
    # a huge int overflows float() in a reader, or makes NumPy build an object array (a plot
    # fails); integers past 2^53 (exact in a float) have no use in a results file
    return isinstance(v, float) or (isinstance(v, int) and not isinstance(v, bool) and abs(v) <= 2**53)


def _finite(v: Any) -> bool:
    return _real(v) and math.isfinite(v)


def show(v: Any) -> str:
    """A value in a refusal: short, on one line."""
    if isinstance(v, dict):
        return "an object"
    if isinstance(v, list):
        return "a list"
    if isinstance(v, bool) or v is None:
        return {True: "true", False: "false", None: "null"}[v]
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


@functools.lru_cache(maxsize=4096)      # a store repeats its few keys in every record
def show_key(k: str) -> str:
    """A JSON object's key in a refusal (quoted where it is not a plain name)."""
    return k if re.fullmatch(r"[A-Za-z0-9_]{1,40}", k) else repr(k)[:40]


# Levels of objects and lists a stored block may nest: the stores hold at most 7, and every
# reader and writer recurses through them (Python stops near 1000, JSON's parser a little sooner).
MAX_DEPTH = 64


def too_deep(v: Any, limit: int = MAX_DEPTH) -> bool:
    """Whether ``v`` nests objects and lists more than ``limit`` levels (found without recursing)."""
    stack = [(v, 1)]
    while stack:
        x, depth = stack.pop()
        if isinstance(x, (dict, list, tuple)):
            if depth > limit:
                return True
            stack.extend((y, depth + 1) for y in (x.values() if isinstance(x, dict) else x))
    return False


def problem(node: Any, v: Any, where: str) -> str | None:
    """The first way ``v`` (found at ``where``) does not fit ``node``, or None."""
    if isinstance(node, Leaf):
        return None if node.ok(v) else f"{where} must be {node.what}, got {show(v)}"
    if isinstance(node, Either):
        found = []
        for o in node.options:         # the first option that fits ends it, no refusal worded
            if (p := problem(o, v, where)) is None:
                return None
            found.append(p)
        # a list or an object of the right kind: its own first problem says more
        same = [p for o, p in zip(node.options, found) if isinstance(o, Seq if isinstance(v, list) else Obj)]
        return same[0] if same and isinstance(v, (list, dict)) else f"{where} must be {node.what}, got {show(v)}"
    if v is None and node.null:
        return None
    if isinstance(node, Seq):
        if not isinstance(v, list):
            return f"{where} must be a list, got {show(v)}"
        for i, x in enumerate(v):
            if (p := problem(node.item, x, f"{where}[{i}]")) is not None:
                return p
        return None
    if not isinstance(v, dict):
        return f"{where} must be an object, got {show(v)}"
    for k in node.required:
        if k not in v:
            return f"{where}.{k} is missing"
    for k, x in v.items():
        sub = node.fields.get(k, node.rest)
        if sub is not None and (p := problem(sub, x, f"{where}.{show_key(k)}")) is not None:
            return p
    return None


# ---- leaves -----------------------------------------------------------------------------------
TEXT = Leaf("a string", lambda v: isinstance(v, str))
OPT_TEXT = Leaf("a string or null", lambda v: v is None or isinstance(v, str))
FLAG = Leaf("true, false or null", lambda v: v is None or isinstance(v, bool))
COUNT = Leaf("an integer >= 0", lambda v: isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 2**53)
OPT_COUNT = Leaf("an integer >= 0 or null", lambda v: v is None or COUNT.ok(v))
SECONDS = Leaf("a finite number >= 0", lambda v: _finite(v) and v >= 0)
OPT_SECONDS = Leaf("a finite number >= 0 or null", lambda v: v is None or SECONDS.ok(v))
POSITIVE = Leaf("a finite number > 0", lambda v: _finite(v) and v > 0)
OPT_POSITIVE = Leaf("a finite number > 0 or null", lambda v: v is None or POSITIVE.ok(v))
AMOUNT = Leaf("a finite number >= 0", SECONDS.ok)           # bytes, items, flops
OPT_AMOUNT = Leaf("a finite number >= 0 or null", OPT_SECONDS.ok)
OPT_NUMBER = Leaf("a finite number or null", lambda v: v is None or _finite(v))
# an error figure: non-finite floats are stored as the strings jsonable writes
FIGURE = Leaf("a number, 'nan', 'inf', '-inf' or null",
              lambda v: v is None or _real(v) or v in ("nan", "inf", "-inf"))
SCALAR = Leaf("a string, number, boolean or null", lambda v: v is None or isinstance(v, (str, bool)) or _real(v))
FIGURES = Either("a figure or a list of figures", (FIGURE, Seq(FIGURE)))

# ---- a record ---------------------------------------------------------------------------------
REGIME = Obj({"median_s": OPT_SECONDS, "iqr_s": OPT_SECONDS, "min_s": OPT_SECONDS, "repeats": OPT_COUNT,
              "k": OPT_COUNT, "host_s": OPT_SECONDS, "how": TEXT, "failed": TEXT, "unavailable": TEXT,
              "same_as": TEXT})
THROUGHPUT = Obj({**REGIME.fields, "median_s": SECONDS}, ("median_s",))
TIME = Obj({"first_call_s": SECONDS, "median_s": POSITIVE, "iqr_s": SECONDS, "min_s": SECONDS, "repeats": COUNT,
            "warmup": COUNT, "timed_total_s": SECONDS, "setup_s": OPT_SECONDS, "download_s": OPT_SECONDS,
            "timer": TEXT, "clock": TEXT, "cache": TEXT, "first_call_clock": TEXT,
            "window": Seq(SECONDS),       # epoch seconds the cell's timed window opened and closed
            "wall": Obj({"median_s": POSITIVE, "iqr_s": SECONDS, "min_s": SECONDS},
                        ("median_s", "iqr_s", "min_s")),
            # the yardstick judges a throughput regime by its median (compare.running.hardware.annotate)
            "latency": REGIME, "throughput": THROUGHPUT, "graph": REGIME, "null": REGIME,
            "events": Obj({**REGIME.fields, "clock": TEXT}), "events_error": TEXT,
            "own_timer": Obj({"tool": TEXT, "median_s": OPT_SECONDS, "calls": OPT_COUNT, "failed": TEXT,
                              "ours_s": OPT_SECONDS, "rounds": OPT_COUNT, "block": OPT_COUNT,
                              "ours_call_s": OPT_SECONDS, "ratio": OPT_POSITIVE}),
            # the cell's figures over several worker processes (compare.running.repeats)
            "processes": Obj({"count": COUNT, "order": TEXT, "interval": TEXT, "failed": COUNT, "capped": TEXT},
                             rest=Obj({"values": Seq(POSITIVE, null=False), "median_s": POSITIVE,
                                       "ci_lo_s": POSITIVE, "ci_hi_s": POSITIVE, "confidence": SECONDS},
                                      ("values", "median_s", "ci_lo_s", "ci_hi_s", "confidence"))),
            "noise": Obj({"noisy": FLAG, "cores": OPT_COUNT, "measured_s": OPT_SECONDS, "own_cores": OPT_SECONDS,
                          "others_cores": OPT_SECONDS,
                          "reasons": Seq(Obj({"regime": TEXT, "why": TEXT}, ("regime", "why"), null=False))})},
           ("first_call_s", "median_s", "iqr_s", "min_s", "repeats"))
ERROR = Obj({"vs_oracle": FIGURE, "tolerance": FIGURE, "vs_reference": FIGURE, "reference": TEXT,
             "vs_reference_device": TEXT, "metric": TEXT, "checked_items": TEXT, "ill_conditioned": COUNT})
# a checked cell's block (compare/running/worker.py writes both figures for every ok or mismatch record)
CHECKED = Leaf("a number, 'nan', 'inf' or '-inf'", lambda v: v is not None and FIGURE.ok(v))
CHECKED_ERROR = Obj({**ERROR.fields, "vs_oracle": CHECKED, "tolerance": CHECKED}, ("vs_oracle", "tolerance"),
                    null=False)
HARDWARE = Obj({"copy_bytes_per_s": POSITIVE, "copy_how": TEXT, "launch_latency_s": OPT_SECONDS,
                "launch_pipelined_s": OPT_SECONDS, "gpu": TEXT, "copy_bytes": OPT_AMOUNT,
                "copy_median_s": OPT_SECONDS, "error": TEXT})
# a CUDA cell's own launch floor (compare.running.cell_floor): its probes before and after the regimes
PROBE = Obj({"latency_s": OPT_SECONDS, "latency_iqr_s": OPT_SECONDS, "pipelined_s": OPT_SECONDS,
             "launches": OPT_COUNT, "k": OPT_COUNT, "batches": OPT_COUNT, "spent_s": OPT_SECONDS,
             "context": OPT_TEXT, "error": OPT_TEXT})
RECORD = Obj({
    "reason": TEXT, "params": Obj(), "time": TIME, "error": ERROR,
    "tags": Obj({"sweep": OPT_TEXT, "role": OPT_TEXT,
                 "knob": Obj({"name": OPT_TEXT, "value": OPT_POSITIVE})}, rest=SCALAR),
    "work": Obj(rest=AMOUNT),
    "throughput": Obj({"hw_fraction": OPT_NUMBER, "floor_s": OPT_SECONDS, "floor_kind": TEXT, "floor": TEXT},
                      rest=Either("a number, a string or null", (OPT_NUMBER, TEXT))),
    "memory": Obj(rest=Either("a finite number, a string or null", (OPT_NUMBER, TEXT))),   # deltas may be < 0
    "gradient": Obj({"method": TEXT, "reference": OPT_TEXT, "vs_oracle_rel": FIGURE, "vs_fd64_rel": FIGURE,
                     "vs_oracle": FIGURE, "fd_agreement": FIGURE, "fd_resolved": FIGURE, "value": FIGURES,
                     "reference_value": FIGURES, "tolerance": FIGURES}),
    "converged": Obj({"error": FIGURE, "metric": TEXT, "reference": Obj(rest=SCALAR, null=False)},
                     ("error", "metric")),
    "hardware": HARDWARE, "cell_floor": Obj({"before": PROBE, "after": PROBE, "how": OPT_TEXT}),
    "info": Obj(), "versions": Obj(),
    "host": OPT_TEXT, "host_load_1m": OPT_NUMBER, "host_cores": OPT_COUNT, "machine": OPT_TEXT,
    "run": Obj({"created": TEXT, "commit": OPT_TEXT, "dirty": FLAG, "note": TEXT, "noisy_sitting": FLAG},
               ("created",)),
    "traceback": TEXT})


def shape_problem(rec: Any) -> str | None:
    """The first way ``rec`` is not a record at all (an object with string names, a known status,
    objects where objects belong), or None: what an older format's upgrade may rely on."""
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
                 "gradient", "converged", "cell_floor")
NUMBER_FIELDS = {"time": ("first_call_s", "median_s", "iqr_s", "min_s"),
                 "error": ("vs_oracle", "tolerance", "vs_reference")}


def _number(v: Any) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)) or v in ("nan", "inf", "-inf")


# identity: names that go into paths, keys and colours; the scenario and precision by registry
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,63}")


def record_problem(rec: dict[str, Any]) -> str | None:     # a stored record's JSON, as loaded
    """The first field of a record (already of the basic shape, ``shape_problem``) that a later
    step could not read, as 'FIELD must be ...', or None."""
    import scenarios
    from scenarios.base import PRECISIONS, ParamError
    for f in ("backend", "device", "variant"):
        if f in rec and not (isinstance(rec[f], str) and NAME.fullmatch(rec[f])):
            return f"{f} must be a name of letters, digits and _.+- (at most 64), got {show(rec[f])}"
    if rec["scenario"] not in scenarios.SCENARIOS:
        return f"scenario {show(rec['scenario'])} is not one this tool knows ({', '.join(scenarios.SCENARIOS)})"
    if rec["precision"] not in PRECISIONS:
        return f"precision must be one of {', '.join(PRECISIONS)}, got {show(rec['precision'])}"
    if (p := problem(RECORD, rec, "record")) is not None:
        return p.removeprefix("record.")
    sc = scenarios.get(rec["scenario"])
    known = {f.name for f in dataclasses.fields(sc.Params)}
    try:        # types and ranges as a run would have accepted them; a name the scenario lacks is
        # resolved by nothing but the array path, which refuses it (arrays_problem)
        sc.params({k: v for k, v in (rec.get("params") or {}).items() if k in known})
    except ParamError as exc:
        return f"params: {exc}"
    if rec["status"] in ("ok", "mismatch") and not isinstance(rec.get("params"), dict):
        return f"a {rec['status']} record needs its params (the cell's parameters)"
    if rec["status"] in ("ok", "mismatch") and (rec.get("time") is None) != (rec.get("error") is None):
        # a measured cell carries both; a placeholder (every reader skips it) neither
        only = "time" if rec.get("time") is not None else "error"
        return f"a {rec['status']} record needs both time and error (or neither), got only {only}"
    if rec["status"] in ("ok", "mismatch") and rec.get("error") is not None:
        if (p := problem(CHECKED_ERROR, rec["error"], "error")) is not None:
            return f"{p} (a checked {rec['status']} record holds its distance to the oracle and the tolerance)"
    knob = (rec.get("tags") or {}).get("knob") or {}
    if knob.get("value") is not None and knob.get("name") is None:
        return "tags.knob.name must be a string where tags.knob.value is set"
    return None


# ---- runs (environments) and a suite's analysis -----------------------------------------------
RUN = Obj({
    "created": OPT_TEXT, "hostname": OPT_TEXT, "os": OPT_TEXT, "cpu": OPT_TEXT, "cpu_id": OPT_TEXT, "python": OPT_TEXT,
    "cuda_toolkit": OPT_TEXT, "command": OPT_TEXT, "git_commit": OPT_TEXT, "git_note": OPT_TEXT,
    "git_dirty": FLAG, "git_dirty_paths": Seq(TEXT, null=False), "cores": OPT_COUNT, "memory_gib": OPT_AMOUNT,
    # readers write env.get("gpus", []) and index a GPU's three names: present means a list
    "gpus": Seq(Obj({"name": TEXT, "driver": TEXT, "memory": TEXT}, ("name", "driver", "memory"), null=False),
                null=False),
    "packages": Obj(rest=TEXT, null=False), "hardware": Obj(rest=HARDWARE), "merged_from": Seq(TEXT, null=False),
    "backends": Obj(), "scheduler": Obj(), "kinds": Seq(TEXT),
    "sitting": Obj({"start": Obj(), "end": Obj(), "quiet": Obj()}), "noisy_sitting": FLAG,
    "noisy_sitting_reasons": Seq(TEXT, null=False)}, null=False)
# a merged report's entry holds the runs it merged (its header shows each): runs, checked alike
RUN.fields["environments"] = Seq(RUN)     # type: ignore[index]
ROW_FIELDS = ("experiment", "backend", "device", "precision", "setting", "figure", "value", "verdict", "detail")
ROW = Obj({**{k: TEXT for k in ROW_FIELDS}, "value": SCALAR}, ROW_FIELDS, null=False)
PROVENANCE_RUN = Obj({"command": OPT_TEXT, "created": OPT_TEXT, "git_commit": OPT_TEXT, "git_dirty": FLAG,
                      "backends": Seq(TEXT, null=False), "noisy_sitting": FLAG}, null=False)
ANALYSIS = Obj({"rows": Seq(ROW, null=False), "series": Obj(null=False),
                "provenance": Obj(rest=Either("a run (command, created, git_commit) or a list of runs",
                                              (PROVENANCE_RUN, Seq(PROVENANCE_RUN, null=False))), null=False)},
               null=False)


def store_problem(data: dict[str, Any]) -> str | None:     # a stored file's JSON, as loaded
    """The first problem of a parsed file's ``runs`` and ``analysis`` (its records are checked one
    by one as they load, ``compare.results.record.Record.from_json``), as 'runs[0].cores must be ...', or
    None."""
    for where, block in [*((f"runs[{i}]", env) for i, env in enumerate(data["runs"])), ("analysis", data["analysis"])]:
        if too_deep(block):             # first: the checks below recurse
            return f"{where} is nested more than {MAX_DEPTH} levels deep"
    for i, env in enumerate(data["runs"]):
        if (p := problem(RUN, env, f"runs[{i}]")) is not None:
            return p
    if (p := problem(ANALYSIS, data["analysis"], "analysis")) is not None:
        return p
    return None


# ---- a suite's format ------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Format:
    """A suite's results file: its name, the upgrade of a format-1 record to today's shape, and
    the suite's own checks on top of this module's (registered in ``compare.results.formats``)."""
    suite: str
    file: str
    upgrade: Callable[[dict[str, Any]], dict[str, Any]] | None = None   # stored JSON, older -> newer
    record_problem: Callable[[dict[str, Any]], str | None] | None = None   # one record, as loaded
    store_problem: Callable[[dict[str, Any]], str | None] | None = None    # the file's runs and analysis


# ---- saved arrays -----------------------------------------------------------------------------
def arrays_problem(rec: Mapping[str, Any], headers: dict[str, tuple[tuple[int, ...], int]]) -> str | None:  # stored JSON
    """Why the saved arrays (name -> (shape, bytes), read from their headers) of a loaded record
    must not be used, or None: a picture or distance drawn from them allocates by the record's
    parameters, so the shapes must be the ones those parameters declare and the cell must fit in
    the memory available now."""
    import psutil
    import scenarios
    if "params" not in rec:      # a cell named by hand; a loaded ok or mismatch record has them
        return None
    sc = scenarios.get(rec["scenario"])
    p = sc.params(rec["params"] or {})
    want = sc.output_shapes(p)
    for name, (shape, _) in headers.items():
        w = want.get(name)
        if w is not None and tuple(w) != shape:
            return f"{name} has shape {shape}, the parameters declare {tuple(w)}"
    need = max(sc.footprint(p, rec["precision"], rec["device"]), sc.output_bytes(p, rec["precision"]))
    if sum(b for _, b in headers.values()) > max(need, 1 << 20):
        return "the arrays are larger than the cell's declared footprint"
    if need > psutil.virtual_memory().available:
        return "the cell needs more memory than is available"
    return None


__all__ = ["Format", "arrays_problem", "problem", "record_problem", "shape_problem", "show", "store_problem"]
