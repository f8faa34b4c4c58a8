"""The one driver every suite runs on: probe -> what can run -> preflight -> claim -> lock -> run -> render.

A suite (``suites.run.RunSuite`` for all/<scenario>, ``suites.sweep.SweepSuite``,
``suites.stress.StressSuite``) is a ``Suite``: a command (its arguments, then its run) whose
capabilities are methods with harmless defaults. It plans a list of ``Planned`` (a cell and the
suite's own extra) and says what to do with each record (``on_record``) and how to render; ``drive``
owns the sequence between, once: probe the backends, refuse a plan nothing of which can run,
preflight memory (the suite's own refusal) and disk (``disk_need``), connect the cluster client
(--scheduler), claim and lock --out, run the cells on ``engine.run_cells`` with the repeats across
processes (--processes) of every timed suite, and render. ``publish`` runs no cell: it is a
``Command`` (arguments, then run) that shares the claim and lock (``claim``).
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any, Callable, ClassVar, Generic, NamedTuple, Protocol, TypeVar

import numpy as np

import scenarios
from backends.base import DEFAULT_VARIANT, UNRANKED_VARIANTS
from compare.running import cells as cells_, engine, lifeline, overlap, repeats, scaleout
from compare import options
from compare.planning import outdir, preflight
from compare.planning.calibrate import Refusal
from compare.running.lock import DirectoryLock
from compare.options import UsageError
from compare.results.record import Record
from compare.results.record_parts import Processes, Timing
from compare.results.store import Store
from compare.results.environment import RunEnvironment
from compare.spec import Cell, key
from compare.suites import family_caches

X = TypeVar("X")
Blocked = tuple[str, str] | None
Outputs = dict[str, np.ndarray]


class Planned(NamedTuple, Generic[X]):
    """One unit of a suite's plan: its cell and the suite's own extra (a sweep point's converged
    reference; None where a suite has none). A stress experiment makes its cells as it runs (from
    what its earlier cells found), so its units carry no cell: ``cell`` None, the experiment's
    name as the extra."""
    cell: Cell | None
    extra: X


@dataclasses.dataclass
class Run:
    """One invocation, as the driver fills it in: what the suite's later steps read."""
    args: argparse.Namespace
    argv: list[str]
    planned: list[Planned[Any]]
    probes: engine.Probes = dataclasses.field(default_factory=dict)
    runnable: list[Cell] = dataclasses.field(default_factory=list)
    judged: Refusal | None = None             # the preflight's reason not to start a cell
    spent: dict[str, float] = dataclasses.field(default_factory=dict)   # seconds per part (compare.measuring.phases)
    client: Any = None                         # the Dask client of --scheduler
    out: Path = Path(".")
    ahead: int = 0                             # --overlap, resolved (compare.running.overlap)
    began: float = 0.0                         # time.perf_counter() at its start (--sitting)

    @property
    def cells(self) -> list[Cell]:
        return [p.cell for p in self.planned if p.cell is not None]

    def protocol(self) -> RunEnvironment:
        """How this run times its cells, for its entry in the store's ``runs`` (every timed suite)."""
        env = RunEnvironment(overlap=self.ahead, overlap_beside=overlap.beside(self.ahead),
                             processes=getattr(self.args, "processes", 1))
        if getattr(self.args, "sitting", None) is not None:
            env["sitting_s"] = self.args.sitting
        return env


class Command:
    """A subcommand: its arguments, then its run (an instance per invocation: ``compare.cli``)."""
    help: ClassVar[str | None] = None     # its line in ``--help`` (None: its module's docstring's first)

    @classmethod
    def summary(cls) -> str:
        """The line ``python -m compare --help`` lists it by."""
        return cls.help if cls.help is not None else first_line(sys.modules[cls.__module__].__doc__)

    @staticmethod
    def add_arguments(p: argparse.ArgumentParser) -> None:
        """The command's options (its own, and the shared ones of compare/options.py)."""

    def run(self, args: argparse.Namespace, argv: list[str]) -> int:
        raise NotImplementedError


def first_line(doc: str | None) -> str:
    return (doc or "").strip().splitlines()[0] if (doc or "").strip() else ""


class CommandModule(Protocol):
    """A module that defines a subcommand as functions: ``add_arguments``, ``run`` (and its
    docstring, whose first line ``--help`` shows)."""
    def add_arguments(self, p: argparse.ArgumentParser) -> None: ...
    def run(self, args: argparse.Namespace, argv: list[str]) -> int: ...


def module_command(module: CommandModule) -> type[Command]:
    """The ``Command`` of a module that defines one as functions: the sweep and stress suites'
    (whose ``run`` also routes ``sweep report`` and ``stress --merge``) and the site's ``site``
    and ``agree`` (a stage below this one: they cannot subclass ``Command``)."""
    class ModuleCommand(Command):
        help = first_line(module.__doc__)

        @staticmethod
        def add_arguments(p: argparse.ArgumentParser) -> None:
            module.add_arguments(p)

        def run(self, args: argparse.Namespace, argv: list[str]) -> int:
            return module.run(args, argv)
    return ModuleCommand


