"""Files that appear whole or not at all: atomic writes, streamed writers, output sets, CSV tables, safe names.

Everything the packages save goes through `atomic_path`: the data is written to a temporary file
in the same directory and renamed onto the target, so a crash or a bad input mid-write never
corrupts or loses what was saved before. A process killed mid-write leaves its temporary file
(``.NAME-xxxxxxxx.tmp.SUFFIX``) behind; `remove_stale_temporaries` clears old ones. The files of one
result (a state, its picture, its movie, ...) are an `OutputSet`, which replaces the earlier set all at
once, even against a kill (`labrig.staging`).
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import re
import secrets
import shutil
import time
from pathlib import Path
from typing import Callable, Iterator, Sequence

from .staging import (JOURNAL, PARTIAL_JOURNAL, SetBusyError, directory_lock, open_staging, plain_file_name, recover,
                      recover_beside)
from .validate import InputError

__all__ = ["atomic_path", "write_text_atomic", "write_csv", "temporary_beside", "existing_file",
           "remove_stale_temporaries", "AllOrNothing", "StreamedFile", "OutputSet", "SetBusyError",
           "recover_beside", "slug"]

#: Temporary files older than this (s) are left over from a killed process (`remove_stale_temporaries`).
STALE_AFTER = 3600.0


def temporary_beside(path: Path) -> Path:
    """Create an empty, uniquely named file next to ``path`` with the same suffix."""
    path = Path(path)
    if not path.name or path.name in (".", ".."):
        raise IsADirectoryError(f"{str(path)!r} names a directory, not a file")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"cannot write {str(path)!r}: the directory {str(path.parent)!r} does not exist")
    tmp = path.with_name(f".{path.stem}-{secrets.token_hex(4)}.tmp{path.suffix}")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    return tmp


def existing_file(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a Path if it names a regular file; FileNotFoundError if nothing is there, `InputError` if it
    is a directory, a pipe or another kind of file (``what`` names the file in messages, e.g. "scene file")."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} {str(path)!r} does not exist")
    if not path.is_file():
        raise InputError(f"{what} {str(path)!r} is not a regular file (a directory or a pipe?)")
    return path


_TEMPORARY = re.compile(r"^\..+-[0-9a-f]{8}\.tmp(\..*)?$")


def remove_stale_temporaries(directory: str | os.PathLike, older_than: float = STALE_AFTER) -> list[Path]:
    """Delete the temporary files of `atomic_path` in ``directory`` older than ``older_than`` s.

    A process that is killed mid-write leaves its temporary file behind; a newer one may belong to
    a writer still running, so it is kept. Returns the files removed.
    """
    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        if not _TEMPORARY.match(entry.name):
            continue
        with contextlib.suppress(OSError):
            if entry.is_file(follow_symlinks=False) and now - entry.stat().st_mtime > older_than:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` if the block succeeds.

    On any exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    tmp = temporary_beside(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through `atomic_path`; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


class AllOrNothing:
    """Base of what a ``with`` block writes whole or not at all: the block's normal end calls `finish`, an
    exception in it calls `abort`."""

    def finish(self):
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.finish()
        else:
            self.abort()


class StreamedFile(AllOrNothing):
    """Base of writers that stream into a temporary file and rename it into place on `close`.

    Subclasses open their stream on ``self._tmp`` and implement `_close_stream`;
    `_is_empty` may say that nothing worth keeping was written. Used as a
    context manager, an exception in the block calls `abort`: the partial file
    is removed and ``path`` is left as it was.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._tmp = temporary_beside(self.path)
        self._open = True

    @property
    def closed(self) -> bool:
        return not self._open

    def _close_stream(self) -> None:
        raise NotImplementedError

    def _is_empty(self) -> bool:
        return False

    def close(self) -> Path | None:
        """Finish the file and move it onto ``path``; returns it, or None if nothing was written.

        Closing twice does nothing.
        """
        if self.closed:
            return self.path if self.path.exists() else None
        self._open = False
        try:
            self._close_stream()
            if self._is_empty():
                self._tmp.unlink(missing_ok=True)
                return None
            os.replace(self._tmp, self.path)
        except BaseException:
            self._tmp.unlink(missing_ok=True)
            raise
        return self.path

    def abort(self) -> None:
        """Drop the partial file; ``path`` is left untouched."""
        if self.closed:
            return
        self._open = False
        with contextlib.suppress(Exception):
            self._close_stream()
        self._tmp.unlink(missing_ok=True)

    def finish(self) -> Path | None:
        """`close` (what the end of a ``with`` block calls)."""
        return self.close()


