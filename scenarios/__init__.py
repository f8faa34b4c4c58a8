"""Scenario registry: every module here defines one Scenario subclass; the driver looks them up by name."""
from __future__ import annotations

from .base import PRECISIONS, Check, ParamError, Precision, Scenario
from .copy import Copy
from .launch import Launch
from .particles import Particles
from .projectile import Projectile
from .saxpy import Saxpy
from .sdf import Sdf

SCENARIOS: dict[str, Scenario] = {s.name: s for s in (Saxpy(), Sdf(), Particles(), Projectile(),
                                                       Launch(), Copy())}


def get(name: str) -> Scenario:
    if name not in SCENARIOS:
        raise ParamError(f"unknown scenario {name!r} (known: {', '.join(SCENARIOS)})")
    return SCENARIOS[name]


__all__ = ["SCENARIOS", "PRECISIONS", "Check", "ParamError", "Precision", "Scenario", "get"]
