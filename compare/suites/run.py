"""``python -m compare all | run SCENARIO... | <scenario>``: every cell timed, checked and tabled.

Plan: every chosen scenario x backend x device x precision x variant (reference backend first).
Run: ``engine.run_cells`` (one worker process per cell, one at a time: timed cells never share
the machine) into the ``run`` store (``RunStore``: DIR/results.json and with it results.csv/.md,
saved after every cell, each record judged against the run's yardstick and its --save-arrays
file written before it is saved). Render: each port's distance to the reference backend, plots,
results.csv/.md, and the console table.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

import backends
import scenarios
from backends.base import DEFAULT_VARIANT, Device
from compare.planning import calibrate, outdir
from compare.render import console, report, run_plots
from compare.running import engine, hardware, scaleout
from compare.measuring import environment, phases
from compare.running import sitting_run
from compare import options
from compare.site import versus
from compare.suites.driver import Planned, Run, Suite, drive
from compare.planning.preflight import (cell_bytes, check_memory, check_smallest, disk_need,
                               measured_need, memory_refusal)
from compare.results.environment import RunEnvironment
from compare.results.record import Record, plain
from compare.results.record_parts import Timing
from compare.spec import BUSY_TAG, Cell, key
from compare.results.store import Store, StoreError, array_file, load_arrays, save_arrays
from compare.options import UsageError
from scenarios.base import Precision


def add_arguments(p: argparse.ArgumentParser) -> None:
    options.add_selection(p)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario parameter (repeatable; applies to every chosen scenario that has it)")
    p.add_argument("--quick", action="store_true", help="small sizes (CI)")
    options.add_timing(p)
    p.add_argument("--cache", default="cold", choices=("cold", "warm"),
                   help="framework kernel caches for the first call (default cold; warm: a correctness "
                        "run such as the tests', whose first calls need not include compilation)")
    options.add_output(p, "results")
    p.add_argument("--save-arrays", action="store_true", help="write inputs/outputs per cell (npz)")
    p.add_argument("--check-sample", type=options.nonnegative_int, default=0, metavar="K",
                   help="check K items of per-item scenarios against the oracle (row 0, the last, the "
                        "extremes of the inputs and outputs, the rest a seeded random draw) "
                        "(large n: the float64 oracle of every item can take minutes; 0: the scenario's "
                        "default, every item up to a size: 64 trajectories of a projectile batch, "
                        "65536 particles; K at least n: all)")
    p.add_argument("--host-profile", type=options.nonnegative_int, default=0, metavar="TOP",
                   help="also profile the host side of the throughput regime (cProfile) and keep "
                        "the TOP functions by own time in each record (time.host_profile)")
    options.add_processes(p)
    p.add_argument("--busy", type=options.nonnegative_int, default=0, metavar="N",
                   help="the shared-host experiment: time every CPU cell idle, then right after with N "
                        "cores kept busy by other processes (a laptop or CI runner; tags.busy_cores 0 "
                        "and N, kept apart from the plain cells)")
    p.add_argument("--resume", action="store_true",
                   help="keep DIR/results.json's ok, mismatch and skipped cells; run the rest (errors are retried)")
    p.add_argument("--force", action="store_true",
                   help="replace the results of an earlier run in --out (default: refuse them)")
    options.add_scheduler(p)
    p.add_argument("--wide", action="store_true", help="print every column (default: a view that fits 120)")
    console.add_arguments(p)


def plan(args: argparse.Namespace, chosen: list[scenarios.Scenario]) -> list[Cell]:
    """Every cell of the run, validated: bad input never reaches a worker or the output directory.
    Each scenario's parameters are resolved here, once (defaults, --quick, --set), and every cell
    carries that one object."""
    sel = options.selection(args)
    sets = options.scenario_sets(options.parse_sets(args.set), chosen)
    options.check_scheduler(args)
    params = {sc.name: sc.params(sets[sc.name], quick=args.quick) for sc in chosen}
    for sc in chosen:
        for prec in sel["precisions"]:
            options.check_precision(sc, params[sc.name], prec)
    specs = [Cell(sc.name, b, Device(d), Precision(p), v, params[sc.name], repeat=args.repeat, min_time=args.min_time,
                  cache=args.cache, save_inputs=args.save_arrays, check_sample=args.check_sample,
                  host_profile=args.host_profile)
             for sc in chosen for b in sel["backends"] for d in sel["devices"]
             for p in sel["precisions"] for v in sel["variants"] if v in backends.get(b).variants_for(sc.name)]
    if args.busy:     # the shared-host experiment: each CPU cell idle, then with cores kept busy
        specs = [dataclasses.replace(c, tags={BUSY_TAG: n}) for c in specs if str(c.device) == "cpu"
                 for n in (0, args.busy)]
    if not specs:
        raise UsageError(f"nothing to run: no chosen backend ({', '.join(sel['backends'])}) has "
                         f"variant(s) {', '.join(sel['variants'])}")
    if args.scheduler in (None, "local"):      # the worker runs here: refused when no cell fits
        check_smallest(specs)
    return specs


def fill_vs_reference(records: list[Record], outputs: dict[int, dict[str, np.ndarray]],
                      plan: Sequence[Cell] = ()) -> None:
    """Distance of every port's outputs to the reference backend's, same device and precision
    (or, if the reference did not run there, the reference on another device): each such record
    in ``records`` is replaced by one whose ``error`` says it. Parameters come from the
    ``plan``'s cells; a record of no cell of it (kept by --resume, or a report) gives its own."""
    ref = backends.reference()
    planned = {c.key(): c.params for c in plan}
    made: dict[str, dict[str, np.ndarray]] = {}     # inputs once per scenario, size and precision
    for i, r in enumerate(records):
        if i not in outputs or r.error is None:
            continue
        cands = [j for j, q in enumerate(records) if j in outputs and q.backend == ref
                 and q.scenario == r.scenario and q.precision == r.precision
                 and q.variant == DEFAULT_VARIANT and q.params == r.params]
        cands.sort(key=lambda j: records[j].device != r.device)
        if not cands:
            continue
        sc = scenarios.get(r.scenario)
        p = planned.get(r.key) or sc.params(plain(r.params))
        made_key = json.dumps([r.scenario, plain(r.params), r.precision], sort_keys=True)
        if made_key not in made:
            made[made_key] = sc.inputs(p, r.precision)
        records[i] = r.replace(error={**r.error, "reference": ref,
                                      "vs_reference": sc.distance(p, made[made_key], outputs[i], outputs[cands[0]]),
                                      "vs_reference_device": records[cands[0]].device})


