"""Staging directories of output sets: who writes which set, and a switch that is one rename.

An `labrig.outputset.OutputSet` named ``NAME`` in an output directory ``OUT`` is the folder ``OUT/NAME``.
Its files are written into a hidden staging directory beside it, ``OUT/.staging-NAME-<pid>-<8 hex
digits>/`` (the same filesystem). Its process holds an exclusive ``flock`` on that directory while the
set is open: the lock says that the set is being written, and the operating system drops it when the
process ends, however it ends, so a lock is never stale. A second writer of ``NAME`` in ``OUT`` finds
it held and is refused (`SetBusyError`).

The switch (`switch_into`) puts the staging directory at ``OUT/NAME`` in one step: a rename when there
is no earlier set, else an atomic exchange of the two directories (``renameat2(RENAME_EXCHANGE)`` on
Linux, ``renamex_np(RENAME_SWAP)`` on macOS), after which the staging path holds the earlier set, to be
deleted. A process killed at any moment therefore leaves ``OUT/NAME`` the whole earlier set or the
whole new one, byte for byte; what it may leave besides is a hidden ``.staging-...`` directory, which
the next `recover` deletes. (Nothing is fsynced, so a power cut may still lose the last switch.) On
a filesystem without the exchange the switch takes two renames, ``OUT/NAME`` to
``.staging-...-<tag>.old`` and the staging directory to ``OUT/NAME``; a kill between them leaves no
``OUT/NAME`` until the next `recover` rolls the switch forward.

`recover` runs whenever a set is opened or committed, and whenever a reader opens a file of a set
(`recover_beside`): a staging directory whose lock is free (its process has ended) is deleted, and an
interrupted two-rename switch is rolled forward. A staging directory of a live process is left alone.
Opening, committing and recovering take the output directory's own lock (``flock`` on the directory
itself, no lock file), so they happen one at a time per directory; each takes milliseconds.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import secrets
import shutil
import signal
import threading
import time
import types
from dataclasses import dataclass
from pathlib import Path

from .launch import LateInterrupt
from .validate import InputError

fcntl: types.ModuleType | None
try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no locks; a staging directory is live while its pid runs
    fcntl = None

#: Name of a staging directory: ``.staging-NAME-<pid>-<8 hex digits>``; ``.old`` after it: the earlier set of a
#: two-rename switch.
PREFIX = ".staging-"
RETIRED = ".old"
STAGING_PATTERN = re.compile(r"^\.staging-(?P<name>.+)-(?P<pid>[0-9]+)-(?P<tag>[0-9a-f]{8})(?P<retired>\.old)?$")
#: Longest name of a set, bytes: its staging directory's name must stay under the 255 bytes of a file name, with
#: room for the suffixes of the set's files.
MAX_SET_NAME = 200
#: Longest wait for the lock of an output directory, s (it is held for milliseconds at a time).
LOCK_WAIT_S = 120.0
#: Poll interval while waiting for it, s.
LOCK_POLL_S = 0.02
#: errno values of filesystems without ``flock`` on directories (EBADF: NFS, whose emulated locks need a file
#: open for writing).
_NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL, errno.EBADF}
#: errno values of a filesystem or kernel without an atomic exchange of two directories.
_NO_EXCHANGE = {errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EXDEV}


class SetBusyError(InputError):
    """Another live process is writing the output set ``name`` in ``directory``."""

    def __init__(self, name: str, directory: str | os.PathLike, pid: int):
        super().__init__(f"{name} in {directory} is being written by another run (pid {pid}): "
                         "wait for it or choose another --out")
        self.name, self.directory, self.pid = name, Path(directory), pid


def _open_directory(path: Path) -> int:
    return os.open(path, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))


def _try_lock(fd: int) -> bool | None:
    """Lock ``fd`` exclusively without waiting: True if taken, False if another holds it, None if the
    filesystem has no locks."""
    if fcntl is None:  # pragma: no cover
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:  # pragma: no cover - depends on the filesystem
        if exc.errno in _NO_LOCKS:
            return None
        raise
    return True


@contextlib.contextmanager
def directory_lock(directory: str | os.PathLike, wait: float = LOCK_WAIT_S):
    """Hold the lock of ``directory`` (``flock`` on the directory) for the ``with`` block.

    Waits at most ``wait`` s (TimeoutError, an OSError, after that: a process stopped while it held
    the lock, e.g. by Ctrl-Z); a filesystem without locks is not locked.
    """
    fd = _open_directory(Path(directory))
    try:
        deadline = time.monotonic() + wait
        while _try_lock(fd) is False:
            if time.monotonic() > deadline:
                raise TimeoutError(f"{directory} has been locked by another process for more than {wait:g} s "
                                   "(a run stopped with Ctrl-Z?)")
            time.sleep(LOCK_POLL_S)
        yield
    finally:
        os.close(fd)  # releases the lock


@contextlib.contextmanager
def interrupts_deferred(done: str = ""):
    """Hold a Ctrl-C (SIGINT) that arrives in the ``with`` block until its end, then raise
    `labrig.launch.LateInterrupt` with the message ``done`` (what the block wrote whole).

    What a switch runs under, so that Ctrl-C never cuts it in two. Only the main thread can hold
    signals; elsewhere the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise LateInterrupt(done)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@dataclass(frozen=True)
