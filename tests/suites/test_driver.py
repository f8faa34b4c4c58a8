"""The one driver (compare/suites/driver.py): every suite is a ``Suite`` run by ``drive``, in one order."""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import pytest

from compare.suites import driver, publish, run as run_suite
from compare import options
from compare.options import UsageError
from compare.results.record import Record
from compare.suites import stress as stress_suite
from compare.suites import sweep as sweep_suite


class Recorder(driver.Suite):
    """A suite that runs no cell and notes every step the driver takes."""
    timed = False

    def __init__(self, refuse_at: str | None = None) -> None:
        self.steps: list[str] = []
        self.refuse_at = refuse_at

    def note(self, step: str) -> None:
        self.steps.append(step)
        if step == self.refuse_at:
            raise UsageError(f"refused at {step}")

    def plan(self, args: argparse.Namespace) -> list[driver.Planned[str]]:
        self.note("plan")
        return [driver.Planned(None, "unit")]

    def check_output(self, args: argparse.Namespace) -> None:
        self.note("check_output")

    def check_runnable(self, run: driver.Run, blocked: list[Any]) -> None:
        self.note("check_runnable")

    def preflight(self, run: driver.Run) -> None:
        self.note("preflight")

    def disk_need(self, run: driver.Run) -> float:
        self.note("disk_need")
        return 0.0

    def open(self, run: driver.Run) -> None:
        self.note("open")
        assert (run.out / ".compare.running.lock").exists()        # opened under the lock

    def execute(self, run: driver.Run) -> list[Any]:
        self.note("execute")
        return []

    def render(self, run: driver.Run, results: list[Any]) -> int:
        self.note("render")
        return options.EXIT_OK


def test_drive_takes_every_step_once_in_order(tmp_path: Path) -> None:
    suite = Recorder()
    args = argparse.Namespace(out=str(tmp_path / "out"))
    assert driver.drive(suite, args, ["x"]) == options.EXIT_OK
    assert suite.steps == ["plan", "check_output", "check_runnable", "preflight", "disk_need", "open",
                           "execute", "render"]
    assert not (tmp_path / "out" / ".compare.running.lock").exists()       # released


@pytest.mark.parametrize("step", ["plan", "check_output", "check_runnable", "preflight", "disk_need"])
def test_a_refusal_before_the_claim_writes_nothing(tmp_path: Path, step: str) -> None:
    suite = Recorder(refuse_at=step)
    with pytest.raises(UsageError):
        driver.drive(suite, argparse.Namespace(out=str(tmp_path / "out")), ["x"])
    assert not (tmp_path / "out").exists()
    assert "open" not in suite.steps


def test_every_suite_is_a_suite_and_publish_a_command() -> None:
    assert issubclass(run_suite.RunSuite, driver.Suite)
    assert issubclass(sweep_suite.SweepSuite, driver.Suite)
    assert issubclass(stress_suite.StressSuite, driver.Suite)
    assert issubclass(publish.Publish, driver.Command) and not issubclass(publish.Publish, driver.Suite)
    assert not stress_suite.StressSuite.timed      # stress figures are not timings: no --processes


def test_every_timed_suite_takes_processes() -> None:
    for add in (run_suite.add_arguments, sweep_suite.add_arguments):
        p = options.Parser()
        add(p)
        known = {a for action in p._actions for a in action.option_strings}
        assert "--processes" in known


class OneSaxpy(driver.Suite):
    """A timed suite of one tiny saxpy cell on NumPy, keeping its records itself (no store)."""
    timed = True

    def __init__(self) -> None:
        self.repeats: list[Any] = []

    def plan(self, args: argparse.Namespace) -> list[driver.Planned[None]]:
        from compare.spec import Cell
        return [driver.Planned(Cell.make(scenario="saxpy", backend="numpy", device="cpu", precision="float32",
                                         quick=True, repeat=3, min_time=0.0), None)]

    def check_output(self, args: argparse.Namespace) -> None:
        pass

    def on_repeat(self, block: Any) -> None:
        self.repeats.append(block)

    def seed(self) -> int:
        return 7

    def render(self, run: driver.Run, results: list[Any]) -> int:
        self.results = results
        return options.EXIT_OK


