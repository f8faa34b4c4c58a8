"""Files written whole: every write of the project goes through a temporary file in the same
directory and a rename (``atomic_write``), so a reader never sees half a file and a full disk
leaves the previous content. The lowest module of compare/: it imports nothing of the project,
so a figure check or a store can use it without an import cycle."""
from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path
from typing import Any

_WRITES = [0]          # atomic writes of this process, for the COMPARE_FAULT_DISK test hook


def _disk_fault(f: Any, data: bytes) -> None:
    """Test hook: COMPARE_FAULT_DISK=N makes every atomic write of this process after the first N
    fail as a full disk does (half the data written, then OSError ENOSPC)."""
    limit = os.environ.get("COMPARE_FAULT_DISK", "")
    if not limit.isdigit():
        return
    _WRITES[0] += 1
    if _WRITES[0] > int(limit):
        f.write(data[: len(data) // 2])
        f.flush()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def atomic_write(path: Path, data: str | bytes, counted: bool = True) -> None:
    """Write via a temporary file in the same directory and rename, so a reader never sees half
    a file and a failed write (a full disk) leaves neither a partial file nor the temporary; the
    file keeps its previous content. An OSError names ``path``, not the temporary. ``counted``:
    the write counts toward the COMPARE_FAULT_DISK test hook (not a cache's own bookkeeping)."""
    path = Path(path)
    raw = data.encode() if isinstance(data, str) else data
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}{TEMP_MARK}", suffix=TEMP_SUFFIX)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            if counted:
                _disk_fault(f, raw)
            f.write(raw)
        os.chmod(tmp, 0o644)          # mkstemp creates 0600; results are meant to be shared
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.filename != str(path):
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise


def save_figure(fig: Any, path: Path, **kwargs: Any) -> None:
    """``fig.savefig`` into memory, then ``atomic_write``: a full disk leaves the old picture or
    none, never half a PNG. Every plot of every suite is saved through here."""
    import io
    buf = io.BytesIO()
    kwargs.setdefault("format", Path(path).suffix.lstrip(".") or "png")
    fig.savefig(buf, **kwargs)
    atomic_write(Path(path), buf.getvalue())


TEMP_SUFFIX = ".tmp"
TEMP_MARK = ".compare-"       # in every temporary's name: clean-up touches no file of the user's
