"""Measurement sweeps (docs/measurement.md): bandwidth, time against error, scaling.

    sweep bandwidth   launch overhead, copy roofline, achieved bandwidth against size
    sweep error       time against error: precision, fast-math variants and each scenario's own
                      knobs (resolution, dt, ...) against a converged float64 reference
    sweep scaling     throughput and memory against problem size (the projectile: against batch)
    sweep horizon     memory and gradient quality against the horizon (the projectile's steps),
                      with each backend's memory-saving variants (e.g. checkpointing)
    sweep all         the four above
    sweep report F... rebuild the page and plots from saved sweep.json files (no rerun)

What is swept per scenario is registered beside this suite (``compare.sweep.points``: points,
role, converged error): this suite plans the cells, runs them on ``compare.running.engine.run_cells`` (one
worker process each, the same protocol as ``python -m compare``), attaches each error-sweep
cell's converged error, and keeps DIR/sweep.json in the common store (compare/results/store.py; a cell
run again replaces its old record; --resume keeps ok, mismatch and skipped cells and retries
errors, as every suite does). A record's suite identity is its ``tags``: sweep
kind, role (the scenario's ``measures`` in the bandwidth sweep, else its name) and knob. Every run
rebuilds the Markdown page (--page, default DIR/measurement.md) and the PNGs in DIR from the whole
file (compare/sweep/page.py, compare/sweep/plots.py).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
from pathlib import Path
from typing import Any, Mapping, NamedTuple

import backends
import scenarios
from backends.base import Device
from compare.running import engine, hardware, scaleout
from compare.measuring import environment
from compare.running import sitting_run
from compare import options
from compare.planning import outdir, preflight
from compare.suites.driver import Planned, Run, Suite, claim, drive
from compare.options import EXIT_FAIL, EXIT_OK, UsageError
from compare.results.record import Record
from compare.spec import Cell
from compare.results.store import Store, atomic_write
from compare.sweep import page as pages
from compare.sweep import plots
from compare.sweep.converged import Cache, Param, Reference
from compare.sweep.points import Point, sweeps
from scenarios.base import PRECISIONS, ParamError, Precision

KINDS = ("bandwidth", "error", "scaling", "horizon")
PRECISION = {"bandwidth": "float32", "error": "float32,float64", "scaling": "float32",
             "horizon": "float32,float64"}
ROLE_ORDER = ("launch", "copy", "bandwidth")    # the bandwidth sweep measures its yardsticks first


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("kind", help="bandwidth | error | scaling | horizon | all | report")
    p.add_argument("files", nargs="*", help="report: sweep.json files to merge")
    options.add_selection(p, precision=None, variants=False)   # error: every variant a backend has
    p.add_argument("--scenarios", default=None, help="error, scaling, horizon: which scenarios to sweep "
                   f"(default: every one with points of that kind; error: {','.join(error_scenarios())})")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a scenario parameter for every swept scenario that has it (repeatable), "
                        "e.g. contact=hard; a parameter the sweep varies cannot be set")
    p.add_argument("--record-every", type=int, default=0, metavar="K",
                   help="scaling: also keep every K-th state (default 0: no trajectory)")
    p.add_argument("--quick", action="store_true", help="few, small points (minutes on 2 cores)")
    options.add_timing(p, repeat=None, min_time=None, timeout=600.0)
    options.add_processes(p)
    p.add_argument("--cache", default="cold", choices=("cold", "warm"),
                   help="framework kernel caches for the first call (docs/measurement.md)")
    options.add_output(p, "results/sweep")
    options.add_page(p)
    options.add_scheduler(p)
    p.add_argument("--resume", action="store_true",
                   help="keep OUT/sweep.json's ok, mismatch and skipped cells; run the rest (errors are retried)")
    p.add_argument("--fresh", action="store_true", help="drop OUT/sweep.json's records first")


def error_scenarios() -> list[str]:
    """Every scenario with time-against-error points on some device."""
    return [sc.name for sc in scenarios.SCENARIOS.values()
            if any(sweeps(sc.name).points("error", d, q) for d in backends.DEVICES for q in (False, True))]


# ---- plans ----------------------------------------------------------------------------------
def swept(kind: str, args: argparse.Namespace, devices: list[str]) -> list[scenarios.Scenario]:
    """The scenarios sweep ``kind`` runs, in the order it runs them."""
    if kind == "error":
        return [scenarios.get(n) for n in
                options.names(",".join(error_scenarios()) if args.scenarios is None else args.scenarios,
                              error_scenarios(), "scenarios")]
    found = [sc for sc in scenarios.SCENARIOS.values()
             if any(sweeps(sc.name).points(kind, d, args.quick) for d in devices)]
    if args.scenarios is not None and kind != "bandwidth":
        wanted = options.names(args.scenarios, list(scenarios.SCENARIOS), "scenarios")
        found = [sc for sc in found if sc.name in wanted]
    rank: dict[str | None, int] = {role: i for i, role in enumerate(ROLE_ORDER)}
    return sorted(found, key=lambda sc: rank.get(sweeps(sc.name).measures, len(rank)))


class Resolved(NamedTuple):
    """A scenario's sweep point with its parameters resolved: the scenario's Params (the cell's
    ``params``), the point's defaults overridden by --set (and, for scaling, --record-every)."""
    params: Any                     # the scenario's own Params dataclass (compare.spec.Cell.params)
    point: Point