def saved_outputs(directory: Path, records: list[Record],
                  outputs: dict[int, dict[str, np.ndarray]]) -> None:
    """Outputs of cells not run now (resumed, or a report) from --save-arrays files, where kept."""
    for i, r in enumerate(records):
        if i not in outputs and r.status in ("ok", "mismatch"):
            got = load_arrays(directory, r.identity, scenarios.get(r.scenario).outputs)
            if got:
                outputs[i] = got


def render(out: Path, env: RunEnvironment, records: list[Record],
           outputs: dict[int, dict[str, np.ndarray]], plots: bool, clean: bool = False) -> None:
    """Plots (``run_plots.write_plots``: speed, time against error, each scenario's picture; an
    earlier run's removed first when ``clean``) and results.csv/.md in ``out``."""
    if clean:
        run_plots.remove_pictures(out / "plots")
    if plots:
        run_plots.write_plots(records, outputs, out / "plots")
    report.write_tables(out, env, records, images=report.images_in(out / "plots", out))


def refuse_overwrite(args: argparse.Namespace) -> None:
    """An earlier run's results in --out are kept (--resume) or replaced (--force), never silently."""
    if args.resume and args.force:
        raise UsageError("--resume keeps --out's earlier results and --force replaces them: give one")
    if not (args.resume or args.force) and (Path(args.out) / "results.json").exists():
        raise UsageError(f"--out {args.out} holds an earlier run's results: --resume adds to them, "
                         "--force replaces them, or choose another --out")