class Suite(Command):
    """A command that runs cells through ``drive``. Override what differs; every default is harmless."""
    timed = True        # its figures are timings: --overlap and --processes apply

    def run(self, args: argparse.Namespace, argv: list[str]) -> int:
        return drive(self, args, argv)

    # ---- before anything is written (a refusal is exit 2) -----------------------------------
    def plan(self, args: argparse.Namespace) -> list[Planned[Any]]:
        """Every unit of the run, validated (bad input never reaches a worker or --out)."""
        raise NotImplementedError

    def check_output(self, args: argparse.Namespace) -> None:
        """Read-only refusals of --out and the files in it (a bad store to resume)."""
        outdir.check_output(args.out)

    def backends(self, run: Run) -> list[str]:
        """The backends to probe."""
        return list(dict.fromkeys(c.backend for c in run.cells))

    def refusal(self, run: Run) -> Refusal | None:
        """The suite's own reason, known before the probes' results, not to start a cell."""
        return None

    def check_runnable(self, run: Run, blocked: list[Blocked]) -> None:
        """Refuse a plan nothing of which can run."""
        nothing_to_run(run.cells, blocked)

    def preflight(self, run: Run) -> Refusal | None:
        """Memory checks of the runnable cells; the returned refusal is the engine's ``refuse``."""
        return None

    def disk_need(self, run: Run) -> float:
        """Bytes the run may write into --out (a store rewritten through a temporary: twice)."""
        return 2 * preflight.RECORD_BYTES * len(run.runnable) + preflight.PAGE_BYTES

    def what(self, args: argparse.Namespace) -> str:
        return "the results"

    # ---- under the lock ----------------------------------------------------------------------
    def open(self, run: Run) -> None:
        """Open the store and its run's environment, before any cell runs."""

    def execute(self, run: Run) -> list[engine.Result]:
        """Run the plan (default: its cells on the engine)."""
        return run_cells(self, run)

    def on_record(self, i: int, rec: Record, outputs: Outputs | None) -> Record:
        """Every finished cell's record, mapped to the one the store keeps: the one place a
        suite adds to a record (a new record: records are immutable) or reports it."""
        return rec

    def on_repeat(self, block: Timing) -> None:
        """The ``time`` block of every repeat process (--processes)."""

    def shares_caches(self, cell: Cell) -> bool:
        """Whether ``cell`` may start from the kernel caches an earlier cell of its family kept
        (``family_caches``): only where no page reads its first call."""
        return False

    # a check of a record's JSON, as the worker wrote it (its process's record.json) or a file keeps it
    @property
    def check(self) -> Callable[[dict[str, Any]], str | None] | None:
        """Its records' own check beyond the common schema (its store's format, ``compare.results.formats``)."""
        from compare.results.formats import FORMATS
        store = self.store()
        return FORMATS[store.suite].record_problem if store is not None else None

    def seed(self) -> int:
        """The seed of the repeats' interleaved rounds (the run's environment's)."""
        return 0

    def store(self) -> Store | None:
        """The store that keeps every record as it arrives (None: the suite keeps them)."""
        return None

    def render(self, run: Run, results: list[engine.Result]) -> int:
        """Tables, pages and plots from what ran; returns the exit status."""
        return options.EXIT_OK


def nothing_to_run(cells: list[Cell], blocked: list[Blocked]) -> None:
    """Refuse a plan whose every cell would be skipped (no chosen backend can use a chosen
    device): exit 2 with the first reason, before anything is written."""
    if cells and all(b is not None and b[0] == "skipped" for b in blocked):
        c, why = cells[0], blocked[0][1]         # type: ignore[index]
        raise UsageError(f"nothing to run: every one of the {len(cells)} cells would be skipped "
                         f"(first: {c.backend} on {c.device}: {why})")


def claim(args: argparse.Namespace, need: float, what: str = "the results", client: Any = None,
          lock_name: str | None = None) -> tuple[Path, DirectoryLock]:
    """--out checked, with room for ``need`` bytes, created and locked by this driver; a
    refusal closes the cluster client first (no lock and no --out left behind). ``lock_name``:
    a lock beside the writers' one (``outdir.claim_output``)."""
    try:
        out, lock = outdir.claim_output(args.out, need, what, lock_name)
        return out, lock
    except UsageError:
        if client is not None:
            client.close()
        raise


