"""Backend registry: each sub-package with a BACKEND object is a framework port.

Importing a backend package is cheap (it must not import its framework at module level), so the
driver can list backends without paying framework start-up; frameworks load inside workers.
"""
from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from scenarios.base import ParamError

from .base import DEVICES, Backend, ScenarioKernel

ORDER = ("warp", "taichi", "jax", "numba")   # table order; the reference first


class Broken(Backend):
    """Stands in for a backend package that failed to import; every device says why."""

    def __init__(self, name: str, reason: str) -> None:
        self.name, self.reason = name, f"backend package failed to import: {reason}"
        self.package = name

    def available(self) -> dict[str, str | None]:
        return {d: self.reason for d in DEVICES}


def _discover() -> dict[str, Backend]:
    found = {}
    for mod in pkgutil.iter_modules([str(Path(__file__).parent)]):
        if not mod.ispkg:
            continue
        try:
            pkg = importlib.import_module(f"{__name__}.{mod.name}")
            backend = getattr(pkg, "BACKEND", None)
        except Exception as exc:  # a broken port must not take the driver down: list it as unusable
            backend = Broken(mod.name, f"{type(exc).__name__}: {exc}")
        if isinstance(backend, Backend):
            found[backend.name] = backend
    return dict(sorted(found.items(), key=lambda kv: (ORDER.index(kv[0]) if kv[0] in ORDER
                                                      else len(ORDER), kv[0])))


BACKENDS: dict[str, Backend] = _discover()


def get(name: str) -> Backend:
    if name not in BACKENDS:
        raise ParamError(f"unknown backend {name!r} (known: {', '.join(BACKENDS)})")
    return BACKENDS[name]


def reference() -> str:
    return next(n for n, b in BACKENDS.items() if b.is_reference)


__all__ = ["BACKENDS", "DEVICES", "Backend", "ScenarioKernel", "get", "reference"]