def points(sc: scenarios.Scenario, kind: str, device: str, args: argparse.Namespace,
           sets: Mapping[str, str]) -> list[Resolved]:
    """The scenario's points with --set (and, for scaling, --record-every) applied and the
    parameters resolved (the scenario's Params, once)."""
    raw = sweeps(sc.name).points(kind, device, args.quick)
    over: dict[str, Param] = {k: v for k, v in sets.items()}      # --set's strings: Params coerces them
    fields = {f.name for f in dataclasses.fields(sc.Params)}
    if kind == "scaling" and args.record_every and "record_every" in fields:
        over["record_every"] = args.record_every
    for k in over:
        if len({json.dumps(pt.params.get(k)) for pt in raw}) > 1:
            raise ParamError(f"--set {k}: the {kind} sweep of {sc.name} varies it")
    return [Resolved(sc.params({**pt.params, **over}), pt) for pt in raw]


def plan(args: argparse.Namespace) -> list[Planned[Reference | None]]:
    """Every cell of the requested sweeps as (cell, the point's converged-error reference), in
    run order: kind, device, backend, variant (error sweep only), precision, scenario, point."""
    sel = options.selection(args)
    kinds = KINDS if args.kind == "all" else (args.kind,)
    precisions = {k: options.names(PRECISION[k] if args.precision is None else args.precision, PRECISIONS,
                                   "precision") for k in kinds}
    if args.record_every < 0:
        raise ParamError(f"--record-every must be >= 0, got {args.record_every}")
    chosen = {k: swept(k, args, sel["devices"]) for k in kinds}
    everyone = list({sc.name: sc for k in kinds for sc in chosen[k]}.values())
    sets = options.scenario_sets(options.parse_sets(args.set), everyone)
    repeat = args.repeat or (3 if args.quick else 10)
    min_time = args.min_time if args.min_time is not None else (0.05 if args.quick else 0.2)
    out: list[Planned[Reference | None]] = []
    for kind in kinds:
        for dev in sel["devices"]:
            pts = {sc.name: points(sc, kind, dev, args, sets[sc.name]) for sc in chosen[kind]}
            for sc in chosen[kind]:          # --set values each swept precision can represent
                for params, _ in pts[sc.name]:
                    for prec in precisions[kind]:
                        options.check_precision(sc, params, prec)
            for be in sel["backends"]:
                for variant in variants(kind, be, chosen[kind]):
                    for prec in precisions[kind]:
                        for sc in chosen[kind]:
                            if variant not in sweep_variants(kind, be, sc.name):
                                continue
                            measures = sweeps(sc.name).measures
                            role = measures if kind == "bandwidth" and measures else sc.name
                            for params, pt in pts[sc.name]:
                                knob = pt.knob.to_json() if pt.knob else {}
                                cell = Cell(sc.name, be, Device(dev), Precision(prec), variant, params,
                                            tags={"sweep": kind, "role": role, "knob": knob},
                                            repeat=repeat, min_time=min_time, cache=args.cache,
                                            check_sample=pt.check_sample, save_outputs=pt.save_outputs,
                                            own_timer=False)   # the clock's cross-check: the matrix's
                                out.append(Planned(cell, pt.reference))
    return out


