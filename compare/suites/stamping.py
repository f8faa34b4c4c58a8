"""One-off (issue 57 item 4): stamp the published sweep and stress records that were stored before
those suites stamped their records, from the evidence their stores already keep. Run once::

    python -c "from compare.suites import stamping; stamping.main()"

The rule. A record's candidate runs are the run environments of its store (``runs``, a merged
entry's ``environments`` flattened). A run stays a candidate only where every piece of evidence
the store holds for the pair agrees:

* selection: the run's own command selects the record: ``--devices``, ``--backends`` (absent or
  ``all``: any), for a sweep its kind (``tags.sweep``), ``--scenarios`` and ``--precision``;
  where the run kept its probes (``backends``), it probed the record's backend;
* yardstick: a record judged against its run's yardstick (``hardware``) was judged against this
  run's: the same measured copy bandwidth and launch latency (measured floats agree only within
  one run);
* time: a record whose timed window opened at ``time.window`` comes from a run that had started
  by then and, where the store's publish log (``publish.json``) holds the run's part, whose part
  was still running when the window closed; a run of a commit before windows were recorded
  (``WINDOW_SINCE``) wrote none, one after always did (a timed record without one is not its);
* stress rows: the run gave rows of the record's backend (``analysis.provenance``) in an
  experiment that makes this cell (the experiment's own cases, ``compare.stress``: its scenario,
  parameters, precision and variant; with the run's ``--quick``), and its ``--only`` names it.

Exactly one candidate left: the record gets that run's stamp (``run_stamp``). None or several:
the explicit unknown stamp (``compare.results.stamps.unknown_stamp``) naming the candidates.
Records that already carry a stamp are kept as they are.
"""
from __future__ import annotations

import dataclasses
import datetime
import functools
import json
import re
import shlex
import subprocess
from pathlib import Path
from typing import Any, Callable, Mapping

import backends
import scenarios
from compare.measuring.environment import run_stamp
from compare.results.environment import RunEnvironment
from compare.results.record import Record, plain
from compare.results.stamps import flat_runs, is_unknown, names_a_run, unknown_stamp
from compare.results.store import Store
from compare.stress.projectile import lr_grid
from compare.stress.projectile_rules import CONTACTS
from compare.stress.ulp_cases import ulp_cases

ROOT = Path(__file__).resolve().parents[2]
# the commit that began recording each timed cell's window (time.window): a run of a commit
# without it wrote no window, a run of one with it wrote one on every timed record
WINDOW_SINCE = "dbc8b66"
Capability = Callable[[str | None], bool | None]     # a commit -> whether its records have windows


# ---- evidence ----------------------------------------------------------------------------------
def epoch(text: object) -> float | None:
    """An ISO time with its zone as epoch seconds; None for anything else ("2026-11-21 (session 1)")."""
    try:
        t = datetime.datetime.fromisoformat(str(text))
    except ValueError:
        return None
    return t.timestamp() if t.tzinfo is not None else None


def options_of(command: object) -> dict[str, str]:
    """A run's command line as option -> value (the words after ``compare`` under "_kind")."""
    try:
        words = shlex.split(str(command or ""))
    except ValueError:
        return {}
    out = {w: words[i + 1] for i, w in enumerate(words[:-1]) if w.startswith("--") and not words[i + 1].startswith("--")}
    out.update({w: "" for w in words if w in ("--quick",)})
    if "sweep" in words and words.index("sweep") + 1 < len(words):
        out["_kind"] = words[words.index("sweep") + 1]
    return out


def selects(opts: dict[str, str], name: str, value: str) -> bool:
    given = opts.get(name)
    return given is None or given == "all" or value in given.split(",")


def publish_parts(folder: Path) -> list[tuple[str, float, float]]:
    """(command, start, end) of every part in the folder's publish log (``publish.json``)."""
    log = folder / "publish.json"
    if not log.is_file():
        return []
    out = []
    for p in json.loads(log.read_text()).get("parts", []):
        start = epoch(p.get("started"))
        if start is not None and isinstance(p.get("seconds"), (int, float)):
            out.append(("python -m compare " + " ".join(p["argv"]), start, start + float(p["seconds"])))
    return out


