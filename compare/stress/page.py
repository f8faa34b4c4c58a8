"""stress.json and stress.md: the one place that reads and writes the suite's results.

``stress.json`` is the suite's common store (compare/results/store.py): the cell records of the runs, and
as ``analysis`` the findings: ``rows``, plot ``series`` and ``provenance``, which says, per
experiment, which run (command, time, commit) produced its rows, since a results file may be
assembled from several runs (``--only`` parts, ``--merge``).
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path
from typing import Any, Mapping, TypedDict, cast

import backends
from compare.render.report import fmt_num
from compare.results.analysis import Provenance, RunInfo
from compare.results.environment import RunEnvironment, tree_state
from compare.results.store import Store, atomic_write, jsonable, run_environments
from compare.stress import generic, plots
from compare.stress.numerics import COLUMNS, Experiment, Finding, Row, Series

Registry = dict[str, Experiment]


class PageData(TypedDict, total=False):
    """What the page is made from: stress.json's analysis and its run's environment (``_out``:
    the folder the page and plots are in)."""
    environment: RunEnvironment
    rows: list[Finding]
    series: dict[str, Series]
    provenance: Provenance
    _out: str


def fmt_value(v: Any) -> str:
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v)
    if isinstance(v, float) and math.isfinite(v) and v != 0:
        return f"{v:.4g}"
    return fmt_num(v) if not isinstance(v, bool) else str(v)


def provenance(data: PageData) -> Provenance:
    """experiment -> the run that produced its rows (command, time, commit), or, for a file merged
    from parts that ran different backends, the list of those runs, each naming its ``backends``."""
    if "provenance" in data:
        return data["provenance"]
    env = data.get("environment", {})
    run = RunInfo(command=env.get("command"), created=env.get("created"), git_commit=env.get("git_commit"),
                  git_dirty=env.get("git_dirty"))
    if env.get("noisy_sitting"):
        run["noisy_sitting"] = True
    if "merged_from" in env:      # an old merged file: its parts' commands and trees were not kept
        run["command"] = f"merge of {len(env['merged_from'])} parts (commands not recorded)"
        run["git_dirty"] = None
    return {r["experiment"]: run for r in data.get("rows", [])}


def runs_of(entry: RunInfo | list[RunInfo]) -> list[RunInfo]:
    """One experiment's provenance as a list of runs (a single run gave all of its rows)."""
    return entry if isinstance(entry, list) else [entry]


def produced_by(data: PageData) -> list[str]:
    """One line per run that produced rows: its command, when, and which experiments (with the
    backends it gave, where a merge took the experiment's other backends from another run)."""
    runs: dict[tuple, list[str]] = {}
    for e, entry in provenance(data).items():
        for r in runs_of(entry):
            label = e if "backends" not in r or len(runs_of(entry)) == 1 else f"{e} ({', '.join(r['backends'])})"
            state = f", {words}" if (words := tree_state(r.get("git_dirty"))) else ""
            runs.setdefault((r.get("command") or "?", r.get("created") or "?", f"{r.get('git_commit') or '?'}{state}"),
                            []).append(label)
    lines = ["- produced by:" if len(runs) > 1 else "- produced by"]
    for (cmd, when, commit), exps in runs.items():
        lines.append(f"  - `{cmd}` ({when}, commit {commit}): {', '.join(exps)}")
    return lines


def run_key(run: Mapping[str, Any]) -> tuple[object, object]:
    """What names one run in a provenance and in the environments: its start and command."""
    return run.get("created"), run.get("command")


def part_environments(envs: list[RunEnvironment]) -> dict[tuple[object, object], RunEnvironment]:
    """The parts' runs by ``run_key`` (a part itself merged gives those it names; one merged before
    they were kept gives its last part's, which its entry is, with the packages of all)."""
    known: dict[tuple[object, object], RunEnvironment] = {}
    for env in envs:
        for e in run_environments(env):
            known.setdefault(run_key(e), cast(RunEnvironment, {k: v for k, v in e.items() if k != "merged_from"}))
    return known


def environments(known: dict[tuple[object, object], RunEnvironment],
                 prov: dict[str, list[RunInfo]]) -> list[RunEnvironment]:
    """The runs a merged file's rows come from, once each in provenance order, each run's tree
    state carried into the provenance where it lacked one; a run that a file merged before
    environments were kept names only in its provenance: what that names (tree unknown)."""
    out: dict[tuple[object, object], RunEnvironment] = {}
    for entry in prov.values():
        for r in entry:
            e = known.get(run_key(r))
            if e is not None and "git_dirty" not in r:
                r["git_dirty"] = e.get("git_dirty")
            out.setdefault(run_key(r), e if e is not None else RunEnvironment(
                created=r.get("created"), command=r.get("command"), git_commit=r.get("git_commit"),
                git_dirty=r.get("git_dirty"), git_note=OLD_MERGE))
    return list(out.values())


