"""What each scenario contributes to the report site: its questions and its pages.

A question (a matrix row) reads one scenario's records, and its page speaks of that scenario,
so they live here, as the sweeps' parts live in compare/sweep/points/: one module per scenario,
named after it, with any of ``RULES`` (its matrix rows, in order), ``PAGES`` ({page key: (label,
builder)}) and ``SMALL`` (its default cells belong in the per-call page's table of small
kernels). A scenario without a module has no rows or pages of its own. The site's other code
never names a scenario; a module finds its own name with ``scenario_of(__name__)``.
"""
from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType
from typing import Any, Callable

import scenarios
from compare.site.matrix import Rule


def scenario_of(module: str) -> str:
    """The scenario a topic module speaks for: its own name."""
    return module.rsplit(".", 1)[-1]


def _registry() -> dict[str, ModuleType]:
    """Each scenario's topic module, in the scenarios' order (the matrix's and the pages')."""
    found = {m.name for m in pkgutil.iter_modules(__path__)}
    return {name: importlib.import_module(f"{__name__}.{name}") for name in scenarios.SCENARIOS if name in found}


TOPICS: dict[str, ModuleType] = _registry()
RULES: tuple[Rule, ...] = tuple(r for t in TOPICS.values() for r in getattr(t, "RULES", ()))
PAGES: dict[str, tuple[str, Callable[[Any], list[Any]]]] = {
    k: v for t in TOPICS.values() for k, v in getattr(t, "PAGES", {}).items()}
SMALL: tuple[str, ...] = tuple(name for name, t in TOPICS.items() if getattr(t, "SMALL", False))
