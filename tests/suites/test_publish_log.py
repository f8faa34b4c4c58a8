"""compare/suites/publish_log.py: publish.json, the progress log of a publish, and the state of
each part it gives (fast tier; the states test moved here from tests/suites/test_publish.py)."""
from __future__ import annotations

import os

import pytest

from compare.planning.publish_plan import Part
from compare.suites import publish_log


def test_states_of_the_log():
    part = Part("stress-ulps", ("stress", "--only", "ulps", "--out", "d/stress-parts/ulps"), resumes=False)
    sweep = Part("bandwidth", ("sweep", "bandwidth", "--resume", "--out", "d"))
    site = Part("site", ("site", "d", "--out", "d/report"), reads=("bandwidth", "stress-ulps"))

    def entry(p, code, argv=None, interrupted=False):
        return {"name": p.name, "argv": list(argv or p.argv), "exit_code": code, "interrupted": interrupted}
    log = {"format_version": 1, "parts": []}
    assert publish_log.state(sweep, log, "d") == "to run"
    log["parts"] += [entry(sweep, 1, [*sweep.argv, "--timeout", "5"])]       # --timeout aside
    assert publish_log.state(sweep, log, "d").startswith("done (exit 1")
    assert publish_log.state(sweep, log, os.path.abspath("d")).startswith("done")     # DIR spelled otherwise
    log["parts"] += [entry(sweep, 0, ["sweep", "bandwidth", "--backends", "numpy", "--out", "d"])]
    assert publish_log.state(sweep, log, "d").startswith("done")                  # another command's attempt
    log["parts"] += [entry(site, 0)]
    assert publish_log.state(site, log, "d") == "done"
    log["parts"] += [entry(part, 130, interrupted=True), entry(sweep, None), entry(sweep, -9)]
    assert publish_log.state(site, log, "d") == "to run (bandwidth, stress-ulps ran since)"
    assert publish_log.state(sweep, log, "d") == "to run (last attempt exited -9)"       # it resumes: retried
    assert publish_log.state(part, log, "d") == "to run (interrupted)"
    log["parts"] += [entry(part, None)]
    assert publish_log.state(part, log, "d").startswith("given up (cut off twice")        # it does not resume
    log["parts"] += [entry(part, 1, interrupted=True)]
    assert not publish_log.state(part, log, "d").startswith("done")


def test_no_log_is_an_empty_log_and_a_saved_one_reads_back(tmp_path):
    assert publish_log.load_log(tmp_path) == {"format_version": publish_log.FORMAT_VERSION, "parts": []}
    log = {"format_version": 1, "parts": [{"name": "all", "argv": ["all"], "started": publish_log.started(),
                                           "seconds": 1.5, "exit_code": None, "interrupted": False,
                                           "host": publish_log.host()}]}
    publish_log.save_log(tmp_path, log)
    assert publish_log.load_log(tmp_path) == log
    assert log["parts"][0]["started"].endswith("+00:00") and log["parts"][0]["host"]["cores"] >= 1


@pytest.mark.parametrize("text,needle", [
    ("not json", "cannot read"), ('{"format_version": 2, "parts": []}', "not a publish log of format 1"),
    ("[]", "not a publish log"), ('{"format_version": 1, "parts": {}}', "'parts' must be a list"),
    ('{"format_version": 1, "parts": [{"name": "all", "argv": [], "exit_code": "0"}]}', "'parts' must be a list"),
    ('{"format_version": 1, "parts": [{"name": 3, "argv": []}]}', "'parts' must be a list")])
def test_a_malformed_log_is_refused_in_one_line(tmp_path, text, needle):
    from compare.results.store import StoreError
    (tmp_path / publish_log.LOG).write_text(text)
    with pytest.raises(StoreError, match=needle) as exc:
        publish_log.load_log(tmp_path)
    assert "\n" not in str(exc.value)


def test_identity_ignores_the_timeout_and_spells_paths_under_dir_alike(tmp_path):
    out = str(tmp_path / "d")
    a = publish_log.identity(["sweep", "--timeout", "5", "--out", out, "--x", "y"], out)
    b = publish_log.identity(["sweep", "--out", os.path.join(out, "."), "--x", "y"], out)
    assert a == b == ["sweep", "--out", "DIR/.", "--x", "y"]
    assert publish_log.identity(["--out", str(tmp_path / "d" / "sub")], out) == ["--out", "DIR/sub"]


@pytest.mark.parametrize("entry,cut", [({"exit_code": 0}, False), ({"exit_code": 1}, False),
                                       ({"exit_code": None}, True), ({"exit_code": -9}, True),
                                       ({"exit_code": 0, "interrupted": True}, True), ({"exit_code": 130}, True)])
def test_cut_off(entry, cut):
    assert publish_log.cut_off(entry) is cut



def test_another_machine_in_the_log_is_found():
    log = {"format_version": 1, "parts": [{"name": "a", "argv": [], "host": {"cpu": "AMD EPYC", "gpus": []}},
                                          {"name": "b", "argv": []}]}        # an entry without a host: no machine
    assert publish_log.other_machine(log, {"cpu": "AMD EPYC", "gpus": []}) is None
    assert publish_log.other_machine(log, {"cpu": "Intel Xeon", "gpus": []}) == "AMD EPYC"


def test_a_processor_of_another_family_or_model_is_another_machine():
    """One model name ("AMD EPYC") can stand for several processors: where both hosts recorded
    their family and model, they must match; an entry made before they were recorded matches any."""
    zen5 = {"cpu": "AMD EPYC", "cpu_id": "family 26, model 2, stepping 1", "gpus": []}
    zen4 = {"cpu": "AMD EPYC", "cpu_id": "family 25, model 17, stepping 1", "gpus": []}
    log = {"format_version": 1, "parts": [{"name": "a", "argv": [], "host": zen4},
                                          {"name": "b", "argv": [], "host": {"cpu": "AMD EPYC", "gpus": []}}]}
    assert publish_log.other_machine(log, zen5) == "AMD EPYC (family 25, model 17, stepping 1)"
    assert publish_log.other_machine(log, zen4) is None
    assert publish_log.other_machine({"format_version": 1, "parts": log["parts"][1:]}, zen5) is None
    assert publish_log.host().get("cpu_id") is not None