def sweep_variants(kind: str, backend: str, scenario: str) -> tuple[str, ...]:
    """The variants sweep ``kind`` runs: the backend's general variants in the error sweep (e.g.
    fast math: precision against speed), the scenario's own variants in the horizon sweep (e.g.
    checkpointing: memory against time) and the bandwidth sweep (e.g. vector loads: bandwidth
    against size), else the default."""
    be = backends.get(backend)
    if kind == "error":
        return be.variants
    if kind in ("horizon", "bandwidth"):
        own = be.scenario_variants.get(scenario, ())
        return ("default",) + tuple(v for v in own if v not in be.comparison_variants)
    return ("default",)


def variants(kind: str, backend: str, swept_scenarios: list[scenarios.Scenario]) -> list[str]:
    return list(dict.fromkeys(v for sc in swept_scenarios for v in sweep_variants(kind, backend, sc.name)))


# ---- records and the results file ----------------------------------------------------------
def contents(store: Store) -> pages.Contents:
    """What the page and plots read: the store's runs and records."""
    return pages.Contents(store.runs, store.records)


# ---- running --------------------------------------------------------------------------------
def label(rec: Record) -> str:
    """A sweep record's name in the progress lines: its sweep, identity and knob setting."""
    tags = rec.tags or {}
    knob = tags.get("knob") or {}
    setting = f" {knob.get('name')}={knob.get('value')}" if knob.get("name") and knob.get("value") is not None else ""
    return f"{tags.get('sweep')} {rec.scenario}/{rec.backend}/{rec.device}/{rec.precision}/{rec.variant}{setting}"


def rebuild(data: pages.Contents, args: argparse.Namespace, sources: list[str], notes: str) -> Path:
    """Write the PNGs into --out and the Markdown page (--page); returns the page's path."""
    out = Path(args.out)
    page = Path(args.page) if args.page else out / "measurement.md"
    written = plots.write_plots(data.records, out) if not args.no_plots else {}
    cmd = ["python -m compare sweep report", *map(shlex.quote, [*sources, "--out", str(out),
                                                                "--page", str(page)])]
    if args.title:
        cmd += ["--title", shlex.quote(args.title)]
    if args.notes:
        cmd += ["--notes", shlex.quote(args.notes)]
    atomic_write(page, pages.page(data, written, page, args.title, sources, " ".join(cmd), notes))
    return page


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """``argv``: the command line after ``python -m compare`` (``sweep ...``), for the record."""
    if args.kind == "report":
        return report(args)
    return drive(SweepSuite(), args, argv)


