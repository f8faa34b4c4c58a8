from __future__ import annotations

import fcntl
import functools
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

# the tests' helper modules assert too: pytest's messages for their failures as for the tests'
pytest.register_assert_rewrite("hand_adjoint", "oracle_checks", "reliability_checks")

ROOT = Path(__file__).resolve().parent.parent
FAULTY = ROOT / "tests" / "extra_backends"    # COMPARE_BACKENDS_EXTRA: the tests' faulty backend
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import adversarial  # noqa: E402
import parallel  # noqa: E402
from compare.running import cells, engine  # noqa: E402
from compare.spec import Cell  # noqa: E402
from compare.suites import formats as suite_formats  # noqa: E402
# pytest-xdist's workers, groups and `alone` tests (tests/parallel.py)
from parallel import (pytest_collection_finish, pytest_configure, pytest_runtest_protocol,  # noqa: E402,F401
                      pytest_unconfigure, pytest_xdist_auto_num_workers, pytest_xdist_make_scheduler)

suite_formats.register()        # as the command line's start-up does: every results-file format


# The spec keys of a cell run for its outputs, not its timings: reuse compiled kernels (framework
# default caches) and skip the throughput regime. Timing runs start cold (tests/test_cli.py).
CORRECTNESS = {"cache": "warm", "throughput": False}


@functools.cache
def probe(backend: str) -> dict[str, Any]:
    """The backend's availability probe (its own process), once per test process."""
    return cells.probe(backend)


def availability(backend: str) -> dict[str, str | None]:
    return probe(backend)["available"]


def require_device(backend: str, device: str, precision: str | None = None) -> None:
    """Skip, saying why, where the backend cannot run on ``device`` (or in ``precision`` there)."""
    why = availability(backend).get(device, f"unknown device {device}")
    if why:
        pytest.skip(f"{backend}/{device}: {why}")
    import backends
    if precision and (why := backends.get(backend).precision_unavailable(precision, device)):
        pytest.skip(f"{backend}/{device}/{precision}: {why}")


def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config, items: list[pytest.Item]) -> None:
    """The parity suite first (a stable sort, the rest in their order): its worker processes run
    each backend's cells that the backend's own tests share, in one process per backend, device
    and precision, and those tests then find them run (run_cases), under xdist too (one
    xdist_group per backend: the order within a group is this one)."""
    items.sort(key=lambda item: item.path.name != "test_parity.py")


def pytest_runtest_setup(item):
    adversarial.start()
    memo = sys.modules.get("compare.render.chart_memo")
    if memo is not None:
        memo.recall_from_disk()         # a test's chart_memo.forget() lasts until it ends


def _figures() -> dict | None:
    """This process's reliability figures; none where no reliability test was imported (the
    xdist controller), which gathers the workers' instead."""
    return getattr(sys.modules.get("reliability_checks"), "FIGURES", None)


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
    parallel.merge(_GATHERED, got.get("figures") or {})


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
    """The adversarial tally and the reliability tests' figures (tests/reliability_checks.py)."""
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


@functools.cache
def published_store(path: Path) -> Any:
    """The store at ``path`` (docs/results' are seconds each to read), read once per test process,
    for tests that only read it; they carry ``PUBLISHED_STORES`` so that one worker reads each."""
    from compare.results.store import Store
    return Store.read(path)


PUBLISHED_STORES = pytest.mark.xdist_group("published-stores")


def run_cell(backend: str, scenario: str, precision: str, params: dict, device: str = "cpu",
             variant: str = "default") -> tuple[dict, dict]:
    """One cell through the real worker path (its own process), at quick sizes; ok or mismatch.
    Correctness only, as the parity suite: warm kernel caches and no throughput regime (the
    command-line tests run cells cold)."""
    from compare.running import cells
    require_device(backend, device)
    spec = {"scenario": scenario, "backend": backend, "device": device, "precision": precision,
            "params": params, "quick": True, "repeat": 1, "min_time": 0.0, "variant": variant,
            **CORRECTNESS}
    record, outputs = cells.run(Cell.from_dict(spec), timeout=600)
    assert record["status"] in ("ok", "mismatch"), \
        f"{record.get('reason')}\n{record.get('traceback', '')}"
    return record, outputs


Case = tuple[str, str, str, dict, str, str]     # backend, scenario, precision, params, device, variant
# every cell run_cases ran in this test process, by case: the parity suite's cells and the ones a
# backend's own tests share (shared_cell) are the same cells where the cases are, and tests of one
# backend carry xdist_group(f"{backend}-cells") (tests/backends/test_parity.py), so under xdist too
# each runs once
_CELLS: dict[str, tuple[Any, dict]] = {}


def _case_key(case: Case) -> str:
    return json.dumps(case, sort_keys=True)


