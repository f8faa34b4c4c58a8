"""The one results store: load / validate / upgrade / merge / save records, and cell arrays.

Every suite keeps one JSON file (``results.json``, ``sweep.json``, ``stress.json``) of the same
shape (pyperf-style: versioned, and a merge of different suites or versions is refused):

    {"format_version": 2, "suite": "run" | "sweep" | "stress",
     "runs": [environment, ...],          one per invocation that added records (provenance)
     "records": [record, ...],            compare.results.record.Record, one per cell key
     "analysis": {...}}                   what a suite derives from its records (stress findings)

Files of an older format (compare.results.record says what changed) are read and upgraded in memory by
their suite's format (compare.results.formats);
saving writes the newest. Every write is atomic (temporary file + rename in the same directory,
removed on failure).
"""
from __future__ import annotations

import errno
import json
import math
import os
import re
import tempfile
import zipfile
from pathlib import Path
from typing import Any, Iterable, Mapping, Self

import numpy as np

from backends.base import DEFAULT_VARIANT
from compare.files import TEMP_MARK, TEMP_SUFFIX, atomic_write
from compare.results.analysis import Analysis, analysis_of
from compare.results.environment import RunEnvironment, environment_of
from compare.results.formats import FORMATS
from compare.results.record import FORMAT_VERSION, Record, RecordError
from compare.results.records import arrays_problem, store_problem
from compare.results.records import show as _show
from compare.spec import KEPT_ON_RESUME, Identity

SUITES = {name: f.file for name, f in FORMATS.items()}     # suite -> its file's name


class StoreError(ValueError):
    """A results file that cannot be used; the message is one line naming the file."""


MAX_FILE_BYTES = 512 * 2**20      # far above any real results file; a bigger one is refused


def read_bounded(path: Path, limit: int) -> str:
    """A regular file's text, at most ``limit`` bytes: a FIFO, a device (``/dev/zero``) or a
    symbolic link is refused before it is read, so no read can block or exhaust memory."""
    import stat
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise StoreError(f"cannot read {path}: a symbolic link (give the file it points to)") from None
        raise
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError(errno.EISDIR, "is a directory", str(path))
        if not stat.S_ISREG(st.st_mode):
            raise StoreError(f"cannot read {path}: not a regular file")
        raw = f.read(limit + 1)
    if len(raw) > limit:
        raise StoreError(f"cannot read {path}: larger than {limit // 2**20} MiB")
    return raw.decode("utf-8")


def jsonable(x: Any) -> Any:
    """Plain JSON types; non-finite floats as the strings 'nan', 'inf', '-inf'."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)) and not isinstance(x, bool):
        x = float(x)
        return x if math.isfinite(x) else str(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


OUTPUT_SUBDIRS = ("", "arrays", "plots")    # where a suite writes inside its --out


def run_environments(env: RunEnvironment) -> list[RunEnvironment]:
    """The run environments one entry of a store's ``runs`` stands for: the entry itself, or for
    a merged report's entry (``environments``, written by ``compare report``) those it merged, in
    order (a merge of merges flattened; the store bounds their nesting). A ``stress --merge``
    entry is its own run's environment that also names its inputs (``merged_from``): kept."""
    out: list[RunEnvironment] = []
    todo = [env]
    while todo:
        e = todo.pop(0)
        if "environments" in e:
            todo[:0] = list(e.get("environments") or [])
        else:
            out.append(e)
    return out


def probe_write(directory: Path) -> None:
    """Create and remove a temporary file in ``directory`` (named as the other temporaries, so a
    killed probe's is cleaned up); an OSError where the directory takes no file."""
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".probe{TEMP_MARK}", suffix=TEMP_SUFFIX)
    os.close(fd)
    os.unlink(tmp)


def remove_stale_temps(directory: Path) -> list[Path]:
    """Temporary files of atomic writes (``.NAME.compare-XXXX.tmp``) left in ``directory`` (and its
    arrays/ and plots/) by a driver that was killed mid-write; only call while holding the
    directory's lock (compare.running.lock), when no other driver can be writing there."""
    removed = []
    for sub in OUTPUT_SUBDIRS:
        d = Path(directory) / sub
        if not d.is_dir():
            continue
        for p in d.glob(f".*{TEMP_MARK}*{TEMP_SUFFIX}"):
            if p.is_file():
                try:
                    p.unlink()
                    removed.append(p)
                except OSError:
                    pass
    return removed


