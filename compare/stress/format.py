"""The stress suite's results-file format (``stress.json``): its findings must be readable by
their experiment's own page hooks."""
from __future__ import annotations

from typing import Any

from compare.results.records import Format, show
from compare.stress.numerics import Finding

__all__ = ["FORMAT", "Finding", "rows_problem"]     # Finding: the row as stored (numerics)


def rows_problem(data: dict[str, Any]) -> str | None:     # data: a stress.json as read from the file
    """A finding its experiment's own page hooks cannot read (a setting they parse)."""
    rows = data["analysis"].get("rows") or []
    if not rows:
        return None
    from compare.stress.registry import experiments     # the experiments load their scenarios
    registry = experiments()
    by_exp: dict[Any, list[tuple[int, Any]]] = {}
    for i, r in enumerate(rows):
        by_exp.setdefault(r["experiment"], []).append((i, r))
    found = [p for name, mine in by_exp.items() if (p := _unreadable(registry.get(name), mine)) is not None]
    return min(found)[1] if found else None


def _unreadable(exp: Any, mine: list[tuple[int, Any]]) -> tuple[int, str] | None:
    """The first of one experiment's findings (index, row) its page hooks cannot read, as (index,
    refusal); the hooks read the rows at once, and row by row only to name a failing one."""
    hooks = [h for h in ((exp.extra_markdown, exp.table_rows) if exp is not None else ()) if h is not None]
    try:
        for hook in hooks:
            hook([r for _, r in mine])
        return None
    except Exception:
        pass
    for i, r in mine:
        for hook in hooks:
            try:
                hook([r])
            except Exception as exc:    # the hook is the experiment's: any failure is this row's
                why = f"{type(exc).__name__}: {show(str(exc))}"
                return i, f"analysis.rows[{i}]: the {show(r['experiment'])} page cannot read this finding ({why})"
    return None


FORMAT = Format("stress", "stress.json", store_problem=rows_problem)