def git_capability(since: str = WINDOW_SINCE, root: Path = ROOT) -> Capability:
    """Whether a commit's records carry ``time.window``: ``since`` is its ancestor (None: unknown)."""
    @functools.lru_cache(maxsize=None)
    def has(commit: str | None) -> bool | None:
        if not commit:
            return None
        rc = subprocess.run(["git", "-C", str(root), "merge-base", "--is-ancestor", since, commit],
                            capture_output=True).returncode
        return {0: True, 1: False}.get(rc)
    return has


# ---- the stress experiments' cells (compare/stress: particles.py, projectile.py, generic.py) ----
def resolved(scenario: str, overrides: dict[str, Any]) -> dict[str, Any]:
    return dataclasses.asdict(scenarios.get(scenario).params(overrides))


def experiments_of(rec: Record, quick: bool) -> set[str]:
    """The experiments whose cases include this cell (scenario, parameters, precision, variant)."""
    prm, prec, var, sc = plain(rec.params) or {}, str(rec.precision), rec.variant, rec.scenario
    both = ("float32",) if quick else ("float32", "float64")
    found = set()

    def case(name: str, overrides: Mapping[str, Any], precisions: tuple[str, ...], variants: bool = False) -> None:
        if prec in precisions and (variants or var == "default") and prm == resolved(sc, dict(overrides)):
            found.add(name)
    if sc == "particles":
        for dt in (0.02, 0.005, 0.001) if quick else (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005):
            case("particles-dt", {"n": 256, "steps": int(round(3.0 / dt)), "dt": dt}, both)
        for bo in (0.82, 1.05) if quick else (0.82, 0.99, 1.05):
            for st in (10_000,) if quick else (1000, 10_000, 100_000):
                case("particles-long", {"n": 256, "steps": st, "bounce": bo}, both)
        if isinstance(prm.get("steps"), int):
            case("particles-inf", {"n": 256, "bounce": 1.05, "steps": prm["steps"]}, ("float32", "float64"), True)
        for bo in (0.99,) if quick else (0.82, 0.99):
            case("particles-divergence", {"n": 256, "steps": 1000 if quick else 5000, "record_every": 1,
                                          "bounce": bo}, ("float32", "float64"))
    if sc == "projectile":
        iters = scenarios.get(sc).params({}, quick=quick).iters
        for c in CONTACTS:
            for lr in lr_grid(quick):
                case("projectile-lr", {"contact": c, "lr": lr, "iters": iters}, ("float32",))
            case("projectile-gradient", {"contact": c, "iters": 0}, both)
            for n in (90, 180, 720) if quick else (45, 90, 180, 360, 720, 1440):
                case("projectile-horizon", {"contact": c, "steps": n, "iters": 0}, ("float32",))
    for over, _, _ in ulp_cases(sc, quick):
        case("ulps", over, ("float32",), True)
    s = scenarios.get(sc)
    if s.in_all:
        p = s.params({}, quick=True)
        over = {k: getattr(p, k) for k in s.quick}
        case("races", over, both)
        if var in backends.get(rec.backend).control_variants.get(sc, {}):
            case("races", over, ("float32",), True)
    return found


# ---- matching -----------------------------------------------------------------------------------
@dataclasses.dataclass
class Evidence:
    """What a store (and its folder) keeps about its runs."""
    runs: list[RunEnvironment]
    parts: list[tuple[str, float, float]]
    windows: Capability
    provenance: dict[str, list[dict[str, Any]]]      # stress: experiment -> the runs that gave rows

    rows: list[Mapping[str, Any]]                    # stress: the findings

    def part_of(self, env: RunEnvironment) -> tuple[float, float] | None:
        """The run's part in the publish log: its start and end (the log's start is to the second)."""
        start = epoch(env.get("created"))
        spans = [(a, b + 1) for cmd, a, b in self.parts if cmd == env.get("command") and start is not None
                 and a <= start <= b + 1]
        return spans[0] if len(spans) == 1 else None

    def searched(self, rec: Record) -> set[int] | None:
        """The steps the particles-inf row of the record's backend, device, precision and variant
        says its search ran ("located with N cells at steps [...]"), or None where it says none."""
        setting = "bounce=1.05, n=256" + ("" if rec.variant == "default" else f", variant={rec.variant}")
        for r in self.rows:
            if (r.get("experiment"), r.get("backend"), r.get("device"), r.get("precision"), r.get("setting")) == \
                    ("particles-inf", rec.backend, rec.device, str(rec.precision), setting):
                m = re.search(r"at steps \[([\d, ]*)\]", str(r.get("detail")))
                return {int(x) for x in m.group(1).split(",") if x.strip()} if m else None
        return None


