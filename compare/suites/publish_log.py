"""The publish log, DIR/publish.json: what ``compare publish`` ran, when, and how each attempt
ended, and the rule that says whether a part is done (``state``).

DIR/publish.json, the progress log (the site's machine page reads it; written atomically):

    {"format_version": 1,
     "parts": [{"name": "all",                    one entry per attempt, oldest first
                "argv": ["all", "--devices", ...], the command after ``python -m compare``
                "started": "2026-01-01T00:00:00+00:00",   ISO 8601, UTC
                "seconds": 123.4,                  wall time (so far, updated each minute)
                "exit_code": 0,                    null then; negative: ended by that signal
                "interrupted": false,              true: publish stopped it (--budget, Ctrl-C)
                "host": {"hostname", "cpu", "cpu_id", "cores", "gpus": [{name, driver, memory}]}}]}

Run time: the sum of ``seconds`` over ``parts``. History: 1, the first; a host's ``cpu_id``
(family, model, stepping) since 2026-12-02, absent before.
"""
from __future__ import annotations

import dataclasses
import datetime
import json
from pathlib import Path
from typing import Any, Mapping, cast

from compare.measuring import environment
from compare.options import EXIT_INTERRUPTED
from compare.planning.publish_plan import Part
from compare.results.environment import Host, PublishEntry as Entry, PublishLog as Log, machine, same_machine
from compare.results.store import StoreError, atomic_write

FORMAT_VERSION, LOG = 1, "publish.json"
DONE_CODES = (0, 1)      # 1: the part ran to its end; the report marks its failed cells


def load_log(out: Path) -> Log:
    """DIR/publish.json (an empty log when absent); a malformed one is refused in one line."""
    path = Path(out) / LOG
    if not path.exists():
        return Log(format_version=FORMAT_VERSION, parts=[])
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise StoreError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    if not isinstance(data, dict) or data.get("format_version") != FORMAT_VERSION:
        raise StoreError(f"{path}: not a publish log of format {FORMAT_VERSION}")
    parts = data.get("parts")
    if not isinstance(parts, list) or not all(
            isinstance(e, dict) and isinstance(e.get("name"), str) and isinstance(e.get("argv"), list)
            and (e.get("exit_code") is None or type(e["exit_code"]) is int) for e in parts):
        raise StoreError(f"{path}: 'parts' must be a list of objects with a name, an argv, an exit_code")
    return cast(Log, data)   # the file's JSON, checked above (an older entry may lack a key: read with get)


def identity(argv: Any, out: str) -> list[str]:
    """A command as compared for 'the same part': --timeout aside, paths under DIR relative to it."""
    base = Path(out).resolve()
    words, skip = [], False
    for w in map(str, argv):
        if skip or w == "--timeout":
            skip = not skip
            continue
        r = Path(w).resolve()
        words.append(("DIR/" + str(r.relative_to(base))) if r == base or base in r.parents else w)
    return words


def cut_off(e: Entry) -> bool:
    code = e.get("exit_code")
    return code is None or bool(e.get("interrupted")) or code == EXIT_INTERRUPTED or code < 0


def state(part: Part, log: Log, out: str) -> str:
    """'done', 'done (exit 1 ...)', 'given up ...', or why the part is to run. A measuring part is
    judged by its latest attempt with the same command, a derived one by its latest attempt."""
    mine = [(i, e) for i, e in enumerate(log["parts"]) if e["name"] == part.name
            and (part.reads or identity(e["argv"], out) == identity(part.argv, out))]
    if not mine:
        return "to run"
    (i, e), code = mine[-1], mine[-1][1].get("exit_code")
    if code in DONE_CODES and not cut_off(e):
        newer = [r for r in part.reads if any(k > i and x["name"] == r for k, x in enumerate(log["parts"]))]
        return (f"to run ({', '.join(newer)} ran since)" if newer else
                "done" if code == 0 else "done (exit 1: some cells mismatch or error)")
    if not part.resumes and len(mine) > 1 and all(cut_off(x) for _, x in mine[-2:]):
        return (f"given up (cut off twice: longer than one call; run it per backend, "
                f"--part {part.name} --backends B)")
    return "to run (" + ("publish was killed during it" if code is None else "interrupted" if e.get("interrupted")
                         else f"last attempt exited {code}") + ")"


def host() -> Host:
    import platform
    cores = environment.usable_cores()
    return Host(hostname=platform.node(), cpu=environment.cpu_model(), cpu_id=environment.cpu_id(), cores=cores,
                gpus=environment.gpus())


def other_machine(log: Log, here: Mapping[str, Any]) -> str | None:
    """The machine of an earlier attempt in ``log`` that is not ``here``'s (None: all are), so
    that one store never holds two machines' rows."""
    return next((machine(h) for e in log["parts"] if (h := e.get("host")) and not same_machine(h, here)), None)


def save_log(out: Path, log: Log) -> None:
    atomic_write(Path(out) / LOG, json.dumps(log, indent=1))


def started() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


