"""A site written whole: built in a sibling folder, then swapped in place of the old one.

A rebuild over an existing site must never leave the old pages linking figures the new build has
not drawn yet (or has deleted). So the build writes into ``.NAME.building-<pid>`` beside
``--out`` (the same parent: one filesystem, where a rename is atomic), then the two folders trade
places in one step (``renameat2(RENAME_EXCHANGE)`` on Linux, ``renamex_np(RENAME_SWAP)`` on
macOS; where neither exists the old is renamed away and the new one in, a Ctrl-C or SIGTERM
held until both are done), and the old site, now under the temporary name, is deleted. A Ctrl-C
or crash at any point leaves the complete old site or the complete new one at ``--out``, and at
most that temporary folder, which the next build of the same site removes (when its PID no longer
runs); only a SIGKILL between the two renames, where there is no exchange, leaves ``--out``
missing (the old site is then ``.NAME.building-<pid>.old``). Nothing is followed through a symbolic link: ``--out`` itself must not be one, a temporary
name that is one is unlinked, and only names of exactly that pattern are removed. A folder that
holds anything but a site (no ``site.json``) is refused: it would be replaced whole.
"""
from __future__ import annotations

import ctypes
import errno
import glob
import os
import re
import shutil
import signal
import stat
import sys
from pathlib import Path
from typing import Any, Callable

from compare.options import UsageError
from compare.files import TEMP_MARK, TEMP_SUFFIX

MANIFEST = "site.json"          # every site holds it (compare/site/assemble.py writes it)
LOCK = ".compare.running.lock"          # the driver's lock (compare/running/lock.py), in --out while it runs
SUFFIX = ".building-"


def target(out: str | Path) -> Path:
    """``--out`` as an absolute path whose last part is the folder itself (``.`` and ``..``
    resolved), refused where it is a symbolic link, a file, or names no folder of its own."""
    out = Path(out)
    if out.is_symlink():
        raise UsageError(f"--out {out}: is a symbolic link; give the folder itself")
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: is a file, not a directory")
    real = out.resolve()
    if real == real.parent:
        raise UsageError(f"--out {out}: the file system's root; give a folder for the site")
    return real


# what a build writes (and the lock and temporaries of a driver): a folder holding anything else
# is not replaced, whatever it holds
TOP = re.compile(r"[\w.-]+\.(html|md|png)|" + re.escape(MANIFEST) + "|" + re.escape(LOCK))
FIGURES = re.compile(r"[\w.-]+\.(png|csv)")
TEMPORARY = re.compile(r"\..*" + re.escape(TEMP_MARK) + r".*" + re.escape(TEMP_SUFFIX))


def _foreign(site: Path) -> str | None:
    """The first entry of an earlier site that its build did not write, or None."""
    for p in sorted(site.iterdir()):
        if p.name == "figures" and p.is_dir() and not p.is_symlink():
            bad = next((f for f in sorted(p.iterdir()) if not (FIGURES.fullmatch(f.name) or TEMPORARY.fullmatch(f.name))
                        or f.is_symlink() or not f.is_file()), None)
            if bad is not None:
                return f"figures/{bad.name}"
        elif not (TOP.fullmatch(p.name) or TEMPORARY.fullmatch(p.name)) or p.is_symlink() or not p.is_file():
            return p.name
    return None


def check_replaceable(out: str | Path) -> Path:
    """``target(out)``, refused unless it is new, empty, or an earlier site holding only what a
    build writes (it is replaced whole: a file of the user's in it would go with it)."""
    real = target(out)
    if not real.is_dir():
        return real
    if not (real / MANIFEST).is_file():
        foreign = sorted(p.name for p in real.iterdir() if p.name != LOCK)
        if foreign:
            raise UsageError(f"--out {out}: holds files that are not a site ({foreign[0]}; no {MANIFEST}): "
                             "the site replaces its folder whole, so give a new or empty folder, or an earlier site")
    elif (bad := _foreign(real)) is not None:
        raise UsageError(f"--out {out}: an earlier site, but {bad} in it is not a page or figure: the site "
                         "replaces its folder whole; move that file out, or give a new folder")
    return real