def evidence(store: Store, windows: Capability) -> Evidence:
    seen: dict[tuple[object, object], RunEnvironment] = {}
    for e in flat_runs(store.runs):
        seen.setdefault((e.get("created"), e.get("command")), e)
    prov = {k: v if isinstance(v, list) else [v] for k, v in (store.analysis.get("provenance") or {}).items()}
    return Evidence(list(seen.values()), publish_parts(store.path.parent), windows, prov,   # type: ignore[arg-type]
                    [dict(r) for r in store.analysis.get("rows") or []])


def consistent(rec: Record, env: RunEnvironment, ev: Evidence, suite: str) -> bool:
    """Whether every piece of evidence the store keeps allows ``env`` to have measured ``rec``."""
    opts = options_of(env.get("command"))
    if not (selects(opts, "--devices", rec.device) and selects(opts, "--backends", rec.backend)):
        return False
    if env.get("backends") and rec.backend not in (env.get("backends") or {}):
        return False
    if suite == "sweep" and (opts.get("_kind") != (rec.tags or {}).get("sweep") or not selects(opts, "--scenarios", rec.scenario)
                             or not selects(opts, "--precision", str(rec.precision))):
        return False
    if rec.hardware is not None:
        hw = (env.get("hardware") or {}).get(rec.device) or {}
        if any(hw.get(k) != rec.hardware.get(k) for k in ("copy_bytes_per_s", "launch_latency_s")):
            return False
    window = rec.time.get("window") if rec.time is not None else None
    writes = ev.windows(env.get("git_commit"))
    if window:
        start, span = epoch(env.get("created")), ev.part_of(env)
        if writes is False or start is None or start > window[0] or (span and not span[0] <= window[0] <= window[1] <= span[1]):
            return False
    elif rec.time is not None and writes is True:
        return False
    if suite == "stress":
        made = experiments_of(rec, "--quick" in opts)
        gave = {e for e, runs in ev.provenance.items() for r in runs
                if (r.get("created"), r.get("command")) == (env.get("created"), env.get("command"))
                and rec.backend in r.get("backends", [rec.backend])}
        if "particles-inf" in gave and (steps := ev.searched(rec)) is not None and (rec.params or {}).get("steps") not in steps:
            gave.discard("particles-inf")       # the row of this run's search lists the steps it ran
        if not (made & gave) or not any(selects(opts, "--only", e) for e in made & gave):
            return False
    return True


def restamp(store: Store, windows: Capability) -> tuple[int, int, int]:
    """Stamp the store's unstamped records by the rule above (in place); (kept, stamped, unknown)."""
    ev = evidence(store, windows)
    kept = stamped = unknown = 0
    for rec in store.records:
        if names_a_run(rec, store.runs) or is_unknown(rec.run):
            kept += 1
            continue
        found = [e for e in ev.runs if consistent(rec, e, ev, store.suite)]
        if len(found) == 1:
            store.put(rec.replace(run=dict(run_stamp(found[0]))))
            stamped += 1
        else:
            which = "; ".join(f"{e.get('created')} ({e.get('git_commit') or '?'})" for e in found)
            why = (f"the store's evidence allows {len(found)} of its runs: {which}" if found else
                   "no run of the store agrees with the record's evidence")
            store.put(rec.replace(run=unknown_stamp(why)))
            unknown += 1
    return kept, stamped, unknown


def main(root: Path = ROOT) -> dict[str, tuple[int, int, int]]:
    """Restamp every published sweep and stress store in place (docs/results/*/ and one level
    below); prints and returns (kept, stamped, unknown) per store."""
    counts = {}
    windows = git_capability(root=root)
    for path in sorted({*root.glob("docs/results/*/sweep.json"), *root.glob("docs/results/*/stress.json"),
                        *root.glob("docs/results/*/*/sweep.json")}):
        store = Store.read(path)
        counts[str(path.relative_to(root))] = got = restamp(store, windows)
        if got[1] or got[2]:
            store.save()
        print(f"{path.relative_to(root)}: {got[0]} kept, {got[1]} stamped, {got[2]} run unknown")
    return counts


__all__ = ["experiments_of", "main", "restamp"]