def write_csv(path: str | os.PathLike, rows: Sequence[dict]) -> Path:
    """Write ``rows`` (dicts with the same keys) as CSV, atomically; returns the path."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return write_text_atomic(path, text.getvalue())


def slug(name: str) -> str:
    """A file-name-safe form of a run's name: ``"fig2-2a sigma=0"`` -> ``"fig2-2a_sigma0"``."""
    text = re.sub(r"[^A-Za-z0-9._-]+", "_", name.replace("=", "")).strip("_.")
    return text or "run"


class OutputSet(AllOrNothing):
    """The files of one result, named ``name``: they replace the earlier set all at once, or not at all.

    Opening the set locks it (`labrig.staging`): a second writer of the same ``name`` in the same
    directory, in this or another process, gets `SetBusyError` (an `InputError`) until this one ends.
    Each file is written into the set's hidden staging directory inside ``directory`` (`stage`); streamed
    writers (movies, trajectories) are given a staged path and adopted (`adopt`); `update` names a
    shared file (a summary table) to rewrite at the switch, under the directory's lock. `commit`
    closes the streams, then switches: one journaled set of renames (`labrig.staging.Staging.switch`),
    so that a process killed at any moment leaves the whole earlier set or the whole new one (the next
    open, or reader, finishes a switch that a kill interrupted). `drop` and `keep_as` say what happens
    in the same switch to earlier files of the set that this one does not rewrite. If the ``with``
    block raises, the staging directory is deleted and every stream aborted: the earlier files stay
    as they were. Opening a set also clears temporary files that killed processes left in the
    directory (`remove_stale_temporaries`) and finishes their interrupted switches.

    Examples
    --------
    >>> with OutputSet(out, "run") as files:                             # doctest: +SKIP
    ...     save_png(state, files.stage("run.png"))
    ...     movie = files.adopt(MovieWriter(files.stage("run.mp4")))
    ...     save_scene(scene, files.stage("run.toml", last=True))
    >>> files.written                                                    # doctest: +SKIP
    """

    def __init__(self, directory: str | os.PathLike, name: str):
        self.directory = Path(directory)
        self.name = name
        #: Whether this set made ``directory`` (an aborted set then removes it again if it is empty).
        self.made_directory = not self.directory.exists()
        self.directory.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(self.directory)
        self._staging = open_staging(self.directory, name)
        self._staged: list[tuple[str, bool]] = []
        self._streams: list[StreamedFile] = []
        self._updates: list[tuple[str, Callable[[Path, Path], object]]] = []
        self._drops: list[str] = []
        self._keeps: list[tuple[str, str]] = []
        self._committed = False
        #: Files put in place, in the order of the switch.
        self.written: list[Path] = []
        #: Earlier files removed by the switch (`drop`).
        self.removed: list[Path] = []
        #: Earlier files kept under another name by the switch (`keep_as`): ``(old path, new path)``.
        self.kept: list[tuple[Path, Path]] = []

    @property
    def staging(self) -> Path:
        """The set's staging directory (where its files are written until the switch)."""
        return self._staging.path

    def target(self, name: str) -> Path:
        """Where ``name`` goes in the set's directory."""
        return self.directory / name

    def name_beside(self, name: str, source: str | os.PathLike | None) -> str:
        """``name``, or ``STEM.ran.SUFFIX`` when ``name`` in this directory is the file ``source`` (the input a
        run was started from, which a set never writes over)."""
        target = self.target(name)
        if source is not None and target.exists() and Path(source).exists() and target.samefile(source):
            return f"{target.stem}.ran{target.suffix}"
        return name

    def _claim(self, name: str) -> Path:
        if not plain_file_name(name) or name in (JOURNAL, PARTIAL_JOURNAL):
            raise ValueError(f"a file of an output set must be a plain file name (not {JOURNAL!r}), got {name!r}")
        if name in self._names():
            raise ValueError(f"{name!r} is already staged in the output set {self.name!r}")
        if self.target(name).is_dir():
            raise IsADirectoryError(f"cannot write {str(self.target(name))!r}: it is a directory")
        return self.staging / name

    def _names(self) -> list[str]:
        return [name for name, _ in self._staged] + [name for name, _ in self._updates]

    def stage(self, name: str, last: bool = False) -> Path:
        """The path to write the file ``name`` to (in the staging directory); `commit` puts it in place,
        the ones staged with ``last=True`` after the others."""
        path = self._claim(name)
        self._staged.append((name, last))
        return path

    def adopt(self, stream: "StreamedFile") -> "StreamedFile":
        """Make ``stream`` (opened on a `stage`d path) part of the set: closed by `commit`, aborted by `abort`;
        a stream that wrote nothing leaves its file out of the set."""
        if Path(stream.path).parent != self.staging:
            stream.abort()
            raise ValueError(f"open the stream on files.stage({Path(stream.path).name!r}), not on {stream.path}")
        self._streams.append(stream)
        return stream

    def update(self, name: str, write: Callable[[Path, Path], object]) -> None:
        """Rewrite the shared file ``name`` at the switch: ``write(current, staged)`` reads ``current`` (the file
        in the directory, which may not exist) and writes the new version to ``staged``. It runs under the
        directory's lock, so concurrent sets updating one file (a summary table) never lose each other's
        rows."""
        self._claim(name)
        self._updates.append((name, write))

    def drop(self, name: str) -> None:
        """Remove the earlier file ``name`` in the switch, unless the set writes it (`removed` lists it)."""
        if not plain_file_name(name):
            raise ValueError(f"a file of an output set must be a plain file name, got {name!r}")
        self._drops.append(name)

    def keep_as(self, name: str, new_name: str) -> None:
        """In the switch, keep the earlier file ``name`` as ``new_name`` (``new_name-2`` ... if taken); the set's
        own ``name``, if it writes one, replaces it (`kept` lists the pair)."""
        if not (plain_file_name(name) and plain_file_name(new_name)):
            raise ValueError(f"file names of an output set must be plain, got {name!r} and {new_name!r}")
        self._keeps.append((name, new_name))

    def _free_name(self, name: str, taken: set) -> str:
        stem, suffix = os.path.splitext(name)
        candidate, k = name, 1
        while candidate in taken or os.path.lexists(self.target(candidate)):
            k += 1
            candidate = f"{stem}-{k}{suffix}"
        return candidate

    def commit(self) -> list[Path]:
        """Put every file of the set in place at once; returns their paths (in the order of the switch).

        Committing twice does nothing more."""
        if self._committed:
            return self.written
        try:
            names = self._close_streams()
            with directory_lock(self.directory):
                recover(self.directory)  # an interrupted switch rolled forward later must not undo this one
                names, kept, removals, steps = self._plan(names)
                self._staging.switch(steps)
        except BaseException:
            self.abort()
            raise
        self.written = [self.target(name) for name in names]
        self.kept = [(self.target(old), self.target(new)) for old, new in kept]
        self.removed = [self.target(name) for name in removals]
        self._staged, self._updates, self._committed = [], [], True
        return self.written

    def _close_streams(self) -> list[str]:
        """Close the streams; the staged names that hold a file, last ones last (a stream that wrote nothing
        has none)."""
        empty = set()
        for stream in self._streams:
            if stream.close() is None:
                empty.add(Path(stream.path).name)
        self._streams = []
        names = []
        for name, _ in sorted(self._staged, key=lambda item: item[1]):  # stable: staged order, last ones last
            if os.path.lexists(self.staging / name):
                names.append(name)
            elif name not in empty:
                raise RuntimeError(f"{name!r} was staged in the output set {self.name!r} but never written")
        return names

    def _plan(self, names: list[str]) -> tuple[list[str], list[tuple[str, str]], list[str], list[tuple[str, str]]]:
        """Run the updates and link the files kept under new names into the staging directory (with the
        directory's lock held); the names written, the pairs kept, the names removed and the switch's steps."""
        last = {name for name, is_last in self._staged if is_last}
        for name, write in self._updates:
            write(self.target(name), self.staging / name)
            if not os.path.lexists(self.staging / name):
                raise RuntimeError(f"the update of {name!r} in the output set {self.name!r} wrote nothing")
        names = ([name for name in names if name not in last] + [name for name, _ in self._updates]
                 + [name for name in names if name in last])
        kept = []
        for old, new in self._keeps:
            if os.path.isfile(self.target(old)) and not os.path.islink(self.target(old)):
                new = self._free_name(new, set(names) | {n for _, n in kept})
                _preserve(self.target(old), self.staging / new)
                kept.append((old, new))
        removals = [name for name in dict.fromkeys(self._drops)
                    if name not in names and os.path.isfile(self.target(name))]
        moved = [old for old, _ in kept if old not in names and old not in removals]
        steps = ([("rename", new) for _, new in kept] + [("rename", name) for name in names]
                 + [("remove", name) for name in removals + moved])
        return names, kept, removals, steps

    def abort(self) -> None:
        """Drop every staged file and stream; the earlier files stay as they were (a switch that had
        begun is finished by the next open or reader instead). A directory that this set made is removed
        when nothing is left in it: a refused run leaves nothing behind."""
        for stream in self._streams:
            stream.abort()
        self._streams, self._staged, self._updates = [], [], []
        self._staging.discard()
        if self.made_directory:
            with contextlib.suppress(OSError):  # not empty (another writer's files): it stays
                self.directory.rmdir()

    def finish(self) -> list[Path]:
        """`commit` (what the end of a ``with`` block calls)."""
        return self.commit()


def _preserve(path: Path, copy: Path) -> None:
    """``copy`` as a second name of ``path`` (a hard link), or a copy where links are not possible."""
    try:
        os.link(path, copy)
    except OSError:
        shutil.copy2(path, copy)
