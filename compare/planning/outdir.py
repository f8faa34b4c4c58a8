"""The paths a command writes or reads: ``--out`` folders (checked, measured for free space,
claimed under a lock), ``--page`` files and hand-written notes. Every refusal is one
``UsageError`` line (exit 2) before anything is written."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from compare.options import UsageError, shown


def _exists(p: Path) -> bool:
    try:
        return p.exists()
    except OSError:              # a name too long, a directory we may not search: not usable
        return False


def _existing_ancestor(path: Path) -> Path:
    return next(p for p in (path.absolute(), *path.absolute().parents) if _exists(p) or p == p.parent)


def _missing_dirs(path: Path) -> list[Path]:
    """The directories ``mkdir(parents=True)`` would create for ``path``, deepest first."""
    import itertools
    return list(itertools.takewhile(lambda p: not _exists(p), (path.absolute(), *path.absolute().parents)))


INSIDE_BYTES = 256      # names a suite writes under its --out (arrays/.<cell>.npz.compare-*.tmp)


def check_length(path: str, flag: str, inside: int = 0) -> None:
    """Refuse a path the file system cannot name (ENAMETOOLONG) in one line: a component past
    NAME_MAX, or the path plus ``inside`` bytes (the files written under it) past PATH_MAX."""
    raw, base = os.fsencode(path), _existing_ancestor(Path(path))
    limits = []
    for name, default in (("PC_NAME_MAX", 255), ("PC_PATH_MAX", 4096)):
        try:
            limits.append(os.pathconf(base, name) or default)
        except (OSError, ValueError):
            limits.append(default)
    longest = max(raw.split(b"/"), key=len)
    head = f"{flag} {shown(path[:60])}{'...' if len(path) > 60 else ''}"
    if len(longest) > limits[0]:
        raise UsageError(f"{head}: a name in it is {len(longest)} bytes long; this file system allows {limits[0]}")
    if len(raw) + inside >= limits[1]:
        raise UsageError(f"{head}: too long ({len(raw)} bytes" + (f" + {inside} for the files in it" if inside
                         else "") + f"; this file system allows {limits[1]})")


def check_output(path: str, flag: str = "--out") -> Path:
    """--out checked without writing anything: not empty, not a file, not under a file, on a
    writable filesystem. ``output_directory`` then creates it."""
    if not path or not path.strip():
        raise UsageError(f"{flag} is empty (give a directory)")
    check_length(path, flag, INSIDE_BYTES)
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{flag} {path}: is a file, not a directory")
    base = _existing_ancestor(out)
    if not base.is_dir():
        raise UsageError(f"{flag} {path}: {base} is a file, not a directory")
    if not os.access(base, os.W_OK | os.X_OK):
        raise UsageError(f"{flag} {path}: not writable ({base} does not allow it)")
    return out


def check_page(page: str | None, title: str | None = None) -> None:
    """--page FILE and --title checked before anything runs or is written: the page a file (not
    a directory) in a writable directory, the title one line of text (it is a Markdown heading)."""
    if title is not None and not all(c.isprintable() for c in title):
        raise UsageError(f"--title {shown(title)}: give one line of printable text")
    if page is None:
        return
    if not page.strip():
        raise UsageError("--page is empty (give a file)")
    check_length(page, "--page")
    p = Path(page)
    if p.is_dir():
        raise UsageError(f"--page {page}: is a directory (give a file)")
    if p.exists() and not p.is_file():
        raise UsageError(f"--page {page}: not a regular file")
    check_output(str(p.parent), "--page's directory")
    if p.parent.is_dir():       # permissions do not tell (root on /proc): create a file there
        from compare.results.store import probe_write
        try:
            probe_write(p.parent)
        except OSError as exc:
            raise UsageError(f"--page {page}: cannot write there ({exc.strerror or exc})") from None


def free_bytes(path: Path) -> int:
    """Free space for an unprivileged writer on the filesystem of ``path`` (or its nearest
    existing ancestor). Test hook: COMPARE_FAULT_FREE=BYTES pretends that much is free."""
    import shutil
    fake = os.environ.get("COMPARE_FAULT_FREE", "")
    if fake.isdigit():
        return int(fake)
    return shutil.disk_usage(_existing_ancestor(Path(path))).free


def gib(n: float) -> str:
    return f"{n / 2**30:.2f} GiB" if n >= 2**28 else f"{n / 2**20:.0f} MiB"


def output_directory(path: str, need_bytes: float = 0.0, what: str = "the results") -> Path:
    """The output directory, checked (``check_output``), with room for ``need_bytes`` (refused
    before anything is written otherwise), then created; before any cell runs."""
    out = check_output(path)
    have = free_bytes(out)
    if need_bytes > have:
        raise UsageError(f"--out {path}: {gib(have)} free, {what} need about {gib(need_bytes)}; "
                         "free some space or give another --out")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {path}: cannot write there ({exc.strerror or exc})") from None
    return out


def claim_output(path: str, need_bytes: float = 0.0, what: str = "the results", lock_name: str | None = None
                 ) -> tuple[Path, Any]:
    """``output_directory`` and then this driver's lock on it (compare.running.lock; a second driver on
    the same --out is refused with one line naming the holder's PID), with the temporary files
    a killed driver left there removed. ``lock_name``: a lock other than the writers' (publish
    holds its own while its parts lock DIR themselves; it removes no temporary file of theirs).
    Returns (directory, lock): release the lock when done
    (``with lock:``); the kernel releases it if the driver dies."""
    from compare.running.lock import Busy, DirectoryLock
    from compare.results.store import remove_stale_temps
    made = _missing_dirs(Path(path))
    out = output_directory(path, need_bytes, what)
    # a refusal or failure under the lock removes the directories made here if still empty
    lock = DirectoryLock(out, made=made) if lock_name is None else DirectoryLock(out, made=made, name=lock_name)
    try:
        lock.acquire()
    except Busy as exc:
        lock.remove_made()
        raise UsageError(str(exc)) from None
    except OSError as exc:          # creating the lock file is the first write: the write test
        lock.remove_made()
        raise UsageError(f"--out {path}: cannot write there ({exc.strerror or exc})") from None
    if lock_name is None:
        remove_stale_temps(out)
    return out, lock


NOTES_BYTES = 2**20          # hand-written notes: a page's worth, bounded


def read_notes(path: str | None) -> str:
    """--notes FILE's text ('' without one)."""
    if not path:
        return ""
    from compare.results.store import StoreError, read_bounded
    try:
        return read_bounded(Path(path), NOTES_BYTES)
    except StoreError as exc:
        raise UsageError(f"--notes: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read --notes {path}: {getattr(exc, 'strerror', None) or exc}") from None
