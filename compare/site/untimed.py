"""Which variants a ranked row never timed at its point, so its cells and verdict claim no more
than the records hold.

A row that ranks each framework's fastest variant (matrix.VARIANT_RULE) ranks only the variants
its records hold. A variant the framework offers for the scenario (``Backend.variants_for``) with
no record among the row's records was never timed there; it may be the fastest. Left out: the
variants the rule never ranks (fast math, matrix.NOT_SAME_WORK), those the backend says cannot
run on the row's device (``Backend.variant_unavailable``, decided without importing the
framework), and frameworks whose every record at the point is a skip (not available there: no
variant of it would run either).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import backends
from compare.results.record import Record
from compare.site import matrix
from compare.site.data import Machine
from compare.site.matrix import Row, Rule

RANKING = "the ranking is of the variants timed"


def ranks_variants(rule: Rule) -> bool:
    """Whether a row ranks each framework's fastest variant (matrix._cells' own path): the rows
    over several scenarios, the CPU rows and a row with its own cell builder read defaults only."""
    return rule.cells is None and rule.key != "cpu" and rule.key not in matrix.AGGREGATES


def offered(backend: str, scenario: str, device: str) -> tuple[str, ...]:
    """The variants ``backend`` offers for ``scenario`` that a row may rank on ``device``."""
    be = backends.BACKENDS.get(backend)
    if be is None:
        return ()
    return tuple(v for v in be.variants_for(scenario)
                 if v not in matrix.NOT_SAME_WORK and not be.variant_unavailable(v, device))


def in_order(names: Iterable[str]) -> list[str]:
    """Frameworks in the registry's order (the reference, then ``display_order``), unknown ones last."""
    known = list(backends.BACKENDS)
    return sorted(set(names), key=lambda n: (known.index(n) if n in known else len(known), n))


def missing(recs: list[Record], device: str) -> dict[str, tuple[str, ...]]:
    """Per framework of ``recs`` (a row's records, at its point), the variants it offers for their
    scenarios that none of its records there is of, in the backend's order."""
    out: dict[str, tuple[str, ...]] = {}
    for fw in in_order(r.backend for r in recs):
        mine = [r for r in recs if r.backend == fw]
        if all(r.status == "skipped" for r in mine):
            continue
        ran = {r.variant for r in mine}
        want = dict.fromkeys(v for sc in dict.fromkeys(r.scenario for r in mine) for v in offered(fw, sc, device))
        gone = tuple(v for v in want if v not in ran)
        if gone:
            out[fw] = gone
    return out


def note(gone: dict[str, tuple[str, ...]]) -> str:
    """The verdict's footnote: ``Not timed at this point: jax, drjit (checkpoint). The ranking
    is of the variants timed.``; frameworks missing the same variants named together."""
    if not gone:
        return ""
    groups: dict[tuple[str, ...], list[str]] = {}
    for fw, vs in gone.items():
        groups.setdefault(vs, []).append(fw)
    said = "; ".join(f"{', '.join(fws)} ({', '.join(vs)})" for vs, fws in groups.items())
    return f"Not timed at this point: {said}. {RANKING[0].upper()}{RANKING[1:]}."


def mark(row: Row, m: Machine) -> Row:
    """The row with each cell told which of its framework's variants were never timed at the
    row's point (``Cell.untimed``), and its verdict saying so."""
    if not ranks_variants(row.rule):
        return row
    gone = missing(row.rule.pick(m, row.device), row.device)
    if not gone:
        return row
    cells = {f: dataclasses.replace(c, untimed=gone[f]) if f in gone else c for f, c in row.cells.items()}
    return dataclasses.replace(row, cells=cells, verdict=f"{row.verdict} {note(gone)}")