def drive(suite: Suite, args: argparse.Namespace, argv: list[str]) -> int:
    """The suite's run, every step once, in this order: refusals first (nothing written), then
    the claim of --out and, under its lock, the run and the render."""
    run = Run(args, argv, suite.plan(args))
    suite.check_output(args)
    began = run.began = time.perf_counter()
    run.probes = engine.availability(suite.backends(run))
    run.spent["probes"] = time.perf_counter() - began
    refuse = suite.refusal(run)
    blocked = [engine.not_runnable(c, run.probes) or (refuse(c) if refuse else None) for c in run.cells]
    run.runnable = [c for c, b in zip(run.cells, blocked) if not b]
    suite.check_runnable(run, blocked)
    run.judged = suite.preflight(run)
    need = suite.disk_need(run)
    # connected before the claim: an unreachable scheduler leaves no lock and no --out behind
    scheduler = getattr(args, "scheduler", None)
    run.client = scaleout.client(scheduler) if scheduler else None
    run.out, lock = claim(args, need, suite.what(args), run.client)
    run.ahead = overlap.ahead(args) if suite.timed else 0
    with lock:
        suite.open(run)
        return suite.render(run, suite.execute(run))


def run_cells(suite: Suite, run: Run) -> list[engine.Result]:
    """The plan's cells on the engine: locally one at a time (or overlapped set-ups), or on the
    cluster's workers; each record through ``suite.on_record`` into the suite's store; then the
    repeats across processes (--processes), for every timed suite alike (``more_processes``)."""
    cells, args = run.cells, run.args
    runner = scaleout.runner(run.client, args.timeout, cells, run.probes) if run.client is not None else None
    store, resume = suite.store(), getattr(args, "resume", False)
    processes = getattr(args, "processes", 1) if suite.timed else 1
    seed = suite.seed()
    # the cells --resume keeps run in no process, the first or a repeat one
    kept = {i for i, c in enumerate(cells) if store is not None and resume and store.done(key(c.identity()))}
    many = repeats.plan(processes)[1] > 1
    # the kernel caches a cell's processes, or a family's cells, keep (Cell.cache_dir); none on a
    # Dask worker: another host
    share = not many and runner is None and any(suite.shares_caches(c) for c in cells)
    keeps = lifeline.temp_dir("kept-caches-") if (many and runner is None) or share else contextlib.nullcontext(None)
    capped = caps(cells)          # the same for the first processes, the short-kept line and the repeats
    with keeps as where:
        first = cold_once(cells, Path(where) if where is not None and many else None, capped)
        if share and where is not None:     # one process a cell: a sweep's curve shares its caches
            first = family_caches.share(first, Path(where), suite.shares_caches)
        results = engine.run_cells(first, timeout=args.timeout, probes=run.probes, runner=runner,
                                   store=store, resume=resume,
                                   on_record=suite.on_record, check=suite.check, refuse=run.judged, ahead=run.ahead,
                                   footprint=lambda c: preflight.cell_bytes(c)[0])
        if many:
            repeats.say_short({i: r.process_count for i in kept if store is not None and (r := store.get(
                key(cells[i].identity()))) is not None and r.status == "ok"}, processes, capped)
            ran = [i for i in range(len(cells)) if i not in kept]
            sitting = getattr(args, "sitting", None)
            more_processes(first, results, ran, processes, seed, args.timeout, runner, store, suite.on_repeat,
                           ahead=run.ahead, footprint=lambda c: preflight.cell_bytes(c)[0],
                           fits=None if sitting is None else repeats.within(run.began + sitting, sitting),
                           caches=Path(where) if where is not None else None, capped=capped)
    return results


def cold_once(cells: list[Cell], where: Path | None, capped: dict[int, int] | None = None) -> list[Cell]:
    """The cells as their first process runs them (--processes): a non-default variant's first
    process fills a directory of ``where`` (``Cell.cache_dir``) that its later processes start from,
    so it is cold once and its first result is that process's alone; the default variant's first
    ``repeats.COLD`` processes are cold (``more_processes``). Why: only the default's first result
    is published (the first-call row, the compile page: ``matrix.all_defaults``), and the other
    variants' cold compiles lengthen every cold round (docs/measurement.md, the matrix part).
    ``where`` None (one process, a Dask worker): every cell as planned; a cell ``caps`` stops after
    its first process keeps nothing (no later process would start from it); ``capped``: ``caps(cells)``."""
    alone = {i for i, n in (caps(cells) if capped is None else capped).items() if n == 1}
    return [dataclasses.replace(c, cache_dir=str(where / f"cell-{i}"))
            if where is not None and c.cache == "cold" and c.variant != DEFAULT_VARIANT and i not in alone else c
            for i, c in enumerate(cells)]


CAPPED = ("no row ranks its timings (a fast-math variant, or its scenario at its defaults on this device): "
          "the processes its first result needs")


