from __future__ import annotations

import contextlib
import functools
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import adversarial  # noqa: E402
from compare import cells  # noqa: E402


# The spec keys of a cell run for its outputs, not its timings: reuse compiled kernels (framework
# default caches) and skip the throughput regime. Timing runs start cold (tests/test_cli.py).
CORRECTNESS = {"cache": "warm", "throughput": False}


@functools.cache
def availability(backend: str) -> dict[str, str | None]:
    return cells.probe(backend)["available"]


def require_device(backend: str, device: str) -> None:
    why = availability(backend).get(device, f"unknown device {device}")
    if why:
        pytest.skip(f"{backend}/{device}: {why}")


def pytest_runtest_setup(item):
    adversarial.start()


# ---- pytest-xdist: workers, tests that must run alone, the tallies gathered from the workers ----
@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: one worker per usable core; the long tier (``-m slow``) runs in this process,
    one test at a time, as it always has (its tests fill disks and watch memory peaks)."""
    markexpr = config.getoption("markexpr") or ""
    if "slow" in markexpr.replace("not slow", ""):
        return 0
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


# Modules whose tests share work through a module-scoped fixture or a module-level cache of cells
# (a command run once, one worker process for many cases): under xdist each runs whole on one
# worker, in file order, as without xdist, so that work is done once. Every other test is
# scheduled on its own. A module missing here still passes; its shared work is done once per worker
# (xdist's xdist_group marks would say this per test, but its loadgroup ignores them on pytest 9.2:
# pytest-dev/pytest-xdist#1386).
ONE_WORKER = ("test_cli.py", "test_contract.py", "test_jax.py", "test_measure.py", "test_parity.py",
              "test_site.py", "test_site_browser.py", "test_torch.py", "test_triton.py")


@pytest.hookimpl(optionalhook=True, tryfirst=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """``-n``'s default distribution (load): every test on its own, but ONE_WORKER modules whole.
    Units start largest first (xdist's loadscope order), so the long modules do not end last."""
    if config.getvalue("dist") != "load":
        return None                       # a --dist the user chose
    from xdist.scheduler import LoadScopeScheduling

    class Scheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return path if path.rsplit("/", 1)[-1] in ONE_WORKER else nodeid

    return Scheduling(config, log)


@contextlib.contextmanager
def _turn(item: pytest.Item) -> Iterator[None]:
    """Under xdist, a test marked ``alone`` runs while no other test does: every test holds a
    shared lock on a file of the run's temporary root, an ``alone`` test the exclusive one. A gate
    taken first (exclusively by an ``alone`` test, in passing by the others) keeps the others'
    next tests from starving a waiting ``alone`` test."""
    basetemp = getattr(item.config.option, "basetemp", None)
    if not os.environ.get("PYTEST_XDIST_WORKER") or not basetemp:
        yield
        return
    import fcntl
    alone = item.get_closest_marker("alone") is not None
    mode = fcntl.LOCK_EX if alone else fcntl.LOCK_SH
    root = Path(basetemp).parent          # each worker's basetemp is <run's root>/<worker id>
    with open(root / "alone.gate", "a") as gate, open(root / "alone.lock", "a") as lock:
        fcntl.flock(gate, mode)
        fcntl.flock(lock, mode)
        if not alone:
            fcntl.flock(gate, fcntl.LOCK_UN)
        yield                             # closing the files releases the locks


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Any:
    with _turn(item):
        return (yield)


def _figures() -> dict | None:
    return getattr(sys.modules.get("test_reliability"), "FIGURES", None)


def _merge(into: dict, part: dict) -> None:
    """Add one worker's counts into ``into``: numbers add, lists extend, dicts merge, text stays."""
    for k, v in part.items():
        if isinstance(v, dict):
            _merge(into.setdefault(k, {}), v)
        elif isinstance(v, list):
            into[k] = into.get(k, []) + v
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            into[k] = into.get(k, 0) + v
        else:
            into[k] = v


_GATHERED: dict[str, Any] = {}         # the workers' reliability figures (controller, under xdist)


def pytest_sessionfinish(session: pytest.Session) -> None:
    """An xdist worker hands its tallies to the controller, which prints them."""
    out = getattr(session.config, "workeroutput", None)
    if out is not None:
        out["adversarial"] = adversarial.state()
        out["figures"] = _figures() or {}


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: Any) -> None:
    got = getattr(node, "workeroutput", None) or {}
    adversarial.merge(got.get("adversarial") or {})
    _merge(_GATHERED, got.get("figures") or {})


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """The adversarial tally (tests/adversarial.py): each hostile-input or fault test's cases."""
    outcome = yield
    if item.path.stem not in adversarial.MODULES:
        return
    rep = outcome.get_result()
    if rep.skipped:
        if call.when in ("setup", "call"):
            reason = rep.longrepr[2] if isinstance(rep.longrepr, tuple) else str(rep.longrepr)
            adversarial.skipped(reason.removeprefix("Skipped: "))
    elif call.when == "call" or (call.when == "setup" and rep.failed):
        adversarial.finish(item.name, rep.passed)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """The adversarial tally and tests/test_reliability.py's figures (docs/reliability.md)."""
    tr = terminalreporter
    figures = _figures() or _GATHERED
    tally = adversarial.lines()
    if tally:
        tr.write_sep("-", "adversarial tally")
        for line in tally:
            tr.write_line(line)
    if not figures or not (figures["tried"] or figures["json_fuzzed"] or figures["faults"]):
        return
    tr.write_sep("-", "reliability figures")
    tr.write_line(f"bad inputs tried: {figures['tried']}, refused cleanly (exit 2, one line, no traceback, "
                  f"nothing written): {figures['refused']}")
    tr.write_line("  by test: " + ", ".join(f"{k.removeprefix('test_')} {v}" for k, v in figures["by_test"].items()))
    tr.write_line(f"JSON documents fuzzed through Store.read: {figures['json_fuzzed']}, "
                  f"read or refused in one line: {figures['json_clean']}")
    tr.write_line(f"faults survived: {len(figures['faults'])} ({'; '.join(figures['faults'])})")
    tr.write_line(f"records lost: {figures['records_lost']}")
    if figures.get("memory"):
        tr.write_line(f"memory estimate against measured peaks: {figures['memory']}")


def run_cell(backend: str, scenario: str, precision: str, params: dict, device: str = "cpu",
             variant: str = "default") -> tuple[dict, dict]:
    """One cell through the real worker path (its own process), at quick sizes; ok or mismatch.
    Correctness only, as the parity suite: warm kernel caches and no throughput regime (the
    command-line tests run cells cold)."""
    from compare import cells
    require_device(backend, device)
    spec = {"scenario": scenario, "backend": backend, "device": device, "precision": precision,
            "params": params, "quick": True, "repeat": 1, "min_time": 0.0, "variant": variant,
            **CORRECTNESS}
    record, outputs = cells.run(spec, timeout=600)
    assert record["status"] in ("ok", "mismatch"), \
        f"{record.get('reason')}\n{record.get('traceback', '')}"
    return record, outputs


def run_script(backend: str, body: str, device: str = "cpu") -> dict:
    """Run ``body`` in a fresh interpreter (its own framework init, which is process-global);
    ``DEVICE`` is defined for it, and it prints RESULT<json>."""
    import json
    import subprocess
    import sys
    import textwrap

    from compare import cells
    require_device(backend, device)
    code = "import json\nimport backends, scenarios\nDEVICE = %r\n" % device + textwrap.dedent(body)
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    return json.loads(line[len("RESULT"):])

