"""Staging directories of output sets: who writes which set, and a switch that survives a kill.

An `labrig.files.OutputSet` named ``NAME`` writes its files into a hidden staging directory inside
its output directory, ``.staging-NAME-<pid>-<8 hex digits>/`` (the same filesystem, so a rename out
of it is atomic). Its process holds an exclusive ``flock`` on that directory as long as the set is
open: the lock says that the set is being written, and the operating system drops it when the
process ends, however it ends, so a lock is never stale. A second writer of ``NAME`` in the same
directory finds it held and is refused (`SetBusyError`).

The switch (`Staging.switch`) first writes a journal, ``journal.json``, into the staging
directory (atomically): every rename out of it and every removal that makes the new set. Then it
renames, then removes the journal and the staging directory. A process killed before its journal
exists leaves the earlier set as it was; killed after, its journal is rolled forward by the next
`recover`. The directory therefore holds the whole earlier set or the whole new one, never a mix
(against kills; nothing is fsynced, so a power cut may still lose the last switch).

`recover` runs whenever a set is opened or committed, and whenever a reader opens a file of a set
(`recover_beside`): a staging directory whose lock is free (its process has ended) is rolled forward
(journal present) or deleted (no journal: its run never reached the switch). A staging directory of
a live process is left alone. Opening, committing and recovering take the output directory's own
lock (``flock`` on the directory itself, no lock file), so they happen one at a time per directory;
each takes milliseconds.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import secrets
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no locks; a staging directory is live while its pid runs
    fcntl = None

from .validate import InputError

#: Name of a staging directory: ``.staging-NAME-<pid>-<8 hex digits>``.
PREFIX = ".staging-"
STAGING_PATTERN = re.compile(r"^\.staging-(?P<name>.+)-(?P<pid>[0-9]+)-(?P<tag>[0-9a-f]{8})$")
#: The journal of a switch, in its staging directory, and its name while it is written (no set may stage them).
JOURNAL = "journal.json"
PARTIAL_JOURNAL = f".{JOURNAL}.partial"
JOURNAL_FORMAT = "labrig-output-switch"
JOURNAL_VERSION = 1
#: Longest wait for the lock of an output directory, s (it is held for milliseconds at a time).
LOCK_WAIT_S = 120.0
#: Poll interval while waiting for it, s.
LOCK_POLL_S = 0.02
#: errno values of filesystems without ``flock`` on directories (EBADF: NFS, whose emulated locks need a file
#: open for writing).
_NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL, errno.EBADF}


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
    """A staging directory found in an output directory: its path, set name and owner's pid."""

    path: Path
    name: str
    pid: int


def staging_entries(directory: str | os.PathLike) -> list[StagingEntry]:
    """The staging directories in ``directory`` (live or not), by name."""
    found = []
    with os.scandir(directory) as entries:
        for entry in entries:
            match = STAGING_PATTERN.match(entry.name) if entry.name.startswith(PREFIX) else None
            if match and entry.is_dir(follow_symlinks=False):
                found.append(StagingEntry(Path(entry.path), match["name"], int(match["pid"])))
    return sorted(found, key=lambda e: e.path.name)


def plain_file_name(name) -> bool:
    """Whether ``name`` is a file name without a directory part (what a journal and an output set hold)."""
    return isinstance(name, str) and name not in ("", ".", "..") and "/" not in name and "\\" not in name \
        and "\0" not in name


def read_journal(path: Path) -> list[tuple[str, str]]:
    """The steps of a journal: ``("rename", NAME)`` (staging/NAME onto directory/NAME) and ``("remove", NAME)``.

    Raises `InputError` if it is not a journal of this format whose names are plain file names.
    """
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path} is not a readable journal ({exc})") from None
    if not (isinstance(data, dict) and data.get("format") == JOURNAL_FORMAT
            and data.get("version") == JOURNAL_VERSION and isinstance(data.get("steps"), list)):
        raise InputError(f"{path} is not a {JOURNAL_FORMAT} journal of version {JOURNAL_VERSION}")
    steps = []
    for step in data["steps"]:
        if not (isinstance(step, list) and len(step) == 2 and step[0] in ("rename", "remove")
                and plain_file_name(step[1])):
            raise InputError(f"{path}: a step must be [\"rename\" or \"remove\", a file name], got {step!r}")
        steps.append((step[0], step[1]))
    return steps


