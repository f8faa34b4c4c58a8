"""``python -m compare list`` (compare/suites/listing.py): what a backend lacks, in one line each."""
from __future__ import annotations

import backends
from compare.suites import listing


def test_a_missing_kernel_is_named_required_or_optional(monkeypatch) -> None:
    name = next(n for n, b in backends.BACKENDS.items() if not isinstance(b, backends.Broken))
    b = backends.BACKENDS[name]
    monkeypatch.setattr(type(b), "has_kernel", lambda self, scenario: scenario not in ("saxpy", "launch"))
    lines = [ln for ln in listing.scenario_problems() if ln.startswith(f"{name}: ")]
    assert any("missing required" in ln and "/saxpy.py" in ln for ln in lines), lines
    assert any("no optional" in ln and "/launch.py" in ln for ln in lines), lines