def caps(cells: list[Cell]) -> dict[int, int]:
    """The most processes of each cell whose timings no published row ranks: those its first
    result needs. A fast-math variant (``UNRANKED_VARIANTS``: shown, never ranked) 1, anywhere; a
    scenario at its defaults on a device not in ``Scenario.timings_ranked_on``: ``repeats.COLD`` for
    the default variant (the first-call row), 1 for any other (``cold_once``). Why: processes that
    no figure reads lengthen the matrix part (docs/measurement.md, "The matrix part of publish")."""
    out = {}
    for i, c in enumerate(cells):
        if c.variant in UNRANKED_VARIANTS:
            out[i] = 1
        elif not scenarios.get(c.scenario).timings_ranked(c.params, c.device):
            out[i] = repeats.COLD if c.variant == DEFAULT_VARIANT else 1
    return out


def more_processes(plan: list[Cell], done: list[engine.Result], ran: list[int], processes: int | str,
                   seed: int, timeout: float, runner: Callable[[Cell], cells_.Result] | None = None,
                   store: Store | None = None, on_repeat: Callable[[Timing], None] | None = None,
                   ahead: int = 0, footprint: Callable[[Cell], float] | None = None,
                   fits: Callable[[float], bool] | None = None, caches: Path | None = None,
                   capped: dict[int, int] | None = None) -> None:
    """The repeat processes of every cell of ``ran`` whose first process finished ok, in seeded
    rounds (``compare.running.repeats.run_rounds``): each round's ``time.processes`` replaces the
    record's in ``done`` and in the store, saved once a round. ``on_repeat`` sees each repeat
    process's ``time`` block (its parts, for the run's summary). ``ahead`` > 0 (--overlap, local
    workers): a round's workers set up side by side, in the round's order, each timed alone
    (``compare.running.overlap``), as the first round's were. A cell of ``plan`` with a
    ``cache_dir`` (``cold_once``) kept its first process's caches there: its later processes start
    from them; the others' ``repeats.COLD``-th process keeps its caches in ``caches`` (None: a
    temporary directory of its own), for the processes after it. ``capped``: ``caps(plan)``, where known."""
    first = {i: got[0].time for i in ran if (got := done[i])[0].status == "ok" and got[0].time is not None}
    own = lifeline.temp_dir("kept-caches-") if caches is None else contextlib.nullcontext(str(caches))
    cold = {i: 1 if plan[i].cache_dir else repeats.COLD for i in first}     # processes with cold caches
    most = {i: n for i, n in (caps(plan) if capped is None else capped).items() if i in first}
    if most:
        print(f"  {len(most)} cells capped ({CAPPED})", file=sys.stderr, flush=True)

    def again(i: int, rnd: int) -> Cell:      # a repeat process: no check, no files, only the figures
        keep = (rnd >= cold[i] and rnd < most.get(i, rnd + 1) and runner is None   # a Dask worker: another host
                and plan[i].cache == "cold")
        where = plan[i].cache_dir or str(Path(root) / f"cell-{i}")
        return dataclasses.replace(plan[i], check=False, save_outputs=False, save_inputs=False,
                                   cache_dir=where if keep else "")

    def figures_of(rec: dict[str, Any]) -> Timing | None:       # the worker's record JSON
        t = Timing.from_json(rec["time"]) if rec.get("time") else None
        if on_repeat is not None and t is not None:
            on_repeat(t)
        return t if rec.get("status") == "ok" else None

    def time_round(order: list[int], rnd: int) -> list[Timing | None]:
        if runner is not None or ahead <= 0 or len(order) < 2:
            return [figures_of((runner(again(i, rnd)) if runner is not None else cells_.run(again(i, rnd), timeout))[0])
                    for i in order]
        got: dict[int, Timing | None] = {}
        overlap.run_overlapped([again(i, rnd) for i in order], timeout,
                               lambda k, result: got.__setitem__(k, figures_of(result[0])), ahead,
                               need=footprint, budget=overlap.memory_budget(), lane=engine.cell_lane,
                               ordered=True)
        return [got.get(k) for k in range(len(order))]

    started = [time.monotonic()]

    def on_round(blocks: dict[int, Processes]) -> None:
        count = max((b.count for b in blocks.values()), default=0)
        if count > 1:             # a block of one process: a cell capped there (``caps``), no round
            print(f"  process {count}: {len(blocks)} cells in {time.monotonic() - started[0]:.0f} s",
                  file=sys.stderr, flush=True)
        started[0] = time.monotonic()
        for i, block in blocks.items():
            rec, out = done[i]
            assert rec.time is not None           # a cell of ``first``: its first process timed it
            done[i] = (rec.replace(time=Timing.from_json({**rec.time, "processes": block})), out)
            if store is not None:
                store.put(done[i][0])
        if store is not None:
            store.save()
    with own as root:
        repeats.run_rounds(first, processes, seed, time_round, on_round, fits=fits, cold=cold,
                           most=most, capped=CAPPED)
