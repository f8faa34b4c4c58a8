"""The run suite (compare/suites/run.py, ``all | run S... | <S>``): its plan (every chosen scenario
x backend x device x precision x variant, parameters resolved once), its refusals before anything
is written, each port's distance to the reference backend, and its store that rewrites the tables
with every save."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

import backends
import scenarios
from compare import cli, options
from compare.options import UsageError
from compare.results.record import Record
from compare.spec import BUSY_TAG
from compare.suites import run as run_suite
from compare.suites.driver import Planned
from scenarios.base import ParamError

ARGV = ["run", "saxpy", "--backends", "numpy", "--devices", "cpu", "--quick"]


def planned(*extra: str) -> list[Planned[None]]:
    argv = [*ARGV, *extra]
    return run_suite.RunSuite().plan(cli.parse(argv))


def test_the_plan_of_one_scenario_on_one_backend_and_device() -> None:
    plan = planned("--repeat", "4", "--min-time", "0.5")
    assert all(isinstance(p, Planned) and p.extra is None for p in plan)
    cells = [p.cell for p in plan]
    assert [(c.scenario, c.backend, str(c.device), c.variant) for c in cells] == [("saxpy", "numpy", "cpu", "default")] * len(cells)
    assert [str(c.precision) for c in cells] == options.selection(cli.parse(ARGV))["precisions"]
    quick = scenarios.get("saxpy").params(quick=True)
    assert all(c.params == quick and c.repeat == 4 and c.min_time == 0.5 and not c.tags for c in cells)
    assert all(c.params is cells[0].params for c in cells)        # resolved once, one object for every cell


def test_set_and_precision_reach_every_cell() -> None:
    [p] = planned("--precision", "float64", "--set", "n=333", "--save-arrays", "--check-sample", "5")
    c = p.cell
    assert c is not None and str(c.precision) == "float64" and c.params.n == 333
    assert c.save_inputs and c.check_sample == 5


def test_busy_times_each_cpu_cell_idle_and_then_with_busy_cores() -> None:
    plan = planned("--precision", "float32", "--busy", "3")
    assert [p.cell.tags for p in plan if p.cell] == [{BUSY_TAG: 0}, {BUSY_TAG: 3}]
    assert len({p.cell.key() for p in plan if p.cell}) == 2


def test_a_variant_is_planned_only_where_its_backend_has_it() -> None:
    plan = run_suite.RunSuite().plan(cli.parse(["run", "saxpy", "sdf", "--backends", "numpy,cupy", "--devices", "cpu",
                                                "--precision", "float32", "--variants", "default,vector", "--quick"]))
    assert [(p.cell.scenario, p.cell.backend, p.cell.variant) for p in plan if p.cell] == [
        ("saxpy", "numpy", "default"), ("saxpy", "cupy", "default"), ("saxpy", "cupy", "vector"),
        ("sdf", "numpy", "default"), ("sdf", "cupy", "default")]


def test_a_plan_with_nothing_to_run_is_refused() -> None:
    with pytest.raises(UsageError, match="nothing to run: no chosen backend"):
        run_suite.RunSuite().plan(cli.parse(["run", "sdf", "--backends", "cupy", "--variants", "vector", "--quick"]))
    with pytest.raises(ParamError, match="unknown parameter 'no_such_knob'"):
        planned("--set", "no_such_knob=1")


def test_the_chosen_scenarios_of_all_run_and_a_scenario_word() -> None:
    ns = argparse.Namespace
    assert [s.name for s in run_suite.chosen_scenarios(ns(command="all"))] == \
        [s.name for s in scenarios.SCENARIOS.values() if s.in_all]
    assert [s.name for s in run_suite.chosen_scenarios(ns(command="run", scenarios=["sdf", "saxpy"]))] == ["sdf", "saxpy"]
    assert [s.name for s in run_suite.chosen_scenarios(ns(command="launch"))] == ["launch"]
    with pytest.raises(UsageError):
        run_suite.chosen_scenarios(ns(command="run", scenarios=["saxpy", "saxpy"]))


def test_earlier_results_are_kept_or_replaced_never_silently(tmp_path: Path) -> None:
    ns = lambda **kw: argparse.Namespace(out=str(tmp_path), **{"resume": False, "force": False, **kw})  # noqa: E731
    run_suite.refuse_overwrite(ns())                              # nothing there yet
    (tmp_path / "results.json").write_text("{}")
    with pytest.raises(UsageError, match="holds an earlier run's results"):
        run_suite.refuse_overwrite(ns())
    with pytest.raises(UsageError, match="give one"):
        run_suite.refuse_overwrite(ns(resume=True, force=True))
    run_suite.refuse_overwrite(ns(resume=True))
    run_suite.refuse_overwrite(ns(force=True))


def record(backend: str, device: str = "cpu", n: int = 8) -> Record:
    return Record(scenario="saxpy", backend=backend, device=device, precision="float32", params={"n": n},
                  status="ok", reason="", time={"median_s": 1e-4}, error={"vs_oracle": 0.0})


def test_each_port_gets_its_distance_to_the_reference_on_its_device_or_another() -> None:
    ref = backends.reference()
    port = next(b for b in backends.BACKENDS if b != ref)
    recs = [record(port), record(ref, "cuda"), record(ref), record(port, "cuda"), record(port, n=9)]
    out = {i: {"out": np.ones(r.params["n"], np.float32)} for i, r in enumerate(recs)}
    out[0]["out"][0] = 1.5
    run_suite.fill_vs_reference(recs, out)
    assert recs[0].error["reference"] == ref and recs[0].error["vs_reference"] > 0
    assert recs[0].error["vs_reference_device"] == "cpu"                 # the same device first
    assert recs[3].error["vs_reference"] == 0 and recs[3].error["vs_reference_device"] == "cuda"
    assert "vs_reference" not in recs[4].error                          # no reference at its size


def test_the_run_store_rewrites_the_tables_with_every_save(tmp_path: Path) -> None:
    store = run_suite.RunStore.open(tmp_path, "run", keep=False)
    store.env = {"command": "test"}
    store.put(record(backends.reference()))
    store.save()
    assert json.loads((tmp_path / "results.json").read_text())["records"][0]["status"] == "ok"
    assert (tmp_path / "results.csv").is_file() and (tmp_path / "results.md").is_file()
    first = (tmp_path / "results.csv").read_text()
    store.put(record("numpy"))
    store.save()
    assert len((tmp_path / "results.csv").read_text().splitlines()) == len(first.splitlines()) + 1
    key = store.records[1].key
    assert store.done(key)
    store.rerun = frozenset({key})                   # --resume --save-arrays: its arrays are missing
    assert not store.done(key)


def test_a_run_stores_every_planned_cell_and_its_tables(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The whole suite in this process (the driver, one worker per cell): results.json holds one
    record per planned cell, judged and stamped with this run, beside results.csv and .md."""
    argv = [*ARGV, "--precision", "float32", "--repeat", "1", "--min-time", "0", "--no-plots", "--out", str(tmp_path)]
    args = cli.parse(argv)
    assert run_suite.run(args, argv) == options.EXIT_OK
    doc = json.loads((tmp_path / "results.json").read_text())
    [rec] = doc["records"]
    assert (rec["scenario"], rec["backend"], rec["status"]) == ("saxpy", "numpy", "ok")
    assert rec["params"] == json.loads(json.dumps(planned("--precision", "float32")[0].cell.identity()))["params"]
    assert rec["run"]["created"] == doc["runs"][0]["created"]
    assert (tmp_path / "results.csv").is_file() and (tmp_path / "results.md").is_file()
    assert "wrote" in capsys.readouterr().out
    with pytest.raises(UsageError, match="earlier run's results"):      # and a second run must say keep or replace
        run_suite.run(cli.parse(argv), argv)
