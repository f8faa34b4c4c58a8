"""A chart drawn once per process: the same figure asked for again is written from memory.

``compare.render.charts`` draws byte-for-byte the same PNG (and CSV) for the same arguments, so a
second request with equal arguments (a report rebuilt from the same stores, the several sites a
test suite builds from one fixture) need not lay out and render it again: ``memo`` keys a chart
function's call by a canonical form of every argument but the path (dataclasses, floats by their
bits, arrays by their bytes, formatting functions by their code and captured values) and the
registry it colours and orders by, and writes the remembered bytes atomically where the first
call drew them; ``remembered`` does the same for a plot that saves itself (the sweep and stress
plots, inside their layout check). An argument it cannot put in canonical form makes the call draw
as usual.

Opt-in, for a test suite whose processes draw the same charts: ``COMPARE_CHART_MEMO_DIR`` names a
folder that this process and others setting it (xdist's workers, the command-line processes they
start) share; a chart missing from memory is read there (one JSON file per key, written
atomically) before it is drawn. A file that is absent, unreadable or not of this form is drawn
as usual. Off unless the variable is set; ``forget`` stops reading it until ``recall_from_disk``.
"""
from __future__ import annotations

import base64
import dataclasses
import functools
import hashlib
import json
import os
import types
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Callable, TypeVar

import numpy as np

from compare.files import atomic_write

KEPT = 96                       # charts remembered per process (a PNG is tens of kB)
DISK_ENV = "COMPARE_CHART_MEMO_DIR"
_disk_reads = True              # off after forget(): a test that must see its charts drawn
_CHARTS: OrderedDict[str, tuple[Any, list[bytes | None]]] = OrderedDict()
F = TypeVar("F", bound=Callable[..., None])
T = TypeVar("T")


class Unkeyable(Exception):
    """An argument without a canonical form: the chart is drawn, not remembered."""


def canon(v: Any) -> Any:
    """A hashable, repr-stable form of ``v`` that equal arguments share and different ones do not."""
    if v is None or v is Ellipsis or isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, float):
        return ("f", v.hex())
    if isinstance(v, Path):
        return ("path", str(v))
    if isinstance(v, (list, tuple)):
        return ("seq", tuple(canon(x) for x in v))
    if isinstance(v, (set, frozenset)):
        return ("set", tuple(sorted(repr(canon(x)) for x in v)))
    if isinstance(v, Mapping):
        return ("map", tuple(sorted((repr(canon(k)), canon(x)) for k, x in v.items())))
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return (type(v).__qualname__, tuple((f.name, canon(getattr(v, f.name))) for f in dataclasses.fields(v)))
    if isinstance(v, (np.ndarray, np.generic)):
        a = np.asarray(v)
        return ("nd", str(a.dtype), a.shape, hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest())
    if isinstance(v, functools.partial):
        return ("partial", canon(v.func), canon(v.args), canon(v.keywords))
    if isinstance(v, types.FunctionType):
        cells = tuple(canon(c.cell_contents) for c in v.__closure__ or ())
        return ("fn", v.__module__, v.__qualname__, _code(v.__code__), canon(v.__defaults__),
                canon(v.__kwdefaults__), cells)
    if isinstance(v, bytes):
        return ("bytes", hashlib.sha256(v).hexdigest())
    if isinstance(v, types.BuiltinFunctionType):
        return ("builtin", v.__module__, v.__qualname__)
    raise Unkeyable(type(v).__qualname__)


def _code(c: types.CodeType) -> Any:
    """A code object by its instructions, constants and names (marshal's bytes are not stable:
    its back-reference flags follow reference counts)."""
    return ("code", c.co_code.hex(), tuple(_code(x) if isinstance(x, types.CodeType) else canon(x)
                                           for x in c.co_consts), c.co_names, c.co_varnames, c.co_freevars)


def _registry() -> Any:
    """What the charts colour and order frameworks by (a test may register a backend)."""
    import backends
    from compare.render.colors import backend_color
    return tuple((n, b.display_order, backend_color(n)) for n, b in backends.BACKENDS.items())


def _stamp(f: Path) -> tuple[int, int] | None:
    try:
        st = f.stat()
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size)