OLD_MERGE = "named only, by an older stress merge"


def record_runs(known: dict[tuple[object, object], RunEnvironment], prov: dict[str, list[RunInfo]],
                target: Store) -> list[RunEnvironment]:
    """The parts' runs that a kept cell record names (its ``run``) but no experiment's rows do
    (a later part replaced those rows, not every cell): every record keeps a run in the file."""
    have = {run_key(r)[0] for entry in prov.values() for r in entry}
    named = {str((r.run or {}).get("created")) for r in target.records if r.run}
    return [e for (created, _), e in known.items() if created not in have and str(created) in named]


# A verdict flags a problem or a limit found in CAPITALS (docs/stress.md); these capitals are
# names, never a flag.
ACRONYMS = frozenset({"GD", "FD", "AD", "CPU", "GPU", "CUDA", "ULP", "SDF", "NaN"})
# A figure whose larger value is the worse one: an error, a share of a bound, a count of
# differing elements (the others, e.g. the first step that overflowed, have no "worst" here).
WORSE_HIGHER = re.compile(r"\b(error|bound|ulps|differing|flips|changed|distance)\b", re.I)


def flagged(verdict: str) -> bool:
    """The verdict flags a problem or a limit (a word in capitals that is not a name)."""
    return any(w not in ACRONYMS for w in re.findall(r"\b[A-Z]{2,}\b", str(verdict)))


def skipped(r: Finding) -> bool:
    return str(r.get("verdict")) == "skipped"


def measured(r: Finding) -> float | None:
    """The row's value where it is a finite number (a boolean is none)."""
    v = r.get("value")
    return v if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def verdict(r: Finding) -> str:
    """The row's verdict as the pages show it: a racy control's worded again by
    ``generic.race_verdict`` from the row's own figures (a store made before it said which
    evidence caught the race shows "RACE DETECTED (outside the oracle's bound)" beside 0
    differing elements); any other row's as stored."""
    v, n = str(r.get("verdict", "")), r.get("value")
    if r.get("experiment") == "races" and generic.CONTROL in str(r.get("detail", "")) \
            and isinstance(n, int) and not isinstance(n, bool):
        ok = "outside the oracle's bound" not in v
        return generic.race_verdict(str(r.get("device")), n, (ok, ok))
    return v


def worst(rows: list[Finding]) -> Finding | None:
    """An experiment's worst row: among its flagged rows (else all it measured), the largest
    value of the most common figure whose larger value is worse; a flagged row without such a
    figure: the first flagged."""
    flags = [r for r in rows if flagged(r["verdict"])]
    pool = [r for r in flags or rows if not skipped(r) and measured(r) is not None
            and WORSE_HIGHER.search(str(r["figure"]))]
    if pool:
        figs = [r["figure"] for r in pool]
        top = max(dict.fromkeys(figs), key=figs.count)
        return max((r for r in pool if r["figure"] == top), key=lambda r: measured(r) or 0.0)
    return flags[0] if flags else None


def summary(rows: list[Finding], experiments: Registry) -> list[tuple[str, ...]]:
    """One line per experiment with rows: (experiment, title, cases, skipped, flagged, worst)."""
    out: list[tuple[str, ...]] = []
    for name, exp in experiments.items():
        mine = [r for r in rows if r["experiment"] == name]
        if not mine:
            continue
        w = worst(mine)
        words = "-" if w is None else (f"{w['backend']} {w['device']} {w['precision']} {w['setting']}: "
                                       f"{w['figure']} = {fmt_value(w['value'])} ({verdict(w)})")
        out.append((name, exp.title, str(sum(not skipped(r) for r in mine)), str(sum(skipped(r) for r in mine)),
                    str(sum(flagged(r["verdict"]) for r in mine)), words))
    return out


SUMMARY_HEADERS = ("experiment", "what", "cases", "skipped", "flagged (CAPITALS)", "worst")


