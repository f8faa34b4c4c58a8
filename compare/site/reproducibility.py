"""The machine page's "Reproducibility": every stored second run held against the report's
records ordering by ordering (``compare agree``, compare/site/agreement.py).

A store's second runs are the matrix part run again (``DIR/rerun/``, with its publish log: how
long it took) and its later sittings (``DIR/sittings/<label>/``, compare/site/sittings.py). Each is
held against the report on the cells both measured, so a sitting that timed the default variants
alone is not set against the report's fastest variant. The rerun is then named in full (its
runs, how busy its host was, its yardstick, the part's time) from its own files, not a claim.
"""
from __future__ import annotations

import statistics
from typing import Any, Iterable

from compare.site import agreement, data, fmt, provenance
from compare.site import questions_pages as qp
from compare.site.data import Machine
from compare.site.render import H, P, Table

RERUN = "rerun"       # beside a store: a second run of (part of) its matrix part, named on the page


def _others_cores(recs: Any) -> str:
    """The median of the cores other processes used while the records' cells were timed."""
    got = sorted(v for r in recs if r.time and r.time.noise
                 for v in [data.num(r.time.noise.others_cores)] if v is not None)
    return f"{statistics.median(got):.2f}" if got else "?"


def _hosts(envs: Any, device: str) -> str:
    """The runs' hosts as their yardsticks saw them: the device copy's bandwidth, and the processor
    where recorded (one model name can stand for hosts far apart: measurement.md)."""
    words = []
    for e in envs:
        hw = (e.get("hardware") or {}).get(device) or {}
        copy = fmt.rate(data.num(hw.get("copy_bytes_per_s")), "B/s") if isinstance(hw, dict) else "-"
        words.append(f"copy {copy}" + (f", {e['cpu_id']}" if e.get("cpu_id") else ""))
    return "; ".join(dict.fromkeys(words)) or "?"


def _runs(m: Machine) -> str:
    return "; ".join(provenance.run_words(e.get("created"), e.get("git_commit"), e.get("git_dirty")) for e in m.runs)


def second_runs(c: qp.Ctx) -> list[tuple[str, Machine]]:
    """(label, stores) of the rerun beside the report's stores, then its later sittings."""
    dirs = [s.parent / RERUN for s in c.m.sources if (s.parent / RERUN).is_dir()]
    return ([(f"{RERUN}/", data.load([dirs[0]]))] if dirs else []) + [(f"sittings/{n}", m) for n, m in c.later]


def _which(held: agreement.Held) -> str:
    return "; ".join(f"{r.question}: {', '.join(r.reversed_pairs)}" for r in held.rows if r.reversed_pairs) or "-"


def _total(helds: Iterable[agreement.Held]) -> str:
    rows = [r for h in helds for r in h.rows]
    return agreement.summary(rows).replace("between the two runs", "between the report and a second run")


def blocks(c: qp.Ctx) -> list[Any]:
    """The section: every second run's agreement in a table, then the rerun named in full."""
    others = second_runs(c)
    if not others:
        return [H("Reproducibility"), P("No second run of the matrix part is stored beside these records "
                                         f"(a `{RERUN}/` folder), nor a later sitting: the rankings have not been rerun.")]
    held = [(label, m, agreement.hold(c.m, m)) for label, m in others]
    later = len(c.later)
    what = ", ".join(([f"the matrix part run again, in `{RERUN}/`"] if later < len(others) else [])
                     + ([f"{later} later sitting{'s' if later != 1 else ''}, in `sittings/`"] if later else []))
    counted = [(label, m, h) for label, m, h in held if any(r.significant - r.missing for r in h.rows)]
    out: list[Any] = [H("Reproducibility"), P(
        f"Every second run stored beside these records ({len(others)}: {what}) is held against them ordering "
        "by ordering (`python -m compare agree`): for every pair of frameworks that either run separates on a "
        "row, the other run's order, on the cells both measured (the same framework, variant and sizes: a run "
        "that timed fewer variants is not set against another variant). Summed over them: "
        f"**{_total(h for _, _, h in counted)}** A run with no separated pair in common is not listed; its host "
        "is named by its yardstick (the report's runs: *The sittings* below)."),
        Table(("second run", "its runs", "its host", "cells both measured", "significant pairs", "agree",
               "tie in one run", "reversed", "which"),
              tuple((label, _runs(m), _hosts(m.runs, c.device), str(h.cells),
                     str(sum(r.significant - r.missing for r in h.rows)), str(sum(r.agree for r in h.rows)),
                     str(sum(r.tie for r in h.rows)), str(h.reversed), _which(h))
                    for label, m, h in counted))]
    if others[0][0] != f"{RERUN}/":
        return out
    _, other, first = held[0]
    got = [r for r in first.rows if r.significant]
    asked = {r.question for r in got}
    mine = {x for r in c.rows if r.rule.question + (f" ({r.device})" if r.device else "") in asked for x in r.runs}
    stamps = {(r.run or {}).get("created") for r in c.m.run if provenance.label(r) in mine}
    hosts = (f" Its host's yardstick: {_hosts(other.runs, c.device)} (the runs of these rows: "
             f"{_hosts((e for e in c.m.runs if e.get('created') in stamps), c.device)}).")
    took = [p for p in (other.publish["parts"] if other.publish else []) if p.get("name") == "all"]
    part = (f" The part took {sum(float(p.get('seconds') or 0) for p in took) / 60:.1f} minutes "
            f"in {len(took)} attempt{'s' if len(took) != 1 else ''} ({RERUN}/publish.json)." if took else "")
    return out + [
        P(f"The second run of the matrix part ({RERUN}/: {_runs(other)}), {first.words(alone=False)}: "
          f"**{agreement.summary(got)}** Rows the second run did not measure are not counted. While its cells "
          f"were timed, other processes used a median of {_others_cores(other.run)} cores (in the runs of these "
          f"rows: {_others_cores(r for r in c.m.run if provenance.label(r) in mine)}).{hosts}{part}"),
        Table(("row", "significant pairs", "agree", "tie in one run", "reversed", "which"),
              tuple((r.question, str(r.significant - r.missing), str(r.agree), str(r.tie), str(r.disagree),
                     ", ".join(r.reversed_pairs) or "-") for r in got))]


__all__ = ["RERUN", "blocks", "second_runs"]
