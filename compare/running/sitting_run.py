"""The sitting check measured (``check_sitting``), and a run's checks kept in its entry of the
store's ``runs`` (``compare.measuring.sitting``: the check's figures and the verdict).

``sitting: {"start": check, "end": check}``. ``compare all`` / ``compare run`` / a sweep measure
the start once, before any cell, from the yardstick the run has just measured (on CUDA with
``PROCESSES`` - 1 more; the host window and NVML on top: a quarter of a second on the CPU), and judge it against the published stores'
quiet sittings of the kind: a noisy one is stamped, never refused (only publish refuses). A publish part is handed its start by
``publish`` (``ENV``: the check publish judged before starting the part, its reasons and the quiet
reference) and measures its end after its last cell, judged against the same reference. A run
whose sitting publish let through (``--allow-noisy-sitting``), or whose end is noisy, is stamped
``noisy_sitting: true`` with ``noisy_sitting_reasons``; its records' run stamps say so from the
start's verdict (``compare.measuring.environment.run_stamp``), and the pages name it.
"""
from __future__ import annotations

import json
import os
from typing import Any, Iterable, Mapping

from compare.measuring.sitting import Quiet, SittingCheck, judge, sitting_from
from compare.results.environment import RunEnvironment, Yardstick

ENV = "COMPARE_SITTING"       # publish -> its part: {"start", "reasons", "quiet"} as JSON


# CUDA yardstick processes a check takes: a process's launch floor sits at one of two levels and
# the share of a sitting's processes at the slower one varies (docs/measurement.md, "The sitting
# check"); seven tell a sitting where most are (at least 5: sitting.SLOW_SHARE) from a usual one
PROCESSES = 7


def measure_yardstick(device: str) -> Yardstick:
    """The device's yardstick for a check: CUDA's in its own process (no framework's context);
    the CPU's copy in this process, without the curve of smaller sizes."""
    from compare.running import hardware
    if device == "cuda":
        return hardware.measure("cuda", timeout=120.0)
    try:
        return hardware.measure_cpu(curve_sizes=())
    except Exception as exc:  # a figure lost, never the check
        return Yardstick(error=f"{type(exc).__name__}: {exc}")


def check_sitting(device: str, yardstick: Yardstick | None = None) -> SittingCheck:
    """The sitting of ``device`` ('cuda' or 'cpu') now: on CUDA from ``PROCESSES`` yardstick
    processes (``sitting.of_processes``), ``yardstick`` (one this run has just measured) among
    them, each a process, the driver's start, the copies and launches, one after another; on the
    CPU ``yardstick``, else one measured here (about a second on 2 cores). The host window on top."""
    got = [yardstick] if yardstick is not None else []
    # a failed process ends the series: the next would fail alike (up to its timeout each)
    while not got or (device == "cuda" and len(got) < PROCESSES and not got[-1].get("error")):
        got.append(measure_yardstick(device))
    return sitting_from(device, got)


def device_of(devices: Iterable[str]) -> str:
    """The device a run's sitting is checked on: CUDA where the run uses it, else the CPU."""
    return "cuda" if "cuda" in set(devices) else "cpu"


def handed(check: SittingCheck, reasons: Iterable[str], quiet: Quiet | None) -> str:
    """What publish hands its part (``ENV``)."""
    return json.dumps({"start": check.to_json(), "reasons": list(reasons),
                       "quiet": quiet.to_json() if quiet else None})


def from_publish() -> Mapping[str, Any] | None:
    """What publish handed this part, or None (not a publish part, or unreadable)."""
    text = os.environ.get(ENV, "")
    try:
        got = json.loads(text) if text else None
    except ValueError:
        return None
    return got if isinstance(got, dict) and isinstance(got.get("start"), dict) else None


def stamp(env: RunEnvironment, reasons: Iterable[str]) -> None:
    """Mark the run a noisy sitting, with ``reasons`` (nothing when there are none)."""
    why = list(reasons)
    if why:
        env["noisy_sitting"] = True
        env["noisy_sitting_reasons"] = [*(env.get("noisy_sitting_reasons") or []), *why]


def start(env: RunEnvironment, measure: bool = True) -> None:
    """``env['sitting'] = {'start': ...}``: publish's check in a publish part, else (``measure``)
    one taken now, reusing the run's own yardstick (``env['hardware']``) of its device."""
    got = from_publish()
    if got is not None:
        q = got.get("quiet")
        env["sitting"] = {"start": dict(got["start"]), "quiet": Quiet.from_json(q).to_json() if isinstance(q, dict) else None}
        stamp(env, [str(r) for r in got.get("reasons") or []])
        return
    if not measure:
        return
    hw = env.get("hardware") or {}
    dev = device_of(hw)
    yard = hw.get(dev)
    check = check_sitting(dev, yardstick=yard if yard and not yard.get("error") else None)
    quiet = reference(check)
    # the reference is kept (null: none, e.g. a copy of the tree without the stores), so a page can
    # judge a run that had none against the stores' quiet sittings after the fact
    env["sitting"] = {"start": check.to_json(), "quiet": quiet.to_json() if quiet else None}
    stamp(env, judge(check, quiet))        # outside publish a noisy sitting is said, never refused


def reference(check: SittingCheck) -> Quiet | None:
    """The quiet sittings of ``check``'s kind in the published stores (None: too few stored runs,
    or the stores cannot be read: a verdict lost, never the run)."""
    from compare.measuring import sitting_quiet
    try:
        return sitting_quiet.quiet_for(check, sitting_quiet.repository_stores())
    except (OSError, ValueError, TypeError, KeyError):
        return None


def end(env: RunEnvironment) -> None:
    """A publish part's end check, judged against the quiet reference publish used (outside a
    publish part: nothing, the start alone is kept)."""
    got = from_publish()
    if got is None or "sitting" not in env:
        return
    check = check_sitting(str(env["sitting"]["start"].get("device") or "cpu"))
    env["sitting"] = {**env["sitting"], "end": check.to_json()}
    quiet = Quiet.from_json(got["quiet"]) if isinstance(got.get("quiet"), dict) else None
    stamp(env, [f"at the end: {r}" for r in judge(check, quiet)])


__all__ = ["ENV", "PROCESSES", "check_sitting", "device_of", "measure_yardstick", "end", "from_publish", "handed", "reference", "stamp", "start"]