Kept = tuple[Any, list[bytes | None]]


def _disk(k: str) -> Path | None:
    d = os.environ.get(DISK_ENV)
    return Path(d) / f"{k}.json" if d else None


def _disk_get(k: str, n: int) -> Kept | None:
    """The chart of key ``k`` (``n`` files) another process kept on disk, or None."""
    f = _disk(k)
    if f is None or not _disk_reads:
        return None
    try:
        got = json.loads(f.read_text())
        raws = [None if r is None else base64.b64decode(r, validate=True) for r in got["files"]]
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None
    return (got["result"], raws) if len(raws) == n else None


PNG_HEAD, PNG_TAIL = b"\x89PNG\r\n\x1a\n", b"IEND\xaeB`\x82"


def _whole(files: list[Path], raws: list[bytes | None]) -> bool:
    """Every file written, every PNG a whole one: a test that stubs the drawing (a few bytes for a
    picture, no CSV) keeps its stand-ins out of the other processes."""
    return all(r is not None and (f.suffix != ".png" or r.startswith(PNG_HEAD) and r.endswith(PNG_TAIL))
               for f, r in zip(files, raws))


def _disk_put(k: str, files: list[Path], kept: Kept) -> None:
    """Keep ``kept`` on disk for the other processes: only whole files and a plain result (JSON
    gives it back as it was); written atomically and not counted by the full-disk test hook (a
    cache, not an output); a failure leaves the next process to draw."""
    f = _disk(k)
    if f is None or type(kept[0]) not in (type(None), bool, int, str) or not _whole(files, kept[1]):
        return
    try:
        atomic_write(f, json.dumps({"result": kept[0], "files": [None if r is None else base64.b64encode(r).decode()
                                                                 for r in kept[1]]}), counted=False)
    except OSError:
        pass


def remembered(key: Any, files: list[Path], draw: Callable[[], T]) -> T:
    """``draw()``, which writes ``files`` (any it leaves absent stay absent), remembered by ``key``
    (its arguments but the paths, and the function that draws): equal keys write the remembered
    bytes atomically and give the remembered result, without drawing."""
    try:
        k = hashlib.sha256(repr((canon(key), [f.suffix for f in files], _registry())).encode()).hexdigest()
    except (Unkeyable, RecursionError, ValueError):
        return draw()
    kept = _CHARTS.get(k) or _disk_get(k, len(files))
    if kept is not None:
        _CHARTS[k] = kept
        _CHARTS.move_to_end(k)
        for f, raw in zip(files, kept[1]):
            if raw is not None:
                atomic_write(f, raw)
        result = kept[0]
    else:
        before = [_stamp(f) for f in files]
        result = draw()
        # only what this draw wrote (a file it left as it was is not its picture)
        _CHARTS[k] = (result, [f.read_bytes() if f.is_file() and _stamp(f) != was else None
                               for f, was in zip(files, before)])
        _disk_put(k, files, _CHARTS[k])
    while len(_CHARTS) > KEPT:
        _CHARTS.popitem(last=False)
    return result


def memo(draw: F) -> F:
    """``draw(path, *args, data=True, **kw)`` remembered by its arguments (not ``path``): the PNG at
    ``path`` and, with ``data``, the CSV beside it."""
    @functools.wraps(draw)
    def wrapper(path: Path, *args: Any, **kw: Any) -> None:
        path = Path(path)
        files = [path] + ([path.with_suffix(".csv")] if kw.get("data", True) else [])
        remembered((draw, args, kw), files, lambda: draw(path, *args, **kw))
    return wrapper  # type: ignore[return-value]


def forget() -> None:
    """Drop every remembered chart and stop reading the disk's (a test that must see a chart drawn)."""
    global _disk_reads
    _CHARTS.clear()
    _disk_reads = False


def recall_from_disk() -> None:
    """Read the disk's charts again after ``forget`` (tests/conftest.py: after each test)."""
    global _disk_reads
    _disk_reads = True


__all__ = ["DISK_ENV", "KEPT", "Unkeyable", "canon", "forget", "memo", "recall_from_disk", "remembered"]
