"""``python -m compare publish``: the plan, --list, bad usage, the log, skipping and rerunning parts."""
from __future__ import annotations

import datetime
import json
import os
import shutil
import subprocess
import sys
import time

import pytest

from conftest import ROOT
from shared_runs import QUICK_RUN, numpy_quick_run
from compare import cli, options
from compare.measuring import environment
from compare.suites import publish

pytestmark = pytest.mark.cli
# --allow-dirty: a developer's checkout may hold uncommitted changes; --allow-noisy-sitting: a test
# machine is busy with other tests (each guard has its own test)
NUMPY = ["--backends", "numpy", "--devices", "cpu", "--quick", "--allow-dirty", "--allow-noisy-sitting"]


def compare(*args):
    return subprocess.run([sys.executable, "-m", "compare", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)


def names(parts):
    return [p.name for p in parts]


def test_list_prints_every_part_and_its_command_and_writes_nothing(tmp_path):
    # a real process (the other tests call compare.cli.main: the parts still run as subprocesses)
    out = tmp_path / "m"
    p = compare("publish", "--out", str(out), "--list", *NUMPY)
    assert p.returncode == 0, p.stderr
    assert not out.exists()
    lines = p.stdout.splitlines()
    listed = [ln.split(":")[0].strip() for ln in lines[1::2]]
    parts, _ = publish.plan(str(out), ["cpu"], "numpy", quick=True)
    assert listed == names(parts)
    assert listed[0] == "all" and listed[-2:] == ["stress-merge", "site"]
    for state, cmd in zip(lines[1::2], lines[2::2]):
        assert state.endswith(": to run") and cmd.strip().startswith("python -m compare ")
    assert f"python -m compare site {out} --out {out / 'report'}" in p.stdout


@pytest.mark.parametrize("args,needle", [
    (("--part", "bogus"), "unknown part 'bogus'"),
    (("--part", "all,all"), "names 'all' twice"),
    (("--part", ","), "--part is empty"),
    (("--devices", "tpu"), "unknown device"),
    (("--backends", "fortran"), "unknown backend"),
    (("--budget", "0"), "--budget"),
    (("--timeout", "nan"), "--timeout"),
    (("--frobnicate",), "unrecognized"),
])
def test_bad_usage_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, args, needle):
    out = tmp_path / "m"
    assert cli.main(["publish", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0], err
    assert not out.exists()


def test_empty_out_and_a_bad_log_are_refused(tmp_path, capsys):
    assert cli.main(["publish", "--out", ""]) == 2
    assert "--out is empty" in capsys.readouterr().err
    (tmp_path / "publish.json").write_text('{"format_version": 7}')
    assert cli.main(["publish", "--out", str(tmp_path), *NUMPY]) == 2
    assert "not a publish log" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["publish.json"]


def test_a_folder_of_another_machine_is_refused(tmp_path, capsys):
    """One store, one machine: a publish log naming another machine's host refuses the run."""
    from compare.suites import publish_log
    log = {"format_version": 1, "parts": [{"name": "all", "argv": ["all"], "started": "t", "seconds": 1.0,
                                           "exit_code": 0, "host": {"cpu": "Some Other CPU", "gpus": []}}]}
    (tmp_path / "publish.json").write_text(json.dumps(log))
    assert cli.main(["publish", "--out", str(tmp_path), *NUMPY]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds runs of Some Other CPU, not of this machine" in err[0], err
    assert sorted(os.listdir(tmp_path)) == ["publish.json"]
    log["parts"][0]["host"] = publish_log.host()                   # this machine's own log: allowed
    assert publish_log.other_machine(log, publish_log.host()) is None


def test_a_dirty_checkout_is_refused_unless_allowed(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(environment, "dirty_paths", lambda: ["compare/x.py", "b.py", "c.py", "d.py"])
    monkeypatch.delenv("COMPARE_GIT_COMMIT", raising=False)
    out = tmp_path / "m"
    args = ["publish", "--out", str(out), "--backends", "numpy", "--devices", "cpu", "--quick"]
    assert cli.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "uncommitted changes (compare/x.py, b.py, c.py and 1 more)" in err[0], err
    assert "--allow-dirty" in err[0] and not out.exists()
    assert cli.main([*args, "--list"]) == 0 and not out.exists()      # listing runs nothing
    publish.refuse_dirty(allowed=True)                                 # allowed: the runs name the paths
    monkeypatch.setenv("COMPARE_GIT_COMMIT", "abc1234")                # a copied tree names its commit
    monkeypatch.delenv("COMPARE_GIT_TREE", raising=False)
    monkeypatch.setattr(environment, "files_digest", lambda commit=None: "mine")
    publish.refuse_dirty(allowed=False)                                # ... alone: taken on its word
    monkeypatch.setenv("COMPARE_GIT_TREE", "mine")                     # ... and its files' digest
    publish.refuse_dirty(allowed=False)
    monkeypatch.setenv("COMPARE_GIT_TREE", "theirs")                   # the copy is not that commit's
    with pytest.raises(options.UsageError, match="differ from COMPARE_GIT_TREE"):
        publish.refuse_dirty(allowed=False)
    publish.refuse_dirty(allowed=True)


def test_a_run_names_its_uncommitted_paths(monkeypatch):
    monkeypatch.delenv("COMPARE_GIT_COMMIT", raising=False)
    monkeypatch.setattr(environment, "own_repository", lambda: True)     # also from a copy without .git
    many = [f"f{i}.py" for i in range(environment.DIRTY_PATHS_KEPT + 5)]
    monkeypatch.setattr(environment, "dirty_paths", lambda: many)
    env = environment.collect([])
    assert env["git_dirty"] is True and env["git_dirty_paths"][:2] == ["f0.py", "f1.py"]
    assert env["git_dirty_paths"][-1] == "... and 5 more"
    monkeypatch.setattr(environment, "dirty_paths", lambda: [])
    assert environment.collect([])["git_dirty"] is False and "git_dirty_paths" not in environment.collect([])
    monkeypatch.setenv("COMPARE_GIT_COMMIT", "abc1234")
    assert environment.collect([])["git_dirty"] is None


def test_merge_takes_the_stress_files_that_exist_oldest_first(tmp_path):
    parts, _ = publish.plan(str(tmp_path), ["cpu"], "numpy", quick=True)
    merge = next(p for p in parts if p.name == "stress-merge")
    assert publish.merge_argv(merge) is None                 # no experiment has run
    files = [tmp_path / "stress-parts" / n / "stress.json" for n in ("b", "a")] + [tmp_path / "stress.json"]
    for i, f in enumerate(files):
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text("{}")
        os.utime(f, (time.time() - 100 + i, time.time() - 100 + i))
    argv = publish.merge_argv(merge)
    assert list(argv[argv.index("--merge") + 1:argv.index("--out")]) == list(map(str, files))


def run_publish(monkeypatch, capsys, out, keep, *extra):
    """compare.cli.main's publish with the plan cut to ``keep`` (the parts still run as subprocesses)."""
    real = publish.plan
    monkeypatch.setattr(publish, "plan", lambda *a, **k: (
        [p for p in real(*a, **k)[0] if p.name in keep], []))
    code = cli.main(["publish", "--out", str(out), *NUMPY, *extra])
    return code, capsys.readouterr().out


def publish_logs_skips_and_reruns(monkeypatch, capsys, out, keep, named, stale):
    """Publish ``keep`` (in plan order): each part logged; a second call skips them all; ``--part
    named`` reruns it; the next call reruns only the parts it made stale."""
    code, text = run_publish(monkeypatch, capsys, out, set(keep))
    assert code == 0, text
    for n in keep:
        assert f"] {n}: python -m compare " in text               # each command printed before it runs
    log = json.loads((out / "publish.json").read_text())
    assert log["format_version"] == 1 and [e["name"] for e in log["parts"]] == list(keep)
    for e in log["parts"]:
        assert e["exit_code"] == 0 and e["seconds"] >= 0 and e["interrupted"] is False
        assert datetime.datetime.fromisoformat(e["started"]).utcoffset() == datetime.timedelta(0)
        assert {"hostname", "cores", "gpus"} <= set(e["host"])
    for f in ("stress.json", "report/index.html"):
        assert (out / f).is_file(), f
    stress = json.loads((out / "stress.json").read_text())
    assert {r["experiment"] for r in stress["analysis"]["rows"]} == {"ulps"}

    code, text = run_publish(monkeypatch, capsys, out, set(keep))     # all done: nothing runs
    assert code == 0 and text.count(", skipped") == len(keep) and "python -m compare" not in text
    assert len(json.loads((out / "publish.json").read_text())["parts"]) == len(keep)

    code, text = run_publish(monkeypatch, capsys, out, set(keep), "--part", named)   # named: reruns
    assert code == 0 and f"] {named}: python -m compare " in text
    code, text = run_publish(monkeypatch, capsys, out, set(keep))     # what it made stale, only that
    assert code == 0 and text.count("python -m compare") == len(stale), text
    assert all(f"] {n}: python -m compare " in text for n in stale)
    assert [e["name"] for e in json.loads((out / "publish.json").read_text())["parts"]][len(keep):] == \
        [named, *stale]
    return log


def test_a_real_publish_logs_skips_done_parts_and_reruns_one(tmp_path, monkeypatch, capsys):
    """The cheapest parts (no sweep: stress ulps, the merge, the site): a rerun merge makes the site
    stale; the long tier's runs a sweep too (test_a_real_publish_with_a_sweep_resumes_it_without_duplicates)."""
    publish_logs_skips_and_reruns(monkeypatch, capsys, tmp_path / "m", ("stress-ulps", "stress-merge", "site"),
                                  "stress-merge", ("site",))


@pytest.mark.slow
def test_a_real_publish_with_a_sweep_resumes_it_without_duplicates(tmp_path, monkeypatch, capsys):
    out = tmp_path / "m"
    log = publish_logs_skips_and_reruns(monkeypatch, capsys, out, ("bandwidth", "stress-ulps", "stress-merge", "site"),
                                        "bandwidth", ("site",))
    assert log["parts"][0]["argv"][:2] == ["sweep", "bandwidth"] and "--resume" in log["parts"][0]["argv"]
    records = json.loads((out / "sweep.json").read_text())["records"]
    assert len(records) == len({json.dumps([r["scenario"], r["params"], r["tags"]]) for r in records})


def test_budget_interrupts_the_running_part_and_the_next_call_resumes_it(tmp_path, capsys):
    out = tmp_path / "m"
    code = cli.main(["publish", "--out", str(out), *NUMPY, "--part", "all", "--budget", "1"])
    got = capsys.readouterr()
    assert code == 3, got.out + got.err
    assert "--budget spent during all" in got.err
    (e,) = json.loads((out / "publish.json").read_text())["parts"]
    assert e["name"] == "all" and e["interrupted"] is True
    assert cli.main(["publish", "--out", str(out), *NUMPY, "--list", "--part", "all"]) == 0
    assert "all: to run (interrupted)" in capsys.readouterr().out


@QUICK_RUN
def test_large_parts_share_results_json_with_other_sizes(tmp_path, tmp_path_factory, capsys):
    """``run --resume`` with another --set n keeps the records already there (publish relies on it):
    a large part run into a copy of the quick run of tests/shared_runs.py (cells of its quick sizes)."""
    p, run = numpy_quick_run(tmp_path_factory)
    assert p.returncode == 0, p.stdout + p.stderr
    out = tmp_path / "m"
    shutil.copytree(run, out)
    before = json.loads((out / "results.json").read_text())["records"]
    code = cli.main(["publish", "--out", str(out), *NUMPY, "--part", "large-cpu-saxpy16"])
    assert code == 0, capsys.readouterr()
    records = json.loads((out / "results.json").read_text())["records"]
    assert records[:len(before)] == before                          # kept as they were
    (large,) = records[len(before):]
    assert (large["scenario"], large["params"]["n"], large["precision"], large["status"]) == \
        ("saxpy", 2**16, "float32", "ok")


def test_a_noisy_sitting_is_refused_unless_allowed(tmp_path, monkeypatch, capsys):
    """The sitting check before a measuring part (faked noisy floor): exit 2 in one line, nothing
    started or logged; --allow-noisy-sitting runs the part and hands it the check and its reasons."""
    from compare.measuring import sitting, sitting_quiet
    from compare.running import sitting_run
    bad = sitting.SittingCheck.of(device="cpu", cores=2, host_cores=2, copy_bytes_per_s=1e10, others_cores=0.0)
    checks: list = []
    monkeypatch.setattr(sitting_run, "check_sitting", lambda device: (checks.append(device), bad)[1])
    monkeypatch.setattr(publish, "RECHECK_S", 0.0)
    monkeypatch.setattr(sitting_quiet, "quiet_for", lambda check, folders: sitting.Quiet(
        kind="AMD EPYC", runs=8, copy_bytes_per_s=3e10))
    ran: list = []
    monkeypatch.setattr(publish, "execute", lambda argv, deadline, tick, handed=None: (ran.append(handed), (0, None))[1])
    out = tmp_path / "m"
    argv = ["publish", "--out", str(out), "--part", "all", *[a for a in NUMPY if a != "--allow-noisy-sitting"]]
    assert cli.main(argv) == options.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: a noisy sitting: copy 10 GB/s, 1/3.00 of the quiet 30 GB/s")
    assert "(against 8 stored runs of AMD EPYC; 3 checks 0 s apart)" in err and "--allow-noisy-sitting" in err
    assert ran == [] and not (out / "publish.json").exists() and len(checks) == publish.RECHECKS + 1
    checks.clear()
    assert cli.main([*argv, "--allow-noisy-sitting"]) == options.EXIT_OK
    assert "publish: sitting: copy 10 GB/s" in capsys.readouterr().out
    (handed,) = ran
    got = json.loads(handed)
    assert got["start"] == bad.to_json() and got["reasons"][0].startswith("copy 10 GB/s") and got["quiet"]["runs"] == 8
    assert sitting_run.ENV == "COMPARE_SITTING" and len(checks) == 1     # let through: no second check


def test_a_sitting_noisy_for_a_moment_is_checked_again_before_a_refusal(tmp_path, monkeypatch, capsys):
    """A slow copy right after a heavy part that recovers: the recheck's quiet sitting is handed on,
    each noisy check printed (the publish log says what was seen)."""
    from compare.measuring import sitting, sitting_quiet
    from compare.running import sitting_run
    bad, good = (sitting.SittingCheck.of(device="cpu", cores=2, host_cores=2, copy_bytes_per_s=c, others_cores=0.0)
                 for c in (1e10, 2.9e10))
    seen = iter([bad, good])
    monkeypatch.setattr(sitting_run, "check_sitting", lambda device: next(seen))
    monkeypatch.setattr(publish, "RECHECK_S", 0.0)
    monkeypatch.setattr(sitting_quiet, "quiet_for", lambda check, folders: sitting.Quiet(
        kind="AMD EPYC", runs=8, copy_bytes_per_s=3e10))
    ran: list = []
    monkeypatch.setattr(publish, "execute", lambda argv, deadline, tick, handed=None: (ran.append(handed), (0, None))[1])
    argv = ["publish", "--out", str(tmp_path / "m"), "--part", "all", *[a for a in NUMPY if a != "--allow-noisy-sitting"]]
    assert cli.main(argv) == options.EXIT_OK
    out = capsys.readouterr().out
    assert "publish: sitting: copy 10 GB/s" in out and "checking again in 0 s (1 of 2)" in out
    assert "publish: sitting: copy 29 GB/s" in out and out.rstrip().count("checking again") == 1
    (handed,) = ran
    got = json.loads(handed)
    assert got["start"] == good.to_json() and got["reasons"] == []
