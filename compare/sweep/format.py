"""The sweep suite's results-file format (``sweep.json``): the upgrade of a format-1 record and
what the sweep page and plots index directly in an ok record of each sweep kind."""
from __future__ import annotations

from typing import Any

from compare.results.records import AMOUNT, POSITIVE, TEXT, Format, Obj, problem
from compare.sweep.points import sweeps


def upgrade_record(rec: dict[str, Any]) -> dict[str, Any]:     # JSON: an older sweep.json's record, as read
    """A record of an older sweep.json (top-level 'sweep', 'role', 'knob'; the size sweep's role
    was its scenario's name) in today's shape: the three under ``tags``, the bandwidth sweep's
    role the scenario's ``measures``."""
    if "tags" in rec or not any(k in rec for k in ("sweep", "role", "knob")):
        return rec
    new = {k: v for k, v in rec.items() if k not in ("sweep", "role", "knob")}
    role = rec.get("role")
    measures = sweeps(rec["scenario"]).measures     # a string: from_json upgrades after shape_problem
    if rec.get("sweep") == "bandwidth" and measures:
        role = measures
    new["tags"] = {"sweep": rec.get("sweep"), "role": role, "knob": rec.get("knob") or {}}
    return new


def record_problem(rec: dict[str, Any]) -> str | None:      # JSON: a record as read, before Record is built
    """What the sweep page and plots index directly in an ok, timed record of each sweep kind."""
    tags = rec.get("tags") or {}
    if rec["status"] != "ok" or not rec.get("time"):
        return None
    kind, role = tags.get("sweep"), tags.get("role")
    labels = sweeps(rec["scenario"]).labels
    need: list[tuple[str, Any]] = []
    if kind == "bandwidth" and role in ("copy", "bandwidth"):
        need += [("work.bytes", POSITIVE), ("params.n", POSITIVE)]
    if kind == "bandwidth" and role == "bandwidth" or kind in ("scaling", "horizon"):
        need.append(("tags.knob.value", POSITIVE))          # sorted by, and a log axis of
    if kind == "scaling":
        need += [("error", Obj(null=False)), ("memory.peak_host_rss_bytes", AMOUNT),
                 (f"work.{labels.get('rate_work', 'items')}", AMOUNT)]
        need += [(f"params.{labels['per_run']}", AMOUNT)] if labels.get("per_run") else []
    if kind == "horizon":
        need += [("error", Obj(null=False)), ("variant", TEXT), ("params", Obj(null=False))]
    for path, node in need:
        v: Any = rec
        for part in path.split("."):
            if not isinstance(v, dict) or part not in v:
                return f"{path} is missing (an ok {kind} sweep record, role {role}, needs it)"
            v = v[part]
        if (p := problem(node, v, path)) is not None:
            return p
    return None


FORMAT = Format("sweep", "sweep.json", upgrade=upgrade_record, record_problem=record_problem)