def temp_folder(out: Path, pid: int | None = None) -> Path:
    return out.parent / f".{out.name}{SUFFIX}{os.getpid() if pid is None else pid}"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):     # gone, or a number no PID can be
        return False
    except OSError:                  # someone else's process (or not ours to ask): alive
        return True
    return True


def _remove(p: Path) -> None:
    """Delete ``p`` without following a symbolic link (a link is unlinked, not its target)."""
    if p.is_symlink() or p.is_file():
        p.unlink(missing_ok=True)
    elif p.is_dir():
        shutil.rmtree(p, ignore_errors=True)


def remove_stale(out: Path) -> list[Path]:
    """Temporary folders of earlier builds of ``out`` whose driver is gone (killed mid-build)."""
    pattern = re.compile(re.escape(f".{out.name}{SUFFIX}") + r"(\d+)(\.old)?")
    gone = []
    for p in out.parent.glob(glob.escape(f".{out.name}{SUFFIX}") + "*"):
        m = pattern.fullmatch(p.name)
        if m and (int(m.group(1)) == os.getpid() or not _alive(int(m.group(1)))):
            _remove(p)
            gone.append(p)
    return gone


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step; False where this system or file system cannot."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return False
    if sys.platform.startswith("linux") and hasattr(libc, "renameat2"):
        at_fdcwd, rename_exchange = -100, 2
        rc = libc.renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange)
    elif sys.platform == "darwin" and hasattr(libc, "renamex_np"):
        rc = libc.renamex_np(os.fsencode(a), os.fsencode(b), 2)      # RENAME_SWAP
    else:
        return False
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _rename_twice(new: Path, out: Path) -> None:
    """The old ``out`` renamed to ``<new>.old``, ``new`` into ``out``, the old one then under
    ``new``'s name (deleted next). A Ctrl-C or SIGTERM between the renames is held (its Python
    handler, which runs in the main thread, only noted) and delivered once both are done."""
    old = new.with_name(new.name + ".old")
    caught: list[int] = []
    held: dict[signal.Signals, Any] = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            held[sig] = signal.signal(sig, lambda signum, frame: caught.append(signum))
    except ValueError:                  # not the main thread: its signals are not ours to hold
        pass
    try:
        os.rename(out, old)
        try:
            os.rename(new, out)
        except OSError:
            os.rename(old, out)
            raise
        os.rename(old, new)
    finally:
        for held_sig, handler in held.items():
            signal.signal(held_sig, handler)
        if caught:
            signal.raise_signal(caught[0])


def swap_in(new: Path, out: Path) -> None:
    """``new`` becomes ``out``; the old ``out`` (if any) is left under ``new``'s name."""
    if not out.exists() and not out.is_symlink():
        os.rename(new, out)
    elif not _exchange(new, out):
        _rename_twice(new, out)


def write_whole(out: str | Path, write: Callable[[Path], list[Path]]) -> list[Path]:
    """Call ``write(folder)`` on a fresh sibling of ``out``, then swap it in whole; the files
    written, under ``out``. On any failure (Ctrl-C included) ``out`` is as it was."""
    out = check_replaceable(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(out)
    tmp = temp_folder(out)
    tmp.mkdir()
    if out.is_dir():            # the new folder keeps the old one's permissions
        os.chmod(tmp, stat.S_IMODE(out.stat().st_mode))
    try:
        written = write(tmp)
        swap_in(tmp, out)
    finally:
        _remove(tmp)            # the half-built site on failure, the old one after the swap
        if out.is_dir():        # an old site renamed away is removed only once --out stands again
            _remove(tmp.with_name(tmp.name + ".old"))
    return [out / p.relative_to(tmp) for p in written]