def chosen_scenarios(args: argparse.Namespace) -> list[scenarios.Scenario]:
    """The scenarios of ``all``, ``run S...`` or ``<S>``."""
    if args.command == "all":
        return [sc for sc in scenarios.SCENARIOS.values() if sc.in_all]
    if args.command == "run":
        return [scenarios.get(n) for n in options.no_duplicates(args.scenarios, "run")]
    return [scenarios.get(args.command)]


def run(args: argparse.Namespace, argv: list[str], chosen: list[scenarios.Scenario] | None = None) -> int:
    return drive(RunSuite(chosen), args, argv)


def preflight_cells(args: argparse.Namespace, runnable: list[Cell]) -> calibrate.Refusal:
    """Big cells run in miniature first (``compare.planning.calibrate``), before anything is written: one
    predicted to outlast --timeout, or whose own framework's estimated memory exceeds what is
    available (``preflight.measured_need``), is skipped saying so; a plan none of whose cells
    fits is refused."""
    minis = calibrate.run_miniatures(runnable, args.timeout) if args.timeout is not None else {}
    slow = calibrate.time_refusal(runnable, args.timeout, minis=minis)
    memory = memory_refusal(measured_need(runnable, args.timeout, minis))
    if runnable and all(memory(c) for c in runnable):
        c = min(runnable, key=lambda c: cell_bytes(c)[0])
        raise UsageError(f"nothing fits this machine's memory: {c.backend} on {c.device}, {c.precision}, "
                         f"{memory(c)[1]}")    # type: ignore[index]
    return lambda c: memory(c) or slow(c)


class RunStore(Store):
    """results.json whose every save also rewrites results.csv and results.md from the same
    records (each atomically), so after an interruption the three agree; ``rerun`` names kept
    cells that --resume runs again (their --save-arrays files are missing)."""
    env: RunEnvironment = {}     # the run's environment, stored in results.json
    rerun: frozenset[str] = frozenset()

    def save(self) -> None:
        super().save()
        out = self.path.parent
        report.write_tables(out, self.env, self.records, images=report.images_in(out / "plots", out))

    def done(self, cell_key: str) -> bool:
        return cell_key not in self.rerun and super().done(cell_key)


def arrays_saved(out: Path, rec: Record) -> bool:
    try:
        return array_file(out, rec.identity).is_file()
    except StoreError:
        return False