def test_the_driver_runs_the_repeat_processes_in_rounds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """--processes 2: the engine runs the plan once, the driver the second process; the record
    keeps both processes' figures, and ``on_repeat`` sees the repeat process's time block."""
    from compare.running import engine, repeats
    rounds: list[tuple[int, str | int, int]] = []
    real = repeats.run_rounds

    def spy(first: Any, processes: Any, seed: int, time_one: Any, on_round: Any, **kw: Any) -> Any:
        rounds.append((len(first), processes, seed))
        return real(first, processes, seed, time_one, on_round, **kw)
    monkeypatch.setattr(repeats, "run_rounds", spy)
    once: list[Any] = []
    real_cells = engine.run_cells
    monkeypatch.setattr(engine, "run_cells", lambda *a, **k: once.append(k) or real_cells(*a, **k))
    suite = OneSaxpy()
    args = argparse.Namespace(out=str(tmp_path / "out"), timeout=300, processes=2)
    assert driver.drive(suite, args, ["x"]) == options.EXIT_OK
    [(rec, _)] = suite.results
    assert rec.status == "ok" and len(once) == 1 and "processes" not in once[0]
    assert rounds == [(1, 2, 7)]
    block = rec.time["processes"]
    assert block["count"] == 2 and len(block["latency"]["values"]) == 2
    assert len(block["first_result"]["values"]) == 2
    assert len(suite.repeats) == 1 and "phases" in suite.repeats[0]


def test_every_subcommand_is_a_command_class_dispatched_alike() -> None:
    """compare/cli.py: one typed table of Command classes (list and report included), each
    instantiated afresh per invocation; a module's functions become one through module_command."""
    from compare import cli
    from compare.suites.listing import Listing
    from compare.suites.report import Report
    table = cli.commands()
    assert list(table) == cli.known_commands() and list(table)[:3] == ["list", "all", "run"]
    assert all(isinstance(c, type) and issubclass(c, driver.Command) for c in table.values())
    assert table["list"] is Listing and table["report"] is Report and table["all"] is run_suite.RunSuite
    assert table["publish"] is publish.Publish
    assert Listing.summary() == "scenarios, backends, devices (and why one is unavailable)"
    assert publish.Publish.summary() == (publish.__doc__ or "").strip().splitlines()[0]
    assert table["sweep"].summary() == (sweep_suite.__doc__ or "").strip().splitlines()[0]
    seen: list[tuple[Any, list[str]]] = []

    class Module:
        """a module-like command: its docstring's first line is its help"""
        @staticmethod
        def add_arguments(p: argparse.ArgumentParser) -> None:
            p.add_argument("--flag", action="store_true")

        @staticmethod
        def run(args: argparse.Namespace, argv: list[str]) -> int:
            seen.append((args.flag, argv))
            return 3
    command = driver.module_command(Module)
    p = options.Parser()
    command.add_arguments(p)
    assert command().run(p.parse_args(["--flag"]), ["x", "--flag"]) == 3 and seen == [(True, ["x", "--flag"])]
    assert command.summary() == "a module-like command: its docstring's first line is its help"


