"""Which unit makes an H100 per-call figure travel between sittings (issue 57 item 2).

Reads every stored H100 run of the per-call cells (SAXPY n = 10^6 and particles at their defaults,
float32, CUDA): the published store and every evidence store. One figure per (run, cell); a run
stored twice (published and in its evidence folder) counts once. For every pair of runs that
measured the same cell it compares the figure in each candidate unit: the pair's ratio (larger
over smaller) and the share of pairs within 10 % and 20 %. "/ the cell's own floor" divides by the
launch floor probed in the cell's own worker (``cell_floor``); records before it carry none, so
those rows count no pairs until such runs are stored. Pairs from one machine session (runs
less than SESSION apart) are reported apart from pairs across sessions, the case that matters.

    python docs/results/h100/evidence/units/travel.py        (from the repository root)
"""
from __future__ import annotations

import functools
import itertools
import statistics
import subprocess
import sys
from datetime import datetime
from pathlib import Path
from typing import Any, Callable, Mapping, cast

ROOT = Path(__file__).resolve().parents[5]
sys.path.insert(0, str(ROOT))

from compare.results.record import Record  # noqa: E402
from compare.results.store import Store  # noqa: E402
from compare.site import data  # noqa: E402

H100 = ROOT / "docs" / "results" / "h100"
SESSION = 3600.0     # runs closer than this (seconds) sat on one machine

SHORT: set[str] = set()      # runs of one `compare run` (minutes: the yardstick just before the cells)
Fig = dict[str, float]           # what one record gives a candidate: regime figures and yardsticks


def stores() -> list[Path]:
    return [H100 / "results.json", H100 / "rerun" / "results.json",
            *sorted((H100 / "evidence").glob("**/results.json"))]


Cells = dict[tuple[str, str, str], dict[str, tuple[float, str, Fig]]]


def figures() -> Cells:
    """cell -> {run: (its start in seconds, its code's fingerprint, its figures)}."""
    out: Cells = {}
    for path in stores():
        store = Store.read(path)
        for r in store.records:
            if not (r.status == "ok" and r.device == "cuda" and r.precision == "float32"
                    and r.scenario in ("saxpy", "particles") and data.at_defaults(r) and r.hardware):
                continue
            f = _figs(r)
            if f is None:
                continue
            env = _run_of(r, store.runs, f)
            created = str(env.get("created") or "")
            run = created or f"{path}:{f['floor_lat']}:{f['floor_pipe']}"
            start = datetime.fromisoformat(created).timestamp() if created else 0.0
            code = _code(r, env)
            if " compare run " in str(env.get("command") or ""):
                SHORT.add(run)
            out.setdefault((r.scenario, r.backend, r.variant), {}).setdefault(run, (start, code, f))
    return out


def _run_of(r: Record, runs: Any, f: Fig) -> Mapping[str, Any]:
    """The run entry that made ``r``: named by its stamp, else (an older record) the one whose
    yardstick it carries."""
    stamp = (r.run or {}).get("created")
    for env in runs:
        hw = ((env.get("hardware") or {}).get("cuda") or {})
        if (stamp and env.get("created") == stamp) or (not stamp and hw.get("launch_latency_s") == f["floor_lat"]
                                                       and hw.get("launch_pipelined_s") == f["floor_pipe"]):
            return cast(Mapping[str, Any], env)
    return {}


# what makes a cell's figure: its port and the harness that times it (a scenario file's or the
# backends' base's edits of these months touched checks and words, not the timed call)
CODE = ("backends/{fw}/{sc}.py", "compare/measuring/timing.py", "compare/running/worker.py")


def _code(r: Record, env: Mapping[str, Any]) -> str:
    """The blobs of the files that make the cell's figure (its port, the timing harness) at the
    run's commit; '' where the tree was dirty or its state or commit unknown."""
    commit = env.get("git_commit")
    if not commit or env.get("git_dirty") is not False:
        return ""
    blobs = []
    for path in CODE:
        p = path.format(fw=r.backend, sc=r.scenario)
        blobs.append(_blob(str(commit), p))
    return ",".join(blobs)


@functools.lru_cache(maxsize=None)
def _blob(commit: str, path: str) -> str:
    res = subprocess.run(["git", "-C", str(ROOT), "rev-parse", f"{commit}:{path}"], capture_output=True, text=True)
    return res.stdout.strip() if res.returncode == 0 else "-"


def _figs(r: Record) -> Fig | None:
    hw = r.hardware
    lat, pipe = data.num(hw.launch_latency_s), data.num(hw.launch_pipelined_s)
    if not lat or not pipe:
        return None
    f: Fig = {"floor_lat": lat, "floor_pipe": pipe}
    for g in data.REGIMES:
        t = data.per_call(r, g)
        if t is not None:
            f[g] = t.median
    null = r.time.null if r.time else None
    if null and data.num(null.get("median_s")):
        f["null"] = float(null["median_s"])
    # the cell's own floor (``cell_floor``, probed in its worker beside its timed window) where the
    # record has one: its ``before`` probe (the site's divisor) and the mean with ``after``
    before, after = (r.cell_floor.before, r.cell_floor.after) if r.cell_floor else (None, None)
    for key, field in (("cell_lat", "latency_s"), ("cell_pipe", "pipelined_s")):
        b, a = (data.num(p.get(field)) if p else None for p in (before, after))
        if b:
            f[key] = b
        if b and a:
            f[key + "_mean"] = (b + a) / 2
    return f


