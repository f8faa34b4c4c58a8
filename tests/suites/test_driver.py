"""The one driver (compare/suites/driver.py): every suite is a ``Suite`` run by ``drive``, in one order."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import pytest

from compare.suites import driver, publish, run as run_suite
from compare import options
from compare.options import UsageError
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