def apply_steps(directory: Path, staging: Path, steps: Sequence[tuple[str, str]]) -> None:
    """Carry out a journal's steps; each is skipped if already done, so a journal can be replayed."""
    for kind, name in steps:
        if kind == "rename":
            source = staging / name
            if os.path.lexists(source):  # else renamed before the kill
                os.replace(source, directory / name)
        else:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(directory / name)


def _finish(directory: Path, entry: StagingEntry) -> None:
    """Roll forward (journal present) or delete (no journal) the staging directory of an ended process."""
    journal = entry.path / JOURNAL
    if journal.exists():
        try:
            steps = read_journal(journal)
        except InputError as exc:  # cannot happen to a journal written by `switch`: leave it to a person
            print(f"warning: {exc}; left {entry.path} as it is", file=sys.stderr)
            return
        apply_steps(directory, entry.path, steps)
        journal.unlink()
    shutil.rmtree(entry.path, ignore_errors=True)


def recover(directory: str | os.PathLike) -> list[StagingEntry]:
    """Finish the staging directories of ended processes in ``directory``; returns the live ones.

    The caller holds `directory_lock`.
    """
    directory = Path(directory)
    live = []
    for entry in staging_entries(directory):
        try:
            fd = _open_directory(entry.path)
        except FileNotFoundError:
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
    """Finish the output sets that ended processes left in the directory of the file ``path``.

    What a reader calls before it opens a file of a set. Never raises for the directory's sake
    (read-only, not ours, locked too long): the reader then reads what is there.
    """
    directory = Path(path).parent
    try:
        with os.scandir(directory) as entries:
            if not any(entry.name.startswith(PREFIX) for entry in entries):
                return
        with directory_lock(directory):
            recover(directory)
    except OSError:
        return


class Staging:
    """The staging directory of one output set, created and locked by this process (`open_staging`)."""

    def __init__(self, directory: Path, name: str):
        self.directory = directory
        self.name = name
        self.path = directory / f"{PREFIX}{name}-{os.getpid()}-{secrets.token_hex(4)}"
        os.mkdir(self.path)
        self._fd: int | None = _open_directory(self.path)
        _try_lock(self._fd)  # a new directory: never held
        self.journaled = False

    def release(self) -> None:
        """Drop the lock (the directory stays, for `recover` to finish)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def discard(self) -> None:
        """Delete the staging directory and everything in it, unless its journal is written (then a
        later `recover` rolls it forward); then drop the lock."""
        try:
            if not self.journaled:
                shutil.rmtree(self.path, ignore_errors=True)
        finally:
            self.release()

    def switch(self, steps: Sequence[tuple[str, str]]) -> None:
        """Write the journal of ``steps``, carry them out, remove the journal and the staging directory.

        Called with `directory_lock` held. Once the journal is written the switch is decided: Ctrl-C then
        finishes it before it stops the program; if a step fails, the staging directory stays for the
        next `recover` to roll forward.
        """
        journal = self.path / JOURNAL
        partial = self.path / PARTIAL_JOURNAL
        partial.write_text(json.dumps({"format": JOURNAL_FORMAT, "version": JOURNAL_VERSION, "set": self.name,
                                       "pid": os.getpid(), "steps": [list(step) for step in steps]}, indent=1),
                           encoding="utf-8")
        os.replace(partial, journal)
        self.journaled = True
        try:
            apply_steps(self.directory, self.path, steps)
        except KeyboardInterrupt:  # Ctrl-C mid-switch: finish it (milliseconds), then stop
            apply_steps(self.directory, self.path, steps)
            self._remove(journal)
            raise
        self._remove(journal)

    def _remove(self, journal: Path) -> None:
        """Remove the journal and the staging directory of a finished switch, and drop the lock."""
        journal.unlink()
        self.journaled = False
        shutil.rmtree(self.path, ignore_errors=True)
        self.release()


def open_staging(directory: str | os.PathLike, name: str) -> Staging:
    """Finish what ended processes left in ``directory``, then create and lock the staging directory of
    the set ``name``; `SetBusyError` if a live process is writing that set."""
    directory = Path(directory)
    with directory_lock(directory):
        for entry in recover(directory):
            if entry.name == name:
                raise SetBusyError(name, directory, entry.pid)
        return Staging(directory, name)
