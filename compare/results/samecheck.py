"""``python -m compare.results.samecheck A B``: do two result folders say the same thing?

For a refactoring that must change nothing: run ``compare all --quick --save-arrays --out A``
before it and ``--out B`` after, then compare. Same means: the same suite and format, the same set
of cells (by ``compare.spec.key``), per cell the same fields, recursively, with equal values
except where a value is a measurement or describes the environment (``MEASURED``: only its keys
must agree; ``FREE``: nothing about it), and the same saved arrays (``compare.results.store.array_file``:
the same names, dtypes, shapes and bytes). Each difference is one line; exit 0 when there is
none, 1 when there is one, 2 when a folder cannot be read.
"""
from __future__ import annotations

import json
import sys
import zipfile
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from compare.spec import IDENTITY, key
from compare.results.store import SUITES, StoreError, array_file

# Record fields (dotted paths) whose values are measurements or environment: timings, memory,
# the host, the framework versions, the run's hardware yardstick and the cell's own launch floor.
# Their keys must still agree.
MEASURED = ("time", "throughput", "memory", "host", "host_load_1m", "host_cores", "versions",
            "hardware", "cell_floor", "machine")
# Fields whose very shape is a measurement or the environment: the noise verdict's reasons and the
# host profile (what the host did), a traceback (file paths and line numbers of the code).
FREE = ("time.noise.reasons", "time.host_profile", "traceback")


def _under(path: str, roots: tuple[str, ...]) -> bool:
    return any(path == r or path.startswith(r + ".") for r in roots)


def diff_values(a: Any, b: Any, path: str) -> Iterator[str]:
    """Lines naming where ``a`` and ``b`` (a record's JSON values at ``path``) differ."""
    if _under(path, FREE):
        return
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            sub = f"{path}.{k}" if path else k
            if k not in b:
                if not _under(sub, FREE):
                    yield f"{sub}: only in A"
            elif k not in a:
                if not _under(sub, FREE):
                    yield f"{sub}: only in B"
            else:
                yield from diff_values(a[k], b[k], sub)
        return
    if _under(path, MEASURED):
        if isinstance(a, dict) != isinstance(b, dict):
            yield f"{path}: {_kind(a)} in A, {_kind(b)} in B"
        return
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            yield from diff_values(x, y, f"{path}[{i}]")
        return
    if type(a) is not type(b) or a != b:
        yield f"{path}: {_short(a)} in A, {_short(b)} in B"


def _kind(v: Any) -> str:
    return "an object" if isinstance(v, dict) else type(v).__name__


def _short(v: Any) -> str:
    text = json.dumps(v, sort_keys=True)
    return text if len(text) <= 80 else text[:77] + "..."


def _name(rec: dict[str, Any], params: bool = False) -> str:     # a stored record's JSON
    """A cell's identity in a line (its parameters where two cells may differ only in them)."""
    return "/".join(str(rec.get(f, "default")) for f in IDENTITY) + \
        (f" {json.dumps(rec.get('params'), sort_keys=True)}" if params else "") + \
        (f" {json.dumps(rec['tags'], sort_keys=True)}" if rec.get("tags") else "")


def _array_name(folder: Path, rec: dict[str, Any]) -> str:     # a stored record's JSON
    try:
        return array_file(folder, rec).name
    except StoreError:
        return ""


def read(folder: Path) -> dict[str, Any]:     # a stored results file's JSON
    """The one results file in ``folder`` as parsed JSON (not upgraded: the bytes as stored)."""
    found = [folder / f for f in SUITES.values() if (folder / f).is_file()]
    if len(found) != 1:
        raise StoreError(f"{folder}: expected one of {', '.join(SUITES.values())}, found {len(found)}")
    try:
        data = json.loads(found[0].read_text())
    except (OSError, ValueError) as exc:
        raise StoreError(f"cannot read {found[0]}: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("records"), list):
        raise StoreError(f"{found[0]}: no list of records")
    return data


def diff_arrays(pa: Path, pb: Path) -> Iterator[str]:
    """Lines naming how two saved .npz files differ (names, dtypes, shapes or any bit)."""
    with np.load(pa) as za, np.load(pb) as zb:
        names_a, names_b = set(za.files), set(zb.files)
        for n in sorted(names_a ^ names_b):
            yield f"array {n!r}: only in {'A' if n in names_a else 'B'}"
        for n in sorted(names_a & names_b):
            x, y = za[n], zb[n]
            if x.dtype != y.dtype or x.shape != y.shape:
                yield f"array {n!r}: {x.dtype}{list(x.shape)} in A, {y.dtype}{list(y.shape)} in B"
            elif x.tobytes() != y.tobytes():
                bad = int(np.count_nonzero(np.frombuffer(x.tobytes(), np.uint8)
                                           != np.frombuffer(y.tobytes(), np.uint8)))
                yield f"array {n!r}: bits differ ({bad} bytes of {x.nbytes})"


def differences(a: Path, b: Path) -> list[str]:
    """Every difference between result folders ``a`` and ``b``, one line each."""
    da, db = read(a), read(b)
    out = [f"{f}: {_short(da.get(f))} in A, {_short(db.get(f))} in B"
           for f in ("format_version", "suite") if da.get(f) != db.get(f)]
    ra = {key(r): r for r in da["records"]}
    rb = {key(r): r for r in db["records"]}
    for k in sorted(ra.keys() - rb.keys()):
        out.append(f"{_name(ra[k], params=True)}: cell only in A")
    for k in sorted(rb.keys() - ra.keys()):
        out.append(f"{_name(rb[k], params=True)}: cell only in B")
    used = {_array_name(d, r) for d, recs in ((a, ra), (b, rb)) for r in recs.values()}
    for k in [k for k in ra if k in rb]:
        rec_a, rec_b = ra[k], rb[k]
        name = _name(rec_a)
        out += [f"{name}: {line}" for line in diff_values(rec_a, rec_b, "")]
        try:
            fa, fb = array_file(a, rec_a), array_file(b, rec_b)
        except StoreError:
            continue
        if fa.is_file() != fb.is_file():
            out.append(f"{name}: arrays file {fa.name} only in {'A' if fa.is_file() else 'B'}")
        elif fa.is_file():
            try:
                out += [f"{name}: {line}" for line in diff_arrays(fa, fb)]
            except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
                out.append(f"{name}: arrays unreadable ({type(exc).__name__}: {exc})")
    # files in arrays/ that no common cell names (a cell only on one side is reported above)
    files_a = {p.name for p in (a / "arrays").glob("*.npz")}
    files_b = {p.name for p in (b / "arrays").glob("*.npz")}
    for n in sorted((files_a ^ files_b) - used):
        out.append(f"arrays/{n}: only in {'A' if n in files_a else 'B'}")
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0].startswith("-"):
        print("usage: python -m compare.results.samecheck FOLDER_A FOLDER_B", file=sys.stderr)
        return 2
    try:
        lines = differences(Path(argv[0]), Path(argv[1]))
    except StoreError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for line in lines:
        print(line)
    if not lines:
        print(f"same: {argv[0]} and {argv[1]}", file=sys.stderr)
    return 1 if lines else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
