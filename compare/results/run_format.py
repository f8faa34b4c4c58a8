"""The run suite's results-file format (``results.json``): how a format-1 record is upgraded."""
from __future__ import annotations

from typing import Any

from compare.results.records import Format


def upgrade_record(rec: dict[str, Any]) -> dict[str, Any]:     # a stored record's JSON
    """A format-1 record: its distance to the reference backend was keyed ``vs_<name>``."""
    import backends
    err = rec.get("error")
    ref = backends.reference()
    if isinstance(err, dict) and f"vs_{ref}" in err:
        err["vs_reference"] = err.pop(f"vs_{ref}")
        err["reference"] = ref
        if f"vs_{ref}_device" in err:
            err["vs_reference_device"] = err.pop(f"vs_{ref}_device")
    return rec


FORMAT = Format("run", "results.json", upgrade=upgrade_record)