class StagingEntry:
    """A staging directory found in an output directory: its path, set name, owner's pid, and whether it holds
    the earlier set of an interrupted two-rename switch."""

    path: Path
    name: str
    pid: int
    retired: bool = False


def staging_entries(directory: str | os.PathLike) -> list[StagingEntry]:
    """The staging directories in ``directory`` (live or not), by name."""
    found = []
    with os.scandir(os.fspath(directory)) as entries:
        for entry in entries:
            match = STAGING_PATTERN.match(entry.name) if entry.name.startswith(PREFIX) else None
            if match and entry.is_dir(follow_symlinks=False):
                found.append(StagingEntry(Path(entry.path), match["name"], int(match["pid"]), bool(match["retired"])))
    return sorted(found, key=lambda e: e.path.name)


def plain_file_name(name) -> bool:
    """Whether ``name`` is a file name without a directory part (what an output set holds)."""
    return isinstance(name, str) and name not in ("", ".", "..") and "/" not in name and "\\" not in name \
        and "\0" not in name


def _exchange_function():
    """``exchange(a, b) -> errno`` swapping two paths atomically, or None where the C library has none."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:  # pragma: no cover
        return None
    if hasattr(libc, "renameat2"):  # Linux (glibc >= 2.28, musl)
        call = libc.renameat2
        call.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        return lambda a, b: call(-100, a, -100, b, 2) and ctypes.get_errno()  # AT_FDCWD, RENAME_EXCHANGE
    if hasattr(libc, "renamex_np"):  # pragma: no cover - macOS
        call = libc.renamex_np
        call.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint]
        return lambda a, b: call(a, b, 2) and ctypes.get_errno()  # RENAME_SWAP
    return None  # pragma: no cover


_EXCHANGE = _exchange_function()


class ExchangeUnsupported(OSError):
    """The filesystem (or the system) cannot exchange two directories atomically."""


def exchange(a: str | os.PathLike, b: str | os.PathLike) -> None:
    """Swap the directories ``a`` and ``b`` in one atomic step; `ExchangeUnsupported` where that is impossible."""
    if _EXCHANGE is None:  # pragma: no cover
        raise ExchangeUnsupported(errno.ENOSYS, "no atomic exchange of directories here")
    code = _EXCHANGE(os.fsencode(a), os.fsencode(b))
    if code:
        if code in _NO_EXCHANGE:
            raise ExchangeUnsupported(code, os.strerror(code))
        raise OSError(code, os.strerror(code), str(a), None, str(b))


def switch_into(staging: Path, target: Path) -> Path | None:
    """Put the directory ``staging`` at ``target`` in one step; returns where the earlier ``target`` now is (a
    hidden directory to delete), or None when there was none. Called with `directory_lock` held."""
    if not os.path.lexists(target):
        os.rename(staging, target)
        return None
    try:
        exchange(staging, target)
        return staging
    except ExchangeUnsupported:
        retired = staging.with_name(staging.name + RETIRED)
        os.rename(target, retired)
        try:
            os.rename(staging, target)
        except BaseException:
            os.rename(retired, target)
            raise
        return retired


def _finish(directory: Path, entry: StagingEntry) -> None:
    """Delete the staging directory of an ended process; first roll forward the two-rename switch it was making
    (a ``.old`` entry: the earlier set, moved aside, with no set in its place)."""
    if entry.retired:
        staging, target = entry.path.with_name(entry.path.name[:-len(RETIRED)]), directory / entry.name
        if not os.path.lexists(target):
            os.rename(staging if staging.is_dir() else entry.path, target)
    shutil.rmtree(entry.path, ignore_errors=True)


def recover(directory: str | os.PathLike) -> list[StagingEntry]:
    """Finish the staging directories of ended processes in ``directory``; returns the live ones.

    The caller holds `directory_lock` (so no switch is under way: each runs under that lock).
    """
    directory = Path(directory)
    live = []
    entries = staging_entries(directory)
    for entry in [e for e in entries if e.retired] + [e for e in entries if not e.retired]:
        if entry.retired:
            _finish(directory, entry)
            continue
        try:
            fd = _open_directory(entry.path)
        except FileNotFoundError:  # rolled forward just now
            continue
        try:
            taken = _try_lock(fd)
            alive = (not taken) if taken is not None else _pid_alive(entry.pid)
            if alive:
                live.append(entry)
            else:
                _finish(directory, entry)
        finally:
            os.close(fd)
    return live


def recover_beside(path: str | os.PathLike) -> None:
    """Finish what ended processes left beside the file ``path``: in the output directory of its set (the
    folder above it) and in its own folder.

    What a reader calls before it opens a file of a set. Never raises for the directory's sake
    (read-only, not ours, locked too long): the reader then reads what is there.
    """
    path = Path(path)
    for directory in dict.fromkeys((path.parent.parent, path.parent)):
        try:
            with os.scandir(directory) as entries:
                if not any(entry.name.startswith(PREFIX) for entry in entries):
                    continue
            with directory_lock(directory):
                recover(directory)
        except OSError:
            continue


class Staging:
    """The staging directory of one output set, created and locked by this process (`open_staging`)."""

    def __init__(self, directory: Path, name: str):
        self.directory = directory
        self.name = name
        self.path = directory / f"{PREFIX}{name}-{os.getpid()}-{secrets.token_hex(4)}"
        os.mkdir(self.path)
        self._fd: int | None = _open_directory(self.path)
        _try_lock(self._fd)  # a new directory: never held

    def release(self) -> None:
        """Drop the lock (the directory stays, for `recover` to delete)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def discard(self) -> None:
        """Delete the staging directory (after a switch: the earlier set) and drop the lock."""
        try:
            shutil.rmtree(self.path, ignore_errors=True)
        finally:
            self.release()

    def switch(self, then=None) -> None:
        """Put the staged set in place (`switch_into`), call ``then()`` (what must follow at once: the shared
        files of the set's directory), delete the earlier set, drop the lock. Called with `directory_lock` held."""
        earlier = switch_into(self.path, self.directory / self.name)
        try:
            if then is not None:
                then()
        finally:
            if earlier is not None:
                shutil.rmtree(earlier, ignore_errors=True)
            self.release()


def check_set_name(name: str) -> str:
    """``name`` if it can name an output set: a plain file name of at most `MAX_SET_NAME` bytes, not hidden."""
    if not plain_file_name(name) or name.startswith("."):
        raise InputError(f"name must be a file name without '/' that does not start with '.', got {name!r}")
    size = len(os.fsencode(name))
    if size > MAX_SET_NAME:
        raise InputError(f"name must be at most {MAX_SET_NAME} characters (it names the run's folder and files), "
                         f"got {size}: {name[:40]!r}...")
    return name


def open_staging(directory: str | os.PathLike, name: str) -> Staging:
    """Finish what ended processes left in ``directory``, then create and lock the staging directory of
    the set ``name``; `SetBusyError` if a live process is writing that set."""
    directory = Path(directory)
    with directory_lock(directory):
        for entry in recover(directory):
            if entry.name == name:
                raise SetBusyError(name, directory, entry.pid)
        return Staging(directory, name)
