"""compare/suites/stamping.py: the one-off that stamps published sweep and stress records stored
before those suites stamped them, each from the evidence its store keeps, never guessed."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import scenarios
from compare.results.record import Record
from compare.results.stamps import is_unknown, unstamped
from compare.results.store import Store
from compare.suites import stamping

T0 = "2026-11-28T03:00:00+00:00"
T1 = "2026-11-28T03:10:00+00:00"
EPOCH0 = stamping.epoch(T0)
assert EPOCH0 is not None


def params(scenario: str, **over: object) -> dict:
    return dataclasses.asdict(scenarios.get(scenario).params(over))


def cell(scenario: str = "saxpy", backend: str = "numpy", precision: str = "float32", variant: str = "default",
         tags: dict | None = None, window: list | None = None, hardware: dict | None = None, **over: object) -> Record:
    time = {"first_call_s": 0.1, "median_s": 0.01, "iqr_s": 0.0, "min_s": 0.01, "repeats": 1}
    if window is not None:
        time["window"] = window
    return Record(scenario=scenario, backend=backend, device="cpu", precision=precision, status="ok",
                  variant=variant, params=params(scenario, **over), tags=tags, time=time, hardware=hardware)


def env(created: str, command: str, commit: str = "abc1234", **more: object) -> dict:
    return {"created": created, "command": f"python -m compare {command}", "git_commit": commit, "git_dirty": False,
            **more}


def no_windows(commit: str | None) -> bool | None:
    return None


def test_a_sweep_record_goes_to_the_one_run_whose_yardstick_and_command_it_has(tmp_path: Path) -> None:
    hw_a = {"copy_bytes_per_s": 1.0e10, "launch_latency_s": 1e-5}
    hw_b = {"copy_bytes_per_s": 1.1e10, "launch_latency_s": 1e-5}
    runs = [env(T0, "sweep bandwidth --devices cpu", hardware={"cpu": hw_a}),
            env(T1, "sweep bandwidth --devices cpu --resume", hardware={"cpu": hw_b}),
            env(T1.replace("10", "20"), "sweep scaling --devices cpu", hardware={"cpu": hw_a})]
    judged = cell(tags={"sweep": "bandwidth"}, hardware=hw_b)
    unjudged = cell(tags={"sweep": "bandwidth"}, n=1000)         # both bandwidth runs fit it
    scaling = cell(tags={"sweep": "scaling"}, n=2000)
    stamped_before = cell(tags={"sweep": "bandwidth"}, n=3000).replace(
        run={"created": T0, "commit": "abc1234", "dirty": False})
    store = Store(tmp_path / "sweep.json", "sweep", runs, [judged, unjudged, scaling, stamped_before])
    assert stamping.restamp(store, no_windows) == (1, 2, 1)
    got = {r.key: r.run for r in store.records}
    assert got[judged.key] == {"created": T1, "commit": "abc1234", "dirty": False}
    assert got[scaling.key]["created"] == runs[2]["created"]
    assert is_unknown(got[unjudged.key]) and "allows 2 of its runs" in got[unjudged.key]["note"]
    assert got[stamped_before.key] == stamped_before.run
    assert unstamped(store.records, store.runs) == []


def stress_store(tmp_path: Path, records: list[Record]) -> Store:
    a = env(T0, "stress --devices cpu --backends all --only ulps --quick")
    b = env(T1, "stress --devices cpu --backends all --only races --quick")
    prov = {"ulps": {"command": a["command"], "created": T0, "git_commit": "abc1234", "backends": ["numpy"]},
            "races": {"command": b["command"], "created": T1, "git_commit": "abc1234", "backends": ["numpy"]}}
    merged = {**b, "merged_from": ["a", "b"], "environments": [a, b]}
    store = Store(tmp_path / "stress.json", "stress", [merged], records)
    store.analysis = {"provenance": prov, "rows": [], "series": {}}
    return store


def test_a_stress_record_goes_to_the_run_whose_experiment_makes_its_cell(tmp_path: Path) -> None:
    ulps = cell(n=100_003, inputs="random", seed=3)                  # an ulps case (quick)
    races = cell("sdf", width=203, height=97)                        # the races case (quick sizes)
    store = stress_store(tmp_path, [ulps, races])
    assert stamping.experiments_of(ulps, quick=True) == {"ulps"} and stamping.experiments_of(races, True) == {"races"}
    assert stamping.restamp(store, no_windows) == (0, 2, 0)
    assert [r.run["created"] for r in store.records] == [T0, T1]


def test_a_timed_window_places_a_record_in_the_publish_part_that_was_running(tmp_path: Path) -> None:
    """Both runs made the cell (same experiment cases): only the window tells, and the publish
    log's parts bound each run; a window past every part, or a run whose commit wrote no
    windows, leaves the run unknown."""
    (tmp_path / "publish.json").write_text(json.dumps({"format_version": 1, "parts": [
        {"name": "stress-a", "argv": ["stress", "--devices", "cpu", "--backends", "all", "--only", "ulps", "--quick"],
         "started": T0, "seconds": 60.0},
        {"name": "stress-b", "argv": ["stress", "--devices", "cpu", "--backends", "all", "--only", "races", "--quick"],
         "started": T1, "seconds": 60.0}]}))
    both = cell(n=100_003, inputs="linspace")       # an ulps case and the races case alike
    assert stamping.experiments_of(both, quick=True) == {"ulps", "races"}
    first = both.replace(time={**both.time.to_json(), "window": [EPOCH0 + 10, EPOCH0 + 11]})
    store = stress_store(tmp_path, [first])
    assert stamping.restamp(store, no_windows) == (0, 1, 0) and store.records[0].run["created"] == T0
    late = both.replace(time={**both.time.to_json(), "window": [EPOCH0 + 300, EPOCH0 + 301]})   # between parts
    store = stress_store(tmp_path, [late])
    assert stamping.restamp(store, no_windows) == (0, 0, 1)
    store = stress_store(tmp_path, [first])
    assert stamping.restamp(store, lambda commit: False) == (0, 0, 1)    # that commit wrote no window
    assert "no run of the store agrees" in store.records[0].run["note"]


def test_a_particles_inf_row_says_which_steps_its_search_ran(tmp_path: Path) -> None:
    """A bounce-1.05 cell at a long rollout's steps is a particles-long cell unless the run's
    particles-inf row lists those steps among the ones its search ran."""
    rec = cell("particles", "numpy", n=256, steps=10_000, bounce=1.05)
    assert stamping.experiments_of(rec, quick=True) == {"particles-long", "particles-inf"}
    long_ = env(T0, "stress --devices cpu --only particles-long --quick")
    inf = env(T1, "stress --devices cpu --only particles-inf --quick")
    prov = {"particles-long": {**long_, "backends": ["numpy"]}, "particles-inf": {**inf, "backends": ["numpy"]}}
    row = {"experiment": "particles-inf", "backend": "numpy", "device": "cpu", "precision": "float32",
           "setting": "bounce=1.05, n=256", "figure": "first step", "value": 6670, "verdict": "unstable",
           "detail": "located with 2 cells at steps [6669, 6670]"}
    for steps, want in (([6669, 6670], T0), ([10000, 6670], None)):
        store = Store(tmp_path / "stress.json", "stress", [long_, inf], [rec])
        store.analysis = {"provenance": prov, "series": {},
                          "rows": [{**row, "detail": f"located with 2 cells at steps {steps}"}]}
        stamping.restamp(store, no_windows)
        assert store.records[0].run["created"] == want if want else is_unknown(store.records[0].run)
