"""The fast tier on every core (pytest-xdist, ``-n auto`` in pyproject.toml); hooks imported by
tests/conftest.py.

- **Workers**: one per usable core; the long tier (``-m slow``) runs in the main process, one test
  at a time, as it always has (its tests fill disks and watch memory peaks).
- **Groups**: tests marked ``xdist_group(name)`` run on one worker, one after another in file
  order: they share work done once per process (a module-scoped fixture, a module-level cache of
  cells run in one worker process). Every other test is scheduled on its own: tests marked
  ``early`` (the long ones) first, then the largest groups, so that the run does not end waiting
  on one long test. xdist's own ``--dist loadgroup`` does this, but on pytest 9.2 it ignores the marks
  (pytest-dev/pytest-xdist#1386), so the workers write each test's group to a file that the
  controller's scheduler reads. A ``--dist`` given on the command line is xdist's as usual.
- **Alone**: a test marked ``alone`` runs while no other test does (the others wait): tests that
  judge the host's load.
"""
from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

GROUPS_ENV = "COMPARE_TEST_XDIST_GROUPS"      # the controller's file of test -> group, for workers


def _worker() -> bool:
    return bool(os.environ.get("PYTEST_XDIST_WORKER"))


def _distributing(config: pytest.Config) -> bool:
    return bool(config.getoption("numprocesses", None)) and config.getoption("dist", "no") == "load"


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    markexpr = config.getoption("markexpr") or ""
    if "slow" in markexpr.replace("not slow", ""):
        return 0
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def pytest_configure(config: pytest.Config) -> None:
    if not _worker() and _distributing(config):
        fd, path = tempfile.mkstemp(prefix="pytest-xdist-groups-", suffix=".json")
        os.close(fd)
        os.environ[GROUPS_ENV] = path         # the workers, started after this, inherit it


def pytest_unconfigure(config: pytest.Config) -> None:
    if not _worker() and os.environ.get(GROUPS_ENV):
        Path(os.environ.pop(GROUPS_ENV)).unlink(missing_ok=True)


@pytest.hookimpl(tryfirst=True)          # before xdist reports the collection to the controller
def pytest_collection_finish(session: pytest.Session) -> None:
    path = os.environ.get(GROUPS_ENV)
    if not (_worker() and path):
        return
    groups, early = {}, []
    for item in session.items:
        mark = item.get_closest_marker("xdist_group")
        if mark:
            groups[item.nodeid] = str(mark.args[0] if mark.args else mark.kwargs.get("name", "default"))
        if item.get_closest_marker("early"):
            early.append(item.nodeid)
    tmp = f"{path}.{os.environ['PYTEST_XDIST_WORKER']}"
    Path(tmp).write_text(json.dumps({"groups": groups, "early": early}))
    os.replace(tmp, path)                     # every worker writes the same map


@pytest.hookimpl(optionalhook=True, tryfirst=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    if not os.environ.get(GROUPS_ENV):
        return None                           # a --dist the user chose: xdist's scheduler
    from xdist.scheduler import LoadScopeScheduling

    class GroupScheduling(LoadScopeScheduling):
        """LoadScopeScheduling with one scope per group and one per ungrouped test, the scopes
        holding an ``early`` test first; scheduled once every worker has collected, so after each
        has written the map."""
        _map: dict[str, Any] | None = None
        _ordered = False

        def _read(self) -> dict[str, Any]:
            if self._map is None:
                self._map = json.loads(Path(os.environ[GROUPS_ENV]).read_text() or "{}")
            return self._map

        def _split_scope(self, nodeid: str) -> str:
            group = self._read().get("groups", {}).get(nodeid)
            return f"group:{group}" if group else nodeid

        def _assign_work_unit(self, node: Any) -> None:
            if not self._ordered:                 # the queue is complete at the first assignment
                early = {self._split_scope(n) for n in self._read().get("early", [])}
                for scope in reversed([s for s in self.workqueue if s in early]):
                    self.workqueue.move_to_end(scope, last=False)
                self._ordered = True
            super()._assign_work_unit(node)

    return GroupScheduling(config, log)


@contextlib.contextmanager
def _turn(item: pytest.Item) -> Iterator[None]:
    """Every test holds a shared lock on a file of the run's temporary root, an ``alone`` test the
    exclusive one. A gate taken first (exclusively by an ``alone`` test, in passing by the others)
    keeps the others' next tests from starving a waiting ``alone`` test."""
    basetemp = getattr(item.config.option, "basetemp", None)
    if not _worker() or not basetemp:
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


def merge(into: dict, part: dict) -> None:
    """Add one worker's counts into ``into``: numbers add, lists extend, dicts merge, text stays."""
    for k, v in part.items():
        if isinstance(v, dict):
            merge(into.setdefault(k, {}), v)
        elif isinstance(v, list):
            into[k] = into.get(k, []) + v
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            into[k] = into.get(k, 0) + v
        else:
            into[k] = v
