"""Backend registry: each sub-package with a BACKEND object is a framework port.

Importing a backend package is cheap (it must not import its framework at module level), so the
driver can list backends without paying framework start-up; frameworks load inside workers.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import pkgutil
import sys
from pathlib import Path
from types import ModuleType

from scenarios.base import ParamError

from .base import DEVICES, Backend, ScenarioKernel


class Broken(Backend):
    """Stands in for a backend package that cannot be used (failed import, no or duplicate name);
    every device says why, so its cells are skips with the reason, never a crash."""

    def __init__(self, name: str, reason: str) -> None:
        self.name, self.reason, self.package = name, reason, name

    def available(self) -> dict[str, str | None]:
        return {d: self.reason for d in DEVICES}


# One line per backend package that could not be registered as it is (listed by `compare list`).
PROBLEMS: list[str] = []


EXTRA = "COMPARE_BACKENDS_EXTRA"   # folders of further backend packages (the tests' own: tests/extra_backends)


def _packages() -> list[tuple[str, Path]]:
    """(name, folder) of every backend package: this folder's, then those of the EXTRA folders."""
    roots = [Path(__file__).parent] + [Path(p) for p in os.environ.get(EXTRA, "").split(os.pathsep) if p]
    return [(m.name, root) for root in roots
            for m in sorted(pkgutil.iter_modules([str(root)]), key=lambda m: m.name) if m.ispkg]


def _import(name: str, root: Path) -> ModuleType:
    if root == Path(__file__).parent:
        return importlib.import_module(f"{__name__}.{name}")
    qualified = f"compare_extra_backends.{name}"     # never shadows a framework's own package name
    spec = importlib.util.spec_from_file_location(qualified, root / name / "__init__.py",
                                                  submodule_search_locations=[str(root / name)])
    if spec is None or spec.loader is None:
        raise ImportError(f"no package at {root / name}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[qualified] = module
    spec.loader.exec_module(module)
    return module


def _discover() -> dict[str, Backend]:
    found: dict[str, Backend] = {}
    for name, root in _packages():
        where = f"backends/{name}" if root == Path(__file__).parent else str(root / name)
        mod_name = name
        try:
            pkg = _import(name, root)
            backend = getattr(pkg, "BACKEND", None)
        except Exception as exc:  # a broken port must not take the driver down: list it as unusable
            backend = Broken(mod_name, f"{where}: backend package failed to import: {type(exc).__name__}: {exc}")
        if backend is None:
            continue                          # a helper package, not a backend
        if not isinstance(backend, Backend):
            backend = Broken(mod_name, f"{where}: BACKEND is a {type(backend).__name__}, not a Backend")
        name = getattr(backend, "name", None)
        if not isinstance(name, str) or not name:
            backend = Broken(mod_name, f"{where}: BACKEND has no name (set the class attribute 'name')")
        elif name in found:
            backend = Broken(mod_name, f"{where}: BACKEND calls itself {name!r}, which "
                                       f"{found[name].__module__.replace('.', '/')} already is; rename one")
        elif not isinstance(getattr(backend, "package", None), str):
            backend = Broken(name, f"{where}: BACKEND has no package (the pip distribution it needs)")
        if isinstance(backend, Broken):
            if backend.name in found:     # a folder named like another backend's name
                backend.name = f"{backend.name}@{where}"
            PROBLEMS.append(backend.reason)
        found[backend.name] = backend
    refs = [n for n, b in found.items() if b.is_reference]
    if len(refs) > 1:
        PROBLEMS.append(f"several reference backends ({', '.join(refs)}); the first is used")
    return dict(sorted(found.items(), key=lambda kv: (not kv[1].is_reference, kv[1].display_order, kv[0])))


BACKENDS: dict[str, Backend] = _discover()


def get(name: str) -> Backend:
    if name not in BACKENDS:
        raise ParamError(f"unknown backend {name!r} (known: {', '.join(BACKENDS)})")
    return BACKENDS[name]


def reference() -> str:
    """The reference backend's name (the first marked ``is_reference``; else the first listed)."""
    return next((n for n, b in BACKENDS.items() if b.is_reference), next(iter(BACKENDS), ""))


def cpu_baseline() -> str | None:
    """The backend CPU figures are shown against (marked ``is_cpu_baseline``), or None."""
    return next((n for n, b in BACKENDS.items() if b.is_cpu_baseline), None)


def display_name(name: str) -> str:
    """A backend's name as pages print it (its ``title``, else its name)."""
    b = BACKENDS.get(name)
    return (b.title if b is not None else "") or name


__all__ = ["BACKENDS", "DEVICES", "PROBLEMS", "Backend", "ScenarioKernel", "cpu_baseline", "display_name", "get",
           "reference"]