class RunSuite(Suite):
    """all / run S... / <S>: every chosen scenario's cells timed, checked and tabled."""

    def __init__(self, chosen: list[scenarios.Scenario] | None = None) -> None:
        self.chosen = chosen            # None: from the command (``chosen_scenarios``)
        self.ran: list[Timing | None] = []     # the time blocks of the processes this run ran (not --resume's)

    add_arguments = staticmethod(add_arguments)

    def plan(self, args: argparse.Namespace) -> list[Planned[None]]:
        chosen = self.chosen if self.chosen is not None else chosen_scenarios(args)
        return [Planned(c, None) for c in plan(args, chosen)]

    def check_output(self, args: argparse.Namespace) -> None:
        outdir.check_output(args.out)                    # a bad --out is refused before the probes
        versus.check(args.against)
        refuse_overwrite(args)
        self.kept = Store.open(args.out, "run", keep=args.resume)   # and a bad results.json to resume

    def refusal(self, run: Run) -> calibrate.Refusal | None:
        return memory_refusal() if run.args.scheduler in (None, "local") else None

    def preflight(self, run: Run) -> calibrate.Refusal | None:
        args = run.args
        check_memory(run.runnable, worker=args.scheduler in (None, "local"))
        if args.scheduler:      # a Dask worker's machine is not this one: neither preflight
            return None
        t0 = time.perf_counter()
        judged = preflight_cells(args, [c for c in run.runnable
                                        if not (args.resume and self.kept.done(key(c.identity())))])
        run.spent["miniatures"] = time.perf_counter() - t0
        return judged

    def disk_need(self, run: Run) -> float:
        return disk_need(run.runnable, run.args.save_arrays, Path(run.args.out) / "results.json")

    def what(self, args: argparse.Namespace) -> str:
        return "the results" + (" and arrays" if args.save_arrays else "")

    def open(self, run: Run) -> None:
        """The store, and the run's environment with the framework-neutral yardstick of every
        device some backend can use, measured in this same run."""
        args, out, probes = run.args, run.out, run.probes
        self.store_ = store = RunStore.open(out, "run", keep=args.resume)
        env = self.env = store.env = environment.collect(run.argv)
        env["backends"] = probes
        env.update(run.protocol())
        t0 = time.perf_counter()
        env["hardware"] = {d: hardware.for_run(d) for d in dict.fromkeys(str(c.device) for c in run.cells)
                           if any(p["available"].get(d) is None for p in probes.values())}
        run.spent["yardstick"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        sitting_run.start(env)          # before any cell: reuses the yardstick just measured
        run.spent["sitting"] = time.perf_counter() - t0
        store.runs = [*store.runs, env] if args.resume else [env]
        if args.resume:
            # kept cells keep their own run's yardstick (each record is judged before it is saved):
            # never this run's, which did not measure them
            if args.save_arrays:        # a kept cell whose arrays were never written runs again
                store.rerun = frozenset(r.key for r in store.records
                                        if r.status in ("ok", "mismatch") and not arrays_saved(out, r))
            if store.records:
                store.save()            # tables rebuilt from the kept records before any cell runs
        if run.client is not None:
            env["scheduler"] = {"address": args.scheduler, **scaleout.placement(run.client)}
        self.out, self.args = out, args
        self.show = engine.progress(len(run.cells), every=args.verbose)
        self.t0 = time.perf_counter()

    def store(self) -> Store:
        return self.store_

    def seed(self) -> int:
        return int(self.env.get("seed", 0))

    def on_record(self, i: int, rec: Record, outs: dict[str, np.ndarray] | None) -> Record:
        self.ran.append(rec.time)
        rec = hardware.annotated(rec, self.env.get("hardware") or {})   # judged against this run's yardstick
        rec = rec.replace(run=environment.run_stamp(self.env))    # and named as this run's
        if self.args.save_arrays and outs is not None:        # before its record is saved: a failed
            save_arrays(self.out, rec.identity, outs)         # write leaves the cell to be run again
        self.show(i, rec, outs)
        return rec

    def on_repeat(self, block: Timing) -> None:
        self.ran.append(block)

    def render(self, run: Run, results: list[engine.Result]) -> int:
        args, out, store, env, spent = run.args, run.out, self.store_, self.env, run.spent
        spent["cells"], t0 = time.perf_counter() - self.t0, time.perf_counter()
        # the records of this plan, in plan order; with --resume also the kept records of other plans
        records = [r for r, _ in results]
        outputs = {i: o for i, (_, o) in enumerate(results) if o is not None}
        mine = {r.key for r in records}
        records += [r for r in store.records if r.key not in mine]
        if args.save_arrays or args.resume:
            saved_outputs(out, records, outputs)
        fill_vs_reference(records, outputs, run.cells)
        for r in records:
            store.put(r)
        store.save()
        render(out, env, records, outputs, plots=not args.no_plots, clean=not args.resume)
        spent["tables and pictures"] = time.perf_counter() - t0
        sitting_run.end(env)        # a publish part's end check
        env["phases"] = {"run": spent, "cells": phases.cell_parts(self.ran)}
        store.save()                # the run's parts beside its records
        print("\n".join(console.closing(records, env, args.verbose, args.wide)))
        print(phases.summary_line(spent, env["phases"]["cells"], len(self.ran)))
        print(f"wrote {store.path}, results.csv, results.md" + ("" if args.no_plots else ", plots/"))
        against = versus.block(records, env, out, args.against, args.quick)
        if against:
            print("\n".join(["", *against]))
        missing = [r for r, _ in results if args.save_arrays and r.status in ("ok", "mismatch")
                   and not arrays_saved(out, r)]
        if missing:
            print(f"error: the arrays of {len(missing)} cells are missing (first: "
                  f"{array_file(out, missing[0].identity)}); rerun with --resume --save-arrays", file=sys.stderr)
        bad = missing or any(r.status in ("mismatch", "error") for r in records)
        return options.EXIT_FAIL if bad else options.EXIT_OK


__all__ = ["add_arguments", "run"]
