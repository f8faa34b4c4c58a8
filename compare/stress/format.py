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
    for i, r in enumerate(rows):
        exp = registry.get(r["experiment"])
        for hook in (exp.extra_markdown, exp.table_rows) if exp is not None else ():
            try:
                if hook is not None:
                    hook([r])
            except Exception as exc:    # the hook is the experiment's: any failure is this row's
                why = f"{type(exc).__name__}: {show(str(exc))}"
                return f"analysis.rows[{i}]: the {show(r['experiment'])} page cannot read this finding ({why})"
    return None


FORMAT = Format("stress", "stress.json", store_problem=rows_problem)
