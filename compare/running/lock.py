"""One driver per output directory: an advisory lock on ``DIR/.compare.running.lock`` holding the PID.

Two drivers writing one results file would each save their own records over the other's, so
every suite takes this lock before it reads or writes anything in its ``--out``; a second driver
is refused with one line naming the holder's PID. The lock is ``fcntl.flock``: the kernel drops
it when its holder exits, however it exits (SIGKILL included), so a lock file left behind by a
dead driver is simply taken over. On a filesystem without flock (some network mounts) the file
is created exclusively instead, and one whose PID no longer runs counts as stale.
The file is removed on release, and a driver that leaves by an exception (a refusal, a failure)
also removes the directories its claim made (``made``) if they are still empty: a refused
command leaves nothing behind.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path

NAME = ".compare.running.lock"


class Busy(Exception):
    """Another live driver holds the directory; the message is one line naming its PID."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:          # someone else's process: alive
        return True
    except OSError:
        return False
    return True


def _read_pid(path: Path) -> int | None:
    try:
        text = path.read_text().strip()
        return int(text) if text else None
    except (OSError, ValueError):
        return None


class DirectoryLock:
    """``with DirectoryLock(out):`` or ``acquire()`` / ``release()``; raises ``Busy``."""

    def __init__(self, directory: str | Path, made: list[Path] | tuple[Path, ...] = (), name: str = NAME) -> None:
        self.directory = Path(directory)
        self.path = self.directory / name     # another name: a lock beside the writers' (publish's)
        self.made = list(made)        # directories created for this claim, deepest first
        self._fd: int | None = None
        self._exclusive = False       # the no-flock fallback holds the file itself

    def _busy(self, pid: int | None) -> Busy:
        who = f"PID {pid}" if pid is not None else "a PID it did not record"
        return Busy(f"--out {self.directory}: in use by another compare driver ({who}); "
                    "wait for it to finish or give another --out")

    def _open(self, flags: int) -> int:
        """The lock file, never through a symbolic link planted in its place (a link there would
        make the driver truncate and write its target)."""
        try:
            return os.open(self.path, flags | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
        except OSError as exc:
            if exc.errno == errno.ELOOP or self.path.is_symlink():
                raise Busy(f"--out {self.directory}: {NAME} is a symbolic link; refusing to follow it "
                           "(remove it, or give another --out)") from None
            raise

    def acquire(self) -> "DirectoryLock":
        import fcntl
        for _ in range(20):
            fd = self._open(os.O_RDWR | os.O_CREAT)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise self._busy(_read_pid(self.path)) from None
            except OSError as exc:
                os.close(fd)
                if exc.errno in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
                    return self._acquire_exclusive()
                raise
            try:        # the holder may have released (and unlinked) between our open and flock
                st, now = os.fstat(fd), os.stat(self.path)
                same = (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            self._fd = fd
            return self
        raise self._busy(_read_pid(self.path))

    def _acquire_exclusive(self) -> "DirectoryLock":
        """No flock here: create the file exclusively; a file whose PID is dead is taken over."""
        for _ in range(20):
            try:
                fd = self._open(os.O_WRONLY | os.O_CREAT | os.O_EXCL)
            except FileExistsError:
                pid = _read_pid(self.path)
                if pid is not None and (pid == os.getpid() or _pid_alive(pid)):
                    raise self._busy(pid) from None
                try:
                    os.unlink(self.path)      # stale: its driver is gone
                except FileNotFoundError:
                    pass
                continue
            os.write(fd, f"{os.getpid()}\n".encode())
            os.close(fd)
            self._exclusive = True
            return self
        raise self._busy(_read_pid(self.path))

    def release(self) -> None:
        if self._fd is None and not self._exclusive:
            return
        try:
            if self._exclusive or _read_pid(self.path) == os.getpid():
                os.unlink(self.path)          # while still held: nobody can take a dead file
        except OSError:
            pass
        finally:
            if self._fd is not None:
                os.close(self._fd)            # drops the flock
            self._fd, self._exclusive = None, False

    @property
    def held(self) -> bool:
        return self._fd is not None or self._exclusive

    def __enter__(self) -> "DirectoryLock":
        return self if self.held else self.acquire()

    def remove_made(self) -> None:
        """Remove the directories this claim created, deepest first, while they are empty."""
        for d in self.made:
            try:
                os.rmdir(d)
            except OSError:
                break
        self.made = []

    def __exit__(self, exc_type: object, *exc: object) -> None:
        self.release()
        if exc_type is not None:
            self.remove_made()
