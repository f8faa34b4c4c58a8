"""A worker's kernel caches (``Cell.cache``): cold, kept from an earlier process of the cell, or warm.

The first call measures compilation, so it depends on what a framework compiled before. Each
backend names its on-disk caches (``Backend.cache_environment``); the worker points them at a
directory before the framework is imported (docs/measurement.md, "Caches").
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from backends.base import Backend


def shared_temp() -> None:
    """Warm caches that a framework keeps under the temporary directory by default (MLX's compiled
    CPU kernels, Inductor's) live for the driver's life instead of one worker's: the temporary
    directory moves from the worker's own folder to one in the driver's temporary root (deleted with
    it), which every worker of the driver shares."""
    import tempfile
    from compare.running.lifeline import ROOT_ENV
    root = os.environ.get(ROOT_ENV, "")
    if not root or not Path(root).is_dir():
        return
    shared = Path(root) / "warm-temp"
    shared.mkdir(exist_ok=True)
    for var in ("TMPDIR", "TEMP", "TMP"):
        os.environ[var] = str(shared)
    tempfile.tempdir = None          # gettempdir() reads the variables again


def apply(policy: str, backend: Backend, out_dir: Path, kept: str = "") -> str:
    """Point the backend's on-disk kernel caches at empty directories inside the cell's own
    temporary directory (deleted with it), so first_call_s always includes compilation; set before
    the framework is imported. ``kept`` (``Cell.cache_dir``): the directories live there instead;
    an earlier process of the cell that found it empty filled it, and this one starts from what
    it left ('kept'). Returns the note recorded with the time."""
    if policy == "warm":
        shared_temp()
        return "warm: framework default caches, which may hold kernels compiled by earlier runs"
    cache = Path(kept) if kept else out_dir / "cache"
    filled = cache.is_dir() and any(cache.iterdir())
    cache.mkdir(parents=True, exist_ok=True)
    (cache / "used").touch()        # the next process of the cell finds it filled, whatever the framework keeps
    env = backend.cache_environment(cache)
    folders = {var for var, value in env.items() if value and cache in Path(value).parents}
    for var, value in env.items():
        if var in folders:          # a cache directory (not a flag's value)
            Path(value).mkdir(parents=True, exist_ok=True)
        os.environ[var] = value
    kept_word = "as an earlier process left it (this cell's, or its family's: compare/suites/family_caches.py)"
    state, word = ("kept", kept_word) if filled else ("cold", "empty")
    return f"{state}: " + (", ".join(f"{k} {word}" if k in folders else f"{k}={v}" if v else f"{k} off"
                                     for k, v in env.items())
                           or "the framework keeps no kernel cache on disk")


def nothing_to_keep(cells: list[Any]) -> bool:     # the driver's JSON of each cell (Cell.to_dict)
    """Whether nothing a worker writes at its exit outlives it: every cell's kernel caches were
    cold in the cell's own directory (not kept: ``Cell.cache_dir``), which the driver deletes."""
    return bool(cells) and all(isinstance(c, dict) and c.get("cache", "cold") == "cold"
                               and not c.get("cache_dir") for c in cells)


def leave(cells: list[Any]) -> None:
    """End the worker at once when ``nothing_to_keep``: its records are written, and the
    interpreter's and frameworks' teardown (thread pools, compilers: 0.1-0.5 s a process) would
    only delay the next cell. A warm or kept cache exits normally: what a framework writes at
    exit (an offline kernel cache) is there for the next process, and its first call."""
    if nothing_to_keep(cells):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