def _upgrade(data: Any, path: Path) -> dict[str, Any]:     # the file's JSON
    """Any supported layout -> format 2 (in memory), its records loaded (``Record.from_json``)."""
    if not isinstance(data, dict):
        raise StoreError(f"{path}: not a results file (top level is {type(data).__name__}, not an object)")
    version = data.get("format_version")
    if version is None:                                   # format 1: three layouts
        if "rows" in data:
            suite = "stress"
            analysis = {k: data[k] for k in ("rows", "series", "provenance") if k in data}
            data = {"suite": suite, "runs": [data.get("environment", {})], "records": [],
                    "analysis": analysis}
        elif "runs" in data:
            data = {"suite": "sweep", "runs": data["runs"], "records": data.get("records")}
        elif "environment" in data:
            data = {"suite": "run", "runs": [data["environment"]], "records": data.get("records")}
        else:
            raise StoreError(f"{path}: not a results file (no format_version, records or rows)")
        data["format_version"] = 1
    elif version != FORMAT_VERSION:
        raise StoreError(f"{path}: format_version {_show(version)} is not supported (this tool reads 1 and {FORMAT_VERSION})")
    if not isinstance(data.get("suite"), str) or data["suite"] not in SUITES:
        raise StoreError(f"{path}: unknown suite {_show(data.get('suite'))} (known: {', '.join(SUITES)})")
    if not isinstance(data.get("runs"), list) or not all(isinstance(r, dict) for r in data["runs"]):
        raise StoreError(f"{path}: 'runs' must be a list of objects")
    if not isinstance(data.get("records"), list):
        raise StoreError(f"{path}: 'records' must be a list")
    if not isinstance(data.setdefault("analysis", {}), dict):
        raise StoreError(f"{path}: 'analysis' must be an object")
    fmt = FORMATS[data["suite"]]
    upgrade = fmt.upgrade if data["format_version"] == 1 else None
    for i, rec in enumerate(data["records"]):
        try:
            data["records"][i] = Record.from_json(rec, upgrade, fmt.record_problem)
        except RecordError as exc:
            raise StoreError(f"{path}: record {i}: {exc}") from None
    # every field a later step reads, typed and in range, before any reader writes anything
    problem = store_problem(data)
    if problem is None and fmt.store_problem is not None:
        problem = fmt.store_problem(data)
    if problem is not None:
        raise StoreError(f"{path}: {problem}")
    version = data.pop("format_version")
    data["upgraded_from"] = version if version != FORMAT_VERSION else data.get("upgraded_from")
    return data