def run_cases(cases: list[Case], timeout: float = 900) -> None:
    """Run each of ``cases`` not yet run in this process whose device is available, through the
    worker path: one worker process per backend, device, precision and variant (engine.run_cells,
    share_process), so a framework starts, and compiles what the cells share, once rather than
    once per cell. Correctness only, as run_cell; read a case's (Record, outputs) with ``ran``."""
    # each distinct case once (a group may list one twice: Taichi's FRAMES cell is a SMALL one)
    todo = list({_case_key(c): c for c in cases if _case_key(c) not in _CELLS
                 and not availability(c[0]).get(c[4], "unknown device")}.values())
    if not todo:
        return
    specs = [{"scenario": s, "backend": b, "device": d, "precision": p, "params": o, "quick": True,
              "repeat": 1, "min_time": 0.0, "variant": v, **CORRECTNESS} for b, s, p, o, d, v in todo]
    results = engine.run_cells([Cell.from_dict(s) for s in specs], timeout=timeout, share_process=True,
                               probes={c[0]: probe(c[0]) for c in todo})
    _CELLS.update({_case_key(c): (r, o) for c, (r, o) in zip(todo, results)})


def ran(case: Case) -> tuple[Any, dict]:
    """The (Record, outputs) run_cases gave ``case``."""
    return _CELLS[_case_key(case)]


def shared_cell(name: str, cases: list[Case], backend: str, scenario: str, precision: str,
                params: dict, device: str = "cpu", variant: str = "default") -> tuple[dict, dict]:
    """One of ``cases``, as run_cell gives it. On first use every case of ``name`` runs
    (run_cases: those already run in this process, by the parity suite or another group, are
    not run again). Tests reading one ``name`` carry xdist_group(name), so under xdist they share
    one run."""
    require_device(backend, device)
    run_cases(cases)
    record, outputs = ran((backend, scenario, precision, params, device, variant))
    record = record.to_json()           # the record as the worker path's JSON object (what cells.run gives a test)
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

    from compare.running import cells
    require_device(backend, device)
    code = "import json\nimport backends, scenarios\nDEVICE = %r\n" % device + textwrap.dedent(body)
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    line = next((r for r in proc.stdout.splitlines() if r.startswith("RESULT")), None)
    assert line, proc.stderr[-3000:]
    return json.loads(line[len("RESULT"):])



@pytest.fixture(scope="session", autouse=True)
def shared_yardstick_and_oracle(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The runs of the tests (in this process and the ones they start) share one hardware
    yardstick per device, the first run's (compare.running.hardware.for_run): each run measured
    its own, seconds each; and their workers share the oracle's outputs of a question already
    asked (compare.running.reuse): the same cases ran the projectile's Python oracle once
    per backend; and every process shares each backend's availability probe in one environment
    (a second each, ~140 of them per run); and the charts one process drew (compare.render.chart_memo:
    the site of tests/data/site is built in several processes, seconds of drawing each). xdist's
    workers share the folders under the run's temporary root. Set COMPARE_YARDSTICK_REUSE, COMPARE_ORACLE_REUSE or COMPARE_PROBE_REUSE
    (or COMPARE_CHART_MEMO_DIR) empty to compute each anew;
    tests/running/test_hardware.py and the yardstick's fault tests call ``hardware.measure``,
    which always measures."""
    from compare.render import chart_memo
    from compare.running import hardware, reuse
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base   # a worker's is <root>/<id>
    for env, name in ((hardware.REUSE_ENV, "yardstick"), (reuse.ENV, "oracle"), (reuse.PROBE_ENV, "probes"),
                      (chart_memo.DISK_ENV, "charts")):
        if env not in os.environ:
            (root / name).mkdir(exist_ok=True)
            os.environ[env] = str(root / name)


@pytest.fixture(scope="session")
def compare_list(tmp_path_factory: pytest.TempPathFactory) -> subprocess.CompletedProcess:
    """``python -m compare list`` (no extra backend folders), run once per test run: it probes
    every backend in its own process, seconds each, and several tests read it. xdist's workers
    share it through a file under the run's temporary root; the first to take the lock runs it."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base   # a worker's is <root>/<id>
    path = root / "compare-list.json"
    with open(root / "compare-list.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            env = {k: v for k, v in os.environ.items() if k != "COMPARE_BACKENDS_EXTRA"}
            args = [sys.executable, "-m", "compare", "list"]
            p = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600,
                               stdin=subprocess.DEVNULL)
            tmp = path.with_suffix(".tmp")
            tmp.write_text(json.dumps({"args": args, "returncode": p.returncode, "stdout": p.stdout,
                                       "stderr": p.stderr}))
            os.replace(tmp, path)
        got = json.loads(path.read_text())
    return subprocess.CompletedProcess(got["args"], got["returncode"], got["stdout"], got["stderr"])