# candidate units: figure of one record -> the number that should travel (None: not defined)
def _div(regime: str, by: str) -> Callable[[Fig], float | None]:
    return lambda f: f[regime] / f[by] if regime in f and by in f else None


def _minus(regime: str, by: str) -> Callable[[Fig], float | None]:
    return lambda f: f[regime] - f[by] if regime in f and f[regime] > f[by] else None


CANDIDATES: dict[str, list[tuple[str, Callable[[Fig], float | None]]]] = {
    "latency": [("raw us", lambda f: f.get("latency")),
                ("/ launch + sync floor", _div("latency", "floor_lat")),
                ("/ pipelined floor", _div("latency", "floor_pipe")),
                ("/ null call", _div("latency", "null")),
                ("- launch + sync floor", _minus("latency", "floor_lat")),
                ("/ the cell's own floor", _div("latency", "cell_lat")),
                ("/ the cell's own floor (mean of before, after)", _div("latency", "cell_lat_mean"))],
    "throughput": [("raw us", lambda f: f.get("throughput")),
                   ("/ pipelined floor", _div("throughput", "floor_pipe")),
                   ("/ launch + sync floor", _div("throughput", "floor_lat")),
                   ("/ sqrt(both floors)", lambda f: f["throughput"] / (f["floor_lat"] * f["floor_pipe"]) ** 0.5
                    if "throughput" in f else None),
                   ("/ null call", _div("throughput", "null")),
                   ("- pipelined floor", _minus("throughput", "floor_pipe")),
                   ("/ own latency", _div("throughput", "latency")),
                   ("/ the cell's own floor", _div("throughput", "cell_pipe")),
                   ("/ the cell's own floor (mean of before, after)", _div("throughput", "cell_pipe_mean"))],
    "graph": [("raw us", lambda f: f.get("graph")),
              ("/ pipelined floor", _div("graph", "floor_pipe")),
              ("/ launch + sync floor", _div("graph", "floor_lat"))],
}


def _reference(cells: Cells) -> None:
    """A per-run reference cell: CuPy's default of the same scenario and run (its own figure is 1)."""
    for (sc, fw, var), runs in cells.items():
        ref = cells.get((sc, "cupy", "default"), {})
        for run, (_, _, f) in runs.items():
            if run in ref and "throughput" in ref[run][2]:
                f["ref_thr"] = ref[run][2]["throughput"]
    CANDIDATES["throughput"].append(("/ same run's CuPy default", _div("throughput", "ref_thr")))


def pairs(cells: Cells, fn: Callable[[Fig], float | None], across: bool, same_code: bool,
          short: bool = False) -> list[float]:
    """Larger over smaller of ``fn`` for every pair of runs of one cell; ``across``: pairs across
    sessions (else within one); ``same_code``: only pairs whose port and timing harness were the
    same committed files; ``short``: only pairs of two `compare run` runs."""
    out = []
    for runs in cells.values():
        for (ra, (sa, ca, fa)), (rb, (sb, cb, fb)) in itertools.combinations(runs.items(), 2):
            if (abs(sa - sb) >= SESSION) != across or (same_code and not (ca and ca == cb)) \
                    or (short and not {ra, rb} <= SHORT):
                continue
            a, b = fn(fa), fn(fb)
            if a and b and a > 0 and b > 0:
                out.append(max(a, b) / min(a, b))
    return out


def summary(ratios: list[float]) -> str:
    if not ratios:
        return "| - | - | - | 0 |"
    within = lambda x: sum(r <= x for r in ratios) / len(ratios)  # noqa: E731
    return (f"| {statistics.median(ratios):.3f}x | {100 * within(1.10):.0f} % | {100 * within(1.20):.0f} % "
            f"| {len(ratios)} |")


def main() -> None:
    cells = figures()
    _reference(cells)
    nruns = len({run for runs in cells.values() for run in runs})
    print(f"{len(cells)} cells, {nruns} runs; pairs of runs of one cell. Ratio: larger / smaller "
          f"(1 = the same figure in both sittings).\n")
    scopes = (("across sessions (runs >= 1 h apart), the same code", True, True, False),
              ("across sessions, any code (ports and harness changed between them)", True, False, False),
              ("across sessions, two `compare run` runs (yardstick minutes before the cells), any code",
               True, False, True),
              ("within a session (runs < 1 h apart), any code", False, False, False))
    for scope, across, same, short in scopes:
        print(f"### {scope}\n")
        print("| regime | unit | median ratio | within 10 % | within 20 % | pairs |")
        print("|---|---|---|---|---|---|")
        for regime, cands in CANDIDATES.items():
            for name, fn in cands:
                print(f"| {regime} | {name} " + summary(pairs(cells, fn, across, same, short)))
        print()
    print("### across sessions, two `compare run` runs, by scenario\n")
    print("| scenario | regime | unit | median ratio | within 10 % | within 20 % | pairs |")
    print("|---|---|---|---|---|---|---|")
    for sc in ("saxpy", "particles"):
        mine = {k: v for k, v in cells.items() if k[0] == sc}
        for regime, name in (("latency", "raw us"), ("latency", "/ launch + sync floor"),
                             ("throughput", "raw us"), ("throughput", "/ pipelined floor"),
                             ("throughput", "/ launch + sync floor"), ("graph", "raw us"),
                             ("graph", "/ launch + sync floor")):
            fn = dict(CANDIDATES[regime])[name]
            print(f"| {sc} | {regime} | {name} " + summary(pairs(mine, fn, True, False, True)))


if __name__ == "__main__":
    main()