class Store:
    """Records of one suite in one JSON file, keyed by cell (a later record of a key replaces
    the earlier one); ``analysis`` is the suite's derived data."""

    def __init__(self, path: Path, suite: str, runs: list[RunEnvironment] | None = None,
                 records: Iterable[Record] = (), analysis: Analysis | None = None,
                 upgraded_from: int | None = None) -> None:
        if suite not in SUITES:
            raise ValueError(f"unknown suite {suite!r}")
        self.path, self.suite = Path(path), suite
        self.runs: list[RunEnvironment] = list(runs or [])     # the file's runs
        self.analysis: Analysis = analysis.copy() if analysis else {}     # the file's analysis (stress: its findings)
        self.upgraded_from = upgraded_from
        self._records: dict[str, Record] = {}
        self._encoded: dict[int, tuple[Record, str]] = {}     # to_json's text of each record
        for r in records:
            self.put(r)

    # ---- reading --------------------------------------------------------------------------
    @classmethod
    def read(cls, path: str | Path, suite: str | None = None) -> Self:
        """An existing file, validated; a different suite than asked for is refused."""
        path = Path(path)
        try:
            data = json.loads(read_bounded(path, MAX_FILE_BYTES))
        except StoreError:
            raise
        except RecursionError:
            raise StoreError(f"cannot read {path}: JSON nested too deeply") from None
        except FileNotFoundError:
            raise StoreError(f"cannot read {path}: no such file") from None
        except IsADirectoryError:
            raise StoreError(f"cannot read {path}: a directory, not a results file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise StoreError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
        except ValueError as exc:
            raise StoreError(f"cannot read {path}: not JSON ({exc})") from None
        data = _upgrade(data, path)
        if suite is not None and data["suite"] != suite:
            raise StoreError(f"{path}: holds {data['suite']} results, not {suite} results")
        runs = [environment_of(e) for e in data["runs"]]       # typed once read (checked: records.RUN)
        return cls(path, data["suite"], runs, data["records"], analysis_of(data["analysis"]), data["upgraded_from"])

    @classmethod
    def open(cls, directory: str | Path, suite: str, keep: bool = True) -> Self:
        """The suite's file in ``directory``: its records when ``keep`` and it exists, else empty."""
        path = Path(directory) / SUITES[suite]
        if keep and path.exists():
            return cls.read(path, suite)
        return cls(path, suite)

    # ---- records --------------------------------------------------------------------------
    @property
    def records(self) -> list[Record]:
        return list(self._records.values())

    def put(self, record: Record) -> None:
        self._records[record.key] = record

    def get(self, cell_key: str) -> Record | None:
        return self._records.get(cell_key)

    def done(self, cell_key: str) -> bool:
        """True when a rerun (--resume) keeps this cell's record instead of running it again."""
        r = self._records.get(cell_key)
        return r is not None and r.status in KEPT_ON_RESUME

    def merge(self, other: "Store") -> None:
        """Add ``other``'s runs and records (a later record of a cell wins)."""
        if other.suite != self.suite:
            raise StoreError(f"{other.path}: holds {other.suite} results; cannot merge into {self.suite} results")
        self.runs += other.runs
        for r in other.records:
            self.put(r)

    # ---- writing --------------------------------------------------------------------------
    def to_json(self) -> str:
        data = {"format_version": FORMAT_VERSION, "suite": self.suite, "runs": self.runs,
                "records": [], "analysis": self.analysis}
        if self.upgraded_from is not None:      # a file converted from an older format says so
            data["upgraded_from"] = self.upgraded_from
        text = json.dumps(jsonable(data), indent=1)
        if not self._records:
            return text
        # a run saves after every cell: each record (frozen) is encoded once, and its text put in
        # the list at its depth, as json.dumps(..., indent=1) of the whole would put it
        cache = self._encoded
        self._encoded = {id(r): cache.get(id(r)) or (r, json.dumps(jsonable(r.to_json()), indent=1))
                         for r in self.records}     # the record held: its id is not reused
        body = ",\n".join("  " + t.replace("\n", "\n  ") for _, t in self._encoded.values())
        head, mark, tail = text.partition('\n "records": []')
        assert mark, "the top-level records list"       # one line of indent 1: no string holds it
        return f'{head}\n "records": [\n{body}\n ]{tail}'

    def save(self) -> None:
        atomic_write(self.path, self.to_json())


# ---- arrays (--save-arrays): one .npz per cell beside the results file ------------------------
_NAME = re.compile(r"[A-Za-z0-9_]+")


def array_file(directory: Path, cell: Identity | Mapping[str, Any]) -> Path:   # or a stored record's JSON
    """``DIR/arrays/<scenario>-<backend>-<device>-<precision>[-<variant>].npz`` of a cell (a loaded
    record's ``identity``, or the JSON of one being written); the parts come from a record, so each
    must be a plain name (letters, digits, '_'): no path can leave arrays/."""
    parts: list[Any] = [cell.get(f) for f in ("scenario", "backend", "device", "precision")]   # checked below
    variant = cell.get("variant", DEFAULT_VARIANT)
    if variant != DEFAULT_VARIANT:
        parts.append(variant)
    bad = [p for p in parts if not isinstance(p, str) or not _NAME.fullmatch(p)]
    if bad:
        raise StoreError(f"record names no plain cell ({bad[0]!r} is not a name of letters, digits or '_')")
    return Path(directory) / "arrays" / ("-".join(parts) + ".npz")


def save_arrays(directory: Path, cell: Identity, arrays: dict[str, np.ndarray]) -> None:
    import io
    buf = io.BytesIO()
    # (numpy's stubs read ** as possibly setting savez's allow_pickle: bool)
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    atomic_write(array_file(directory, cell), buf.getvalue())


def load_arrays(directory: Path, cell: Identity, names: Iterable[str]) -> dict[str, np.ndarray] | None:
    """The named arrays of a cell saved beside a results file, or None (absent or unreadable:
    a truncated file must not take a report down)."""
    try:
        f = array_file(directory, cell)
    except StoreError:
        return None
    if not f.is_file() or f.is_symlink():
        return None
    try:
        with np.load(f) as z:
            names = [k for k in names if k in z.files]
            # shapes from the headers first: a record's sizes must not decide what is allocated
            if arrays_problem(cell, {k: _npy_header(z.zip, k) for k in names}) is not None:
                return None
            return {k: z[k] for k in names}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):
        return None


def _npy_header(zf: zipfile.ZipFile, name: str) -> tuple[tuple[int, ...], int]:
    """(shape, bytes) of an array in an .npz, read from its header without loading it."""
    with zf.open(f"{name}.npy") as fh:
        version = np.lib.format.read_magic(fh)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read(fh)
    return tuple(shape), int(np.prod(shape, dtype=np.float64) * dtype.itemsize)