def markdown(data: PageData, experiments: Registry) -> str:
    from tabulate import tabulate
    env = data.get("environment", {})
    lines = ["# Stress suite results", "",
             *produced_by(data), f"- host: {env.get('hostname', '?')}, "
             f"CPU {env.get('cpu', '?')}, GPUs: {', '.join(g.get('name', '?') for g in env.get('gpus', [])) or 'none'}",
             f"- Python {env.get('python', '?')}; " + ", ".join(f"{k} {v}" for k, v in env.get("packages", {}).items()),
             "- How each verdict is decided: docs/stress.md. Verdicts in CAPITALS flag a problem or a "
             "limit found; 'skipped' rows say why.", "", "## Summary", "",
             tabulate(summary(data["rows"], experiments), headers=SUMMARY_HEADERS, tablefmt="github",
                      disable_numparse=True), "", "## Verdicts per experiment", ""]
    counts: dict[str, dict[str, int]] = {}
    for r in data["rows"]:
        v = re.sub(r"(?<![\w.])\d[\d.e+-]*%?", "#", r["verdict"].split(" (")[0])    # numbers apart: one class
        counts.setdefault(r["experiment"], {}).setdefault(v, 0)
        counts[r["experiment"]][v] += 1
    lines += [f"- **{e}**: " + "; ".join(f"{v} x{k}" for v, k in c.items()) for e, c in counts.items()] + [""]
    for name, exp in experiments.items():
        rows = [r for r in data["rows"] if r["experiment"] == name]
        if not rows:
            continue
        lines += [f"## {name}: {exp.title}", ""]
        if (Path(data["_out"]) / f"{name}.png").exists():
            lines += [f"![{name}]({name}.png)", ""]
        if exp.extra_markdown is not None:
            lines += [exp.extra_markdown(rows), ""]
        if exp.table_rows is not None:
            rows = exp.table_rows(rows)
        table = [[r["backend"], r["device"], r["precision"], r["setting"], r["figure"], fmt_value(r["value"]),
                  verdict(r), r["detail"]] for r in rows]
        lines += [tabulate(table, headers=COLUMNS[1:], tablefmt="github", disable_numparse=True), ""]
    return "\n".join(lines) + "\n"


def stored(store: Store) -> PageData:
    """The store's analysis (rows, series, provenance) as the file holds it, with the
    environment of its last run."""
    return cast(PageData, {"environment": store.runs[-1] if store.runs else {}, **store.analysis})


def old_provenance(store: Store) -> Provenance:
    """Provenance of the store's findings (a file of the first format kept none: its one run)."""
    return provenance(stored(store))


def write_outputs(store: Store, env: RunEnvironment, rows: list[Row] | list[Finding], series: dict[str, Series],
                  ran: list[str], experiments: Registry, plots_: bool = True,
                  prov: Provenance | None = None) -> list[Finding]:
    """Findings of the experiments in ``ran`` replace the store's (the others are kept); save
    the store (stress.json), then stress.md and the plots beside it. Rows an experiment made
    (``Row``) become the stored form here. Returns every finding, as stored."""
    out = store.path.parent
    new = [r.to_json() if isinstance(r, Row) else r for r in rows]
    old = stored(store)
    old_rows = [r for r in old.get("rows", []) if r["experiment"] not in ran]
    old_series = {k: v for k, v in old.get("series", {}).items() if k not in ran}
    old_prov = {k: v for k, v in provenance(old).items() if k not in ran}
    order = list(experiments)
    all_rows = sorted(old_rows + new, key=lambda r: order.index(r["experiment"]) if r["experiment"] in order else 99)
    new_prov = prov if prov is not None else provenance({"environment": env, "rows": new})
    store.analysis = jsonable({"provenance": {**old_prov, **{e: v for e, v in new_prov.items() if e in ran}},
                               "rows": all_rows, "series": {**old_series, **series}})
    if not store.runs or store.runs[-1] is not env:
        store.runs.append(env)
    store.save()
    data = cast(PageData, {"environment": env, **store.analysis})
    if plots_:
        for name, s in data["series"].items():
            if name in experiments:
                plots.draw(experiments[name], s, out / f"{name}.png")
    atomic_write(out / "stress.md", markdown({**data, "_out": str(out)}, experiments))
    return data["rows"]


def row_key(r: Finding) -> tuple[str, str, str]:
    """What a later part replaces in a merge: one experiment's rows of one backend on one device."""
    return r["experiment"], r["backend"], r["device"]


def deep_merge(a: Any, b: Any) -> Any:
    """Plot series of two parts: nested dicts are joined (the series are keyed by backend/device
    labels), anything else is taken from ``b``."""
    if isinstance(a, dict) and isinstance(b, dict):
        return {**a, **{k: deep_merge(a[k], v) if k in a else v for k, v in b.items()}}
    return b