def test_overlapped_repeat_rounds_keep_the_rounds_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """--overlap with --processes: each repeat round's workers set up side by side
    (overlap.run_overlapped, every cell timed alone) in the round's seeded order, and every cell's
    record keeps every process's figures."""
    from compare.running import overlap
    from compare.spec import Cell
    calls: list[tuple[list[str], bool, int]] = []
    real = overlap.run_overlapped

    def spy(plan: list[Any], timeout: Any, on_result: Any, ahead: int, **kw: Any) -> None:
        calls.append(([c.variant for c in plan], kw.get("ordered", False), ahead))
        assert all(not c.check and not c.save_outputs for c in plan)     # repeat processes
        real(plan, timeout, on_result, ahead, **kw)
    monkeypatch.setattr(overlap, "run_overlapped", spy)
    cell = Cell.make(scenario="saxpy", backend="numpy", device="cpu", precision="float32", quick=True,
                     repeat=3, min_time=0.0, cache="warm")
    plan = [cell, dataclasses.replace(cell, params=dataclasses.replace(cell.params, n=cell.params.n + 1))]
    from compare.running import cells as cells_
    done = [(Record.from_json({**cells_.run(c, 300)[0], **c.identity()}), None) for c in plan]
    driver.more_processes(plan, done, [0, 1], 3, 7, 300.0, ahead=1)
    assert len(calls) == 2 and all(ordered and ahead == 1 and len(v) == 2 for v, ordered, ahead in calls)
    for rec, _ in done:
        block = rec.time["processes"]
        assert block["count"] == 3 and len(block["latency"]["values"]) == 3


def test_the_sitting_says_why_it_stops(capsys):
    import time
    from compare.running import repeats
    fits = repeats.within(time.perf_counter() + 100.0, 1500.0)
    assert fits(10.0) and not fits(1000.0)
    assert "no more processes: a round takes about 1000 s" in capsys.readouterr().err


def test_a_non_default_variant_is_cold_in_its_first_process_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """--processes: a non-default variant's first process fills a kept-caches directory
    (``Cell.cache_dir``) that its later processes start from, so its first result is one value;
    the default variant's first ``repeats.COLD`` processes are cold, the 3rd keeps its caches. The
    engine and the workers are fakes that fill a directory the first time a process names it."""
    from compare.running import cells as cells_, engine, repeats
    from compare.spec import Cell
    filled: set[str] = set()
    seen: dict[str, list[str]] = {"default": [], "compile": []}     # each process's cache_dir, in order

    def worker(c: Cell) -> dict[str, Any]:
        seen[c.variant].append(c.cache_dir)
        state = "kept" if c.cache_dir in filled else "cold"
        filled.update({c.cache_dir} - {""})
        return {**c.identity(), "status": "ok", "reason": "", "error": {"vs_oracle": 0.0, "tolerance": 1.0},
                "time": {"first_call_s": 1.0 + len(seen[c.variant]), "setup_s": 0.5, "median_s": 1e-5,
                         "iqr_s": 0.0, "min_s": 1e-5, "repeats": 3, "cache": f"{state}: FAKE"}}
    monkeypatch.setattr(engine, "run_cells", lambda plan, **k: [(Record.from_json(worker(c)), None) for c in plan])
    monkeypatch.setattr(cells_, "run", lambda c, timeout: (worker(c), None))
    cell = Cell.make(scenario="saxpy", backend="torch", device="cpu", precision="float32", quick=True)
    plan = [cell, dataclasses.replace(cell, variant="compile")]
    run = driver.Run(argparse.Namespace(timeout=300, processes=4), ["x"], [driver.Planned(c, None) for c in plan])
    [(default, _), (compiled, _)] = driver.run_cells(OneSaxpy(), run)
    once, kept = seen["compile"], seen["default"]
    assert once[0] != "" and once == [once[0]] * 4                  # from process 1 on, one directory
    assert kept[:2] == ["", ""] and kept[2] != "" and kept[2:] == [kept[2]] * 2 and kept[2] != once[0]
    assert len(compiled.time["processes"]["first_result"]["values"]) == 1
    assert len(default.time["processes"]["first_result"]["values"]) == repeats.COLD
    assert compiled.time["processes"]["count"] == default.time["processes"]["count"] == 4
    assert driver.cold_once(plan, None) == plan            # one process, or a Dask worker: as planned


