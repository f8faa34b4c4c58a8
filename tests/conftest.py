from __future__ import annotations

import functools
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from compare import cells  # noqa: E402


@functools.cache
def availability(backend: str) -> dict[str, str | None]:
    return cells.probe(backend)["available"]


def require_device(backend: str, device: str) -> None:
    why = availability(backend).get(device, f"unknown device {device}")
    if why:
        pytest.skip(f"{backend}/{device}: {why}")