def in_table_order(rows: list[Finding], seen: list[Finding]) -> list[Finding]:
    """Merged rows as one run would list them: per experiment, each kind of figure together, in the
    order the parts (``seen``: all their rows, in file order) first showed it, and within it the
    backends in registry order (host-side rows such as the oracle's last)."""
    rank = {b: i for i, b in enumerate(backends.BACKENDS)}
    first: dict[tuple[str, str], int] = {}
    for r in seen + rows:
        first.setdefault((r["experiment"], r["figure"]), len(first))
    return sorted(rows, key=lambda r: (first[(r["experiment"], r["figure"])], rank.get(r["backend"], len(rank))))


def with_backends(run: RunInfo, gave: list[str]) -> RunInfo:
    """``run``, naming the backends it gave."""
    out = run.copy()
    out["backends"] = gave
    return out


def named(file: str, out: Path) -> str:
    """A merged file as the store names it: relative to ``out`` where it lies inside it (a
    publish's parts), else as given (not the merging machine's temporary folders)."""
    try:
        return Path(file).resolve().relative_to(out.resolve()).as_posix()
    except ValueError:
        return file


def merge(files: list[str], out: Path, experiments: Registry, plots_: bool = True) -> int:
    """Rebuild DIR/stress.{json,md} and plots from parts run separately (e.g. one GPU call each,
    or new backends run later); later files win per experiment, backend and device (and per cell
    record), so a part that ran some backends keeps the other backends' rows of earlier parts, and
    a part's ``skipped`` row replaces only another skipped row. A part cut off before its findings
    (records, no rows) is left out, said on stderr."""
    target = Store.open(out, "stress")
    rows: list[Finding] = []
    series: dict[str, Series] = {}
    envs: list[RunEnvironment] = []
    prov: dict[str, list[RunInfo]] = {}
    seen: list[Finding] = []
    for f in files:
        part = Store.read(f, "stress")
        got = stored(part)
        if part.records and not got.get("rows"):
            # cut off before its findings: its records would sit under an earlier run's rows
            n = len(part.records)
            print(f"stress --merge: {f}: {n} record{'s' if n != 1 else ''} and no findings (cut off before "
                  "its experiment ended): not merged", file=sys.stderr)
            continue
        seen += got.get("rows", [])
        found = {row_key(r) for r in rows if r["verdict"] != "skipped"}
        ran = {row_key(r) for r in got.get("rows", []) if r["verdict"] != "skipped"}
        # a part that skipped a backend (not installed where it ran) erases no earlier finding; one
        # that ran it keeps its own skips (a variant the device lacks)
        part_rows = [r for r in got.get("rows", []) if r["verdict"] != "skipped" or row_key(r) in ran
                     or row_key(r) not in found]
        replaced = {row_key(r) for r in part_rows}
        rows = [r for r in rows if row_key(r) not in replaced]
        for e, entry in old_provenance(part).items():
            gave = sorted({r["backend"] for r in part_rows if r["experiment"] == e})
            if not gave:
                continue
            kept = {r["backend"] for r in rows if r["experiment"] == e}
            earlier = [with_backends(run, [b for b in run["backends"] if b in kept]) for run in prov.get(e, [])]
            own = [with_backends(run, [b for b in run.get("backends", gave) if b in gave]) for run in runs_of(entry)]
            prov[e] = [run for run in earlier + own if run["backends"]]
        rows += part_rows
        series = deep_merge(series, got.get("series", {}))
        envs.append(part.runs[-1] if part.runs else {})
        for r in part.records:
            target.put(r)
    # the page lists the packages of every part, each version that any part ran with
    versions: dict[str, list[str]] = {}
    for run_env in envs:
        for k, v in run_env.get("packages", {}).items():
            if v not in versions.setdefault(k, []):
                versions[k].append(v)
    known = part_environments(envs)
    env: RunEnvironment = {**envs[-1], "packages": {k: " / ".join(v) for k, v in versions.items()},
                           "merged_from": [named(f, out) for f in files],
                           "environments": environments(known, prov) + record_runs(known, prov, target)}
    write_outputs(target, env, in_table_order(rows, seen), series, sorted({r["experiment"] for r in rows}), experiments,
                  plots_=plots_, prov={e: v if len(v) > 1 else v[0] for e, v in prov.items()})
    print(f"merged {len(files)} files into {target.path} ({len(rows)} rows)", file=sys.stderr)
    return 0
