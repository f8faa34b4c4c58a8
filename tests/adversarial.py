"""The adversarial tally printed at the end of a pytest run and quoted in docs/reliability.md.

Every test of the hostile-input and fault modules is one case, or as many cases as the inputs it
tries (a test that loops over inputs, or a Hypothesis example, calls ``case()`` once per input).
A case is clean when its test passed: each test asserts the whole contract (exit 2, one line, no
traceback, nothing written, nothing followed, nothing lost, no orphan process). Skipped tests are
counted apart with their reason."""
from __future__ import annotations

import re

MODULES = ("test_options", "test_options_properties", "test_preflight", "test_lock", "test_store_paths",
           "test_cli_hostile", "test_records", "test_records_depth")
CATEGORIES = ("cli", "files", "faults", "security")

# First match wins; a test name matching none is a CLI case (bad arguments and words).
_RULES = (
    ("cli", r"scheduler|name_too_long|refusal_under"),
    ("security", r"symlink|array_paths|stay_in|outside"),
    ("faults", r"lock|kill|disk|no_room|timeout|yardstick|temporar|atomic_write|resume|memory"),
    ("files", r"json|store|file|loader|reader|array|record|corrupted|mutated|header"),
)

_inputs = 0                      # inputs tried by the running test (case() calls)
TALLY: dict[str, list[int]] = {c: [0, 0] for c in CATEGORIES}     # category -> [cases, clean]
SKIPPED: dict[str, int] = {}                                         # reason -> tests


def case() -> None:
    """One more input tried by the running test."""
    global _inputs
    _inputs += 1


def category(test_name: str) -> str:
    name = test_name.split("[")[0]
    return next((c for c, rx in _RULES if re.search(rx, name)), "cli")


def start() -> None:
    global _inputs
    _inputs = 0


def finish(test_name: str, passed: bool) -> None:
    n = max(_inputs, 1)
    tally = TALLY[category(test_name)]
    tally[0] += n
    tally[1] += n if passed else 0


def skipped(reason: str) -> None:
    SKIPPED[reason] = SKIPPED.get(reason, 0) + 1


def state() -> dict:
    """This process's counts (an xdist worker sends them to the controller)."""
    return {"tally": TALLY, "skipped": SKIPPED}


def merge(other: dict) -> None:
    """Add another process's ``state()`` to this one's."""
    for c, (cases, clean) in other.get("tally", {}).items():
        TALLY[c][0] += cases
        TALLY[c][1] += clean
    for reason, n in other.get("skipped", {}).items():
        SKIPPED[reason] = SKIPPED.get(reason, 0) + n


def lines() -> list[str]:
    cases = sum(t[0] for t in TALLY.values())
    if not cases and not SKIPPED:
        return []
    clean = sum(t[1] for t in TALLY.values())
    out = [f"adversarial cases: {cases}, clean: {clean} ({100 * clean / max(cases, 1):.1f} %); "
           + ", ".join(f"{c} {t[1]}/{t[0]}" for c, t in TALLY.items())]
    out += [f"  skipped ({n} tests): {r}" for r, n in sorted(SKIPPED.items())]
    return out
