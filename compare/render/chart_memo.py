"""A chart drawn once per process: the same figure asked for again is written from memory.

``compare.render.charts`` draws byte-for-byte the same PNG (and CSV) for the same arguments, so a
second request with equal arguments (a report rebuilt from the same stores, the several sites a
test suite builds from one fixture) need not lay out and render it again: ``memo`` keys a chart
function's call by a canonical form of every argument but the path (dataclasses, floats by their
bits, arrays by their bytes, formatting functions by their code and captured values) and the
registry it colours and orders by, and writes the remembered bytes atomically where the first
call drew them. An argument it cannot put in canonical form makes the call draw as usual.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import marshal
import types
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable, TypeVar

from compare.files import atomic_write

KEPT = 96                       # charts remembered per process (a PNG is tens of kB)
_CHARTS: OrderedDict[str, tuple[bytes, bytes | None]] = OrderedDict()
F = TypeVar("F", bound=Callable[..., None])


class Unkeyable(Exception):
    """An argument without a canonical form: the chart is drawn, not remembered."""


def canon(v: Any) -> Any:
    """A hashable, repr-stable form of ``v`` that equal arguments share and different ones do not."""
    if v is None or isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, float):
        return ("f", v.hex())
    if isinstance(v, Path):
        return ("path", str(v))
    if isinstance(v, (list, tuple)):
        return ("seq", tuple(canon(x) for x in v))
    if isinstance(v, (set, frozenset)):
        return ("set", tuple(sorted(repr(canon(x)) for x in v)))
    if isinstance(v, dict):
        return ("map", tuple(sorted((repr(canon(k)), canon(x)) for k, x in v.items())))
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return (type(v).__qualname__, tuple((f.name, canon(getattr(v, f.name))) for f in dataclasses.fields(v)))
    if type(v).__module__ == "numpy":
        import numpy as np
        a = np.asarray(v)
        return ("nd", str(a.dtype), a.shape, hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest())
    if isinstance(v, functools.partial):
        return ("partial", canon(v.func), canon(v.args), canon(v.keywords))
    if isinstance(v, types.FunctionType):
        cells = tuple(canon(c.cell_contents) for c in v.__closure__ or ())
        return ("fn", v.__module__, v.__qualname__, hashlib.sha256(marshal.dumps(v.__code__)).hexdigest(),
                canon(v.__defaults__), canon(v.__kwdefaults__), cells)
    if isinstance(v, types.BuiltinFunctionType):
        return ("builtin", v.__module__, v.__qualname__)
    raise Unkeyable(type(v).__qualname__)


def _registry() -> Any:
    """What the charts colour and order frameworks by (a test may register a backend)."""
    import backends
    from compare.render.colors import backend_color
    return tuple((n, b.display_order, backend_color(n)) for n, b in backends.BACKENDS.items())


def memo(draw: F) -> F:
    """``draw(path, *args, data=True, **kw)`` remembered by its arguments (not ``path``): the PNG at
    ``path`` and, with ``data``, the CSV beside it."""
    @functools.wraps(draw)
    def wrapper(path: Path, *args: Any, **kw: Any) -> None:
        path = Path(path)
        try:
            key = hashlib.sha256(repr((draw.__qualname__, path.suffix, canon(args), canon(kw),
                                       _registry())).encode()).hexdigest()
        except (Unkeyable, RecursionError, ValueError):
            draw(path, *args, **kw)
            return
        csv = path.with_suffix(".csv") if kw.get("data", True) else None
        kept = _CHARTS.get(key)
        if kept is not None:
            _CHARTS.move_to_end(key)
            atomic_write(path, kept[0])
            if csv is not None and kept[1] is not None:
                atomic_write(csv, kept[1])
            return
        draw(path, *args, **kw)
        _CHARTS[key] = (path.read_bytes(), csv.read_bytes() if csv is not None else None)
        while len(_CHARTS) > KEPT:
            _CHARTS.popitem(last=False)
    return wrapper  # type: ignore[return-value]


def forget() -> None:
    """Drop every remembered chart (a test that must see a chart drawn)."""
    _CHARTS.clear()


__all__ = ["KEPT", "Unkeyable", "canon", "forget", "memo"]