class SweepSuite(Suite):
    """The sweeps' cells, run one at a time here (they would share cores and the GPU) or on a
    Dask cluster's workers, one per GPU and core set, into DIR/sweep.json (saved after every
    record), each error-sweep record with its converged error attached first."""
    add_arguments = staticmethod(add_arguments)

    def plan(self, args: argparse.Namespace) -> list[Planned[Reference | None]]:
        if args.kind not in (*KINDS, "all"):
            raise UsageError(f"unknown sweep {args.kind!r} ({', '.join(KINDS)}, all, report)")
        if args.files:
            raise UsageError(f"unexpected argument {args.files[0]!r}")
        given = options.given(args, add_arguments, args.kind)
        if "--scenarios" in given and args.kind == "bandwidth":
            raise UsageError("--scenarios does not apply to the bandwidth sweep (its scenarios are its yardsticks)")
        if "--record-every" in given and args.kind not in ("scaling", "all"):
            raise UsageError(f"--record-every does not apply to the {args.kind} sweep (only to scaling)")
        if args.resume and args.fresh:
            raise UsageError("--resume keeps OUT/sweep.json's records and --fresh drops them: give one")
        options.check_scheduler(args)
        planned = plan(args)
        if not planned:
            raise UsageError(f"nothing to run: the {args.kind} sweep has no points for the chosen "
                             "scenarios, backends and devices")
        return planned

    def check_output(self, args: argparse.Namespace) -> None:
        self.notes = outdir.read_notes(args.notes)
        outdir.check_output(args.out)
        Store.open(args.out, "sweep", keep=not args.fresh)     # a bad sweep.json refused (read only)
        # after every read-only refusal: the page's check creates (and removes) a file in its folder
        outdir.check_page(args.page or str(Path(args.out) / "measurement.md"), args.title)

    def disk_need(self, run: Run) -> float:
        return 2 * (preflight.RECORD_BYTES * len(run.runnable) + existing_bytes(run.args.out)) + preflight.PAGE_BYTES

    def open(self, run: Run) -> None:
        args = run.args
        self.store_ = store = Store.open(run.out, "sweep", keep=not args.fresh)
        env = self.env = environment.collect(list(map(shlex.quote, run.argv)))    # a command one can paste
        env["backends"] = run.probes
        env.update(run.protocol())
        env["kinds"] = list(KINDS if args.kind == "all" else (args.kind,))
        env["hardware"] = {d: hardware.for_run(d) for d in dict.fromkeys(str(c.device) for c in run.cells)
                           if any(p["available"].get(d) is None for p in run.probes.values())}
        sitting_run.start(env)          # before any cell: reuses the yardstick just measured
        if run.client is not None:
            env["scheduler"] = {"address": args.scheduler, **scaleout.placement(run.client)}
        store.runs.append(env)
        store.save()
        self.references = [p.extra for p in run.planned]
        self.cache: Cache = {}
        self.show = engine.progress(len(run.cells), label)
        self.count = iter(range(len(run.cells)))

    def shares_caches(self, cell: Cell) -> bool:
        # no sweep page reads a first call but the bandwidth sweep's launch table ("first call (cold)")
        return cell.tags.get("sweep") != "bandwidth"

    def store(self) -> Store:
        return self.store_

    def seed(self) -> int:
        return int(self.env.get("seed", 0))

    def on_record(self, j: int, rec: Record, outputs: engine.Outputs | None) -> Record:
        if (rec.tags or {}).get("sweep") == "error" and rec.status in ("ok", "mismatch"):
            conv = sweeps(rec.scenario).converged_error(dict(rec.params or {}), outputs, rec, self.cache,
                                                        reference=self.references[j])
            if conv is not None:
                rec = rec.replace(converged=conv.to_json())     # stored in sweep.json
        rec = hardware.annotated(rec, self.env.get("hardware") or {}).replace(run=environment.run_stamp(self.env))
        self.show(next(self.count), rec, outputs)
        return rec

    def render(self, run: Run, results: list[Any]) -> int:
        store = self.store_
        if sitting_run.from_publish() is not None:
            sitting_run.end(self.env)   # a publish part's end check, beside its records
            store.save()
        page = rebuild(contents(store), run.args, [str(store.path)], self.notes)
        print(pages.summary(store.records))
        print(f"wrote {store.path} and {page}")
        bad = [r for r in store.records if r.status in ("mismatch", "error")]
        return EXIT_FAIL if bad else EXIT_OK


def existing_bytes(out: str) -> int:
    f = Path(out) / "sweep.json"
    return f.stat().st_size if f.is_file() else 0


def report(args: argparse.Namespace) -> int:
    if not args.files:
        raise UsageError("report needs at least one sweep.json")
    options.refuse_inapplicable(args, add_arguments, ("kind", "files", "--out", "--no-plots", "--page",
                                                      "--title", "--notes"), "to sweep report", "report")
    options.no_duplicates(args.files, "sweep report")
    notes = outdir.read_notes(args.notes)
    merged = Store(Path(args.out) / "sweep.json", "sweep")
    for f in args.files:                  # a later file's record of the same cell wins
        merged.merge(Store.read(f, "sweep"))
    outdir.check_page(args.page or str(Path(args.out) / "measurement.md"), args.title)
    out, lock = claim(args, preflight.PAGE_BYTES)
    with lock:
        rebuild(contents(merged), args, list(args.files), notes)
    print(pages.summary(merged.records))
    return EXIT_OK

