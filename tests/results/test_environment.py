"""A run's environment (compare.results.environment): one typed object from ``collect`` to the
stored ``runs`` and back, the JSON unchanged (keys, their order, keys this version does not name)."""
from __future__ import annotations

import json
import re
from pathlib import Path

from compare.measuring import environment
from compare.results import records
from compare.results.environment import RunEnvironment, machine, same_machine
from compare.results.store import Store, run_environments

ROOT = Path(__file__).resolve().parents[2]
# the order collect gives its first keys in (a run stored before 2026-12-02 lacks cpu_id)
COLLECTED = ("created", "hostname", "os", "cpu", "cpu_id", "cores", "memory_gib", "gpus", "cuda_toolkit", "python", "packages",
             "git_commit", "git_dirty", "command")


def test_every_key_the_store_checks_is_a_typed_field() -> None:
    assert set(records.RUN.fields) <= set(RunEnvironment.__annotations__)
    assert RunEnvironment.__required_keys__ == frozenset()       # older files may lack any key


def test_collect_gives_the_typed_environment_in_the_stored_order() -> None:
    env = environment.collect(["run", "saxpy"])
    assert [k for k in env if k != "git_dirty_paths"] == list(COLLECTED)
    assert set(env) <= set(RunEnvironment.__annotations__)
    assert env["command"] == "python -m compare run saxpy" and isinstance(env["cores"], int)
    assert all(set(g) == {"name", "driver", "memory"} for g in env["gpus"])
    assert environment.run_stamp(env) == {"created": env["created"], "commit": env["git_commit"] or None,
                                          "dirty": env["git_dirty"]}


def test_a_stored_run_is_typed_once_read_and_saved_byte_for_byte(tmp_path: Path) -> None:
    """Keys in an unusual order and keys this version does not name come back as they were."""
    run = {"hostname": "h", "created": "2026-01-01T00:00:00+00:00", "a_later_key": {"x": [1, 2]}, "cores": 4,
           "gpus": [{"name": "G", "driver": "1", "memory": "2 MiB"}], "git_dirty": None,
           "hardware": {"cpu": {"copy_bytes_per_s": 1e10, "copy_how": "test", "copy_curve": [[1, 2.5]]}}}
    text = json.dumps({"format_version": 2, "suite": "run", "runs": [run], "records": [], "analysis": {}}, indent=1)
    path = tmp_path / "results.json"
    path.write_text(text)
    store = Store.read(path)
    env = store.runs[0]
    assert list(env) == list(run) and env.get("cores") == 4 and env.get("git_dirty") is None
    assert (env.get("hardware") or {})["cpu"].get("copy_bytes_per_s") == 1e10
    store.save()
    assert path.read_text() == text


def test_every_stored_run_reads_as_an_environment() -> None:
    for path in sorted((ROOT / "docs" / "results").glob("*/results.json")):
        for env in (e for run in Store.read(path).runs for e in run_environments(run)):
            assert isinstance(env.get("packages", {}), dict) and all(isinstance(g["name"], str)
                                                                    for g in env.get("gpus") or [])


def test_a_machine_is_its_gpu_models_else_its_cpu_model() -> None:
    h200x2 = {"cpu": "Xeon", "gpus": [{"name": "NVIDIA H200"}, {"name": "NVIDIA H200"}]}
    assert machine(h200x2) == "NVIDIA H200 x2"
    assert machine({"cpu": "AMD EPYC", "gpus": []}) == "AMD EPYC"
    assert machine({"cpu": "Other", "gpus": [{"name": "NVIDIA H100 80GB HBM3"}]}) == "NVIDIA H100 80GB HBM3"
    assert machine({}) == "?"
    # the processor's family and model where recorded; a GPU machine is its GPUs whatever its CPU
    assert machine({"cpu": "AMD EPYC", "cpu_id": "family 26, model 2, stepping 1"}) == \
        "AMD EPYC (family 26, model 2, stepping 1)"
    assert machine({**h200x2, "cpu_id": "family 6, model 143, stepping 8"}) == "NVIDIA H200 x2"


def test_same_machine_needs_the_processor_where_both_recorded_it() -> None:
    new, other, old = ({"cpu": "AMD EPYC", "cpu_id": c} for c in ("family 26, model 2, stepping 1",
                                                                  "family 25, model 17, stepping 1", ""))
    assert same_machine(new, new) and same_machine(new, old) and same_machine(old, other)
    assert not same_machine(new, other) and not same_machine(old, {"cpu": "Intel Xeon"})


def test_collect_names_the_processor() -> None:
    got = environment.cpu_id()
    assert got == "" or re.fullmatch(r"family \S+, model \S+, stepping \S+", got), got
    assert environment.collect()["cpu_id"] == got


def test_a_runs_tree_state_reads_alike_on_every_page() -> None:
    """``tree_state``: clean only for a checked commit (False); a run that did not record it, or a
    copy not checked, is not called clean."""
    from compare.results.environment import tree_state
    assert [tree_state(d) for d in (False, True, None)] == ["", "dirty tree", "tree state unknown"]