def test_a_cell_whose_timings_no_row_ranks_is_capped_at_its_first_results_processes() -> None:
    """``caps``: the projectile at its defaults on CUDA (no CUDA row ranks those timings): the
    default variant ``repeats.COLD`` processes (the first-call row), any other 1; on the CPU, or at
    another size, or another scenario, no cap. A fast-math variant (never ranked) 1 anywhere."""
    from compare.running import repeats
    from compare.spec import Cell
    cuda = Cell.make(scenario="projectile", backend="torch", device="cuda", precision="float32")
    plan = [cuda, dataclasses.replace(cuda, variant="compile"),
            dataclasses.replace(cuda, device="cpu"), dataclasses.replace(cuda, device="cpu", variant="compile"),
            Cell.make(scenario="projectile", backend="torch", device="cuda", precision="float32", params={"batch": 2}),
            Cell.make(scenario="projectile", backend="torch", device="cuda", precision="float32", quick=True),
            Cell.make(scenario="saxpy", backend="torch", device="cuda", precision="float32"),
            Cell.make(scenario="saxpy", backend="numba", device="cpu", precision="float32", variant="fastmath"),
            Cell.make(scenario="projectile", backend="taichi", device="cuda", precision="float32", variant="fastmath"),
            Cell.make(scenario="sdf", backend="drjit", device="cuda", precision="float32", variant="fastmath",
                      params={"width": 64})]
    assert driver.caps(plan) == {0: repeats.COLD, 1: 1, 7: 1, 8: 1, 9: 1}


def test_the_driver_stops_a_capped_cell_and_says_why(monkeypatch: pytest.MonkeyPatch, capsys: Any) -> None:
    """--processes 4 over fake workers: the projectile at its defaults on CUDA stops at its cap
    (default variant: ``repeats.COLD`` processes, its three first results; another variant: its
    first process alone), its block says why; a SAXPY cell runs all four."""
    from compare.running import cells as cells_, engine, repeats
    from compare.spec import Cell
    count: dict[tuple[str, str], int] = {}
    dirs: dict[tuple[str, str], list[str]] = {}

    def worker(c: Cell) -> dict[str, Any]:
        k = (c.scenario, c.variant)
        count[k] = count.get(k, 0) + 1
        dirs.setdefault(k, []).append(c.cache_dir)
        return {**c.identity(), "status": "ok", "reason": "", "error": {"vs_oracle": 0.0, "tolerance": 1.0},
                "time": {"first_call_s": float(count[k]), "setup_s": 0.5, "median_s": 1e-5, "iqr_s": 0.0,
                         "min_s": 1e-5, "repeats": 3, "cache": "cold: FAKE"}}
    monkeypatch.setattr(engine, "run_cells", lambda plan, **k: [(Record.from_json(worker(c)), None) for c in plan])
    monkeypatch.setattr(cells_, "run", lambda c, timeout: (worker(c), None))
    monkeypatch.setattr(engine, "availability", lambda names: {})
    proj = Cell.make(scenario="projectile", backend="torch", device="cuda", precision="float32")
    plan = [proj, dataclasses.replace(proj, variant="compile"),
            Cell.make(scenario="saxpy", backend="torch", device="cuda", precision="float32")]
    run = driver.Run(argparse.Namespace(timeout=300, processes=4), ["x"], [driver.Planned(c, None) for c in plan])
    [(default, _), (other, _), (saxpy, _)] = driver.run_cells(OneSaxpy(), run)
    assert count == {("projectile", "default"): repeats.COLD, ("projectile", "compile"): 1, ("saxpy", "default"): 4}
    d, o, s = (r.time["processes"] for r in (default, other, saxpy))
    assert d["count"] == repeats.COLD and len(d["first_result"]["values"]) == repeats.COLD
    assert d["capped"] == o["capped"] == driver.CAPPED and "capped" not in s
    assert o["count"] == 1 and "latency" not in o and s["count"] == 4
    assert "2 cells capped (no row ranks its timings (a fast-math variant, or its scenario at its defaults on this device)" \
        in capsys.readouterr().err
    assert dirs[("projectile", "compile")] == [""]       # its one process keeps no caches: none would read them
