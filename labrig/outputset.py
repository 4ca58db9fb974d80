"""An output set: the files of one result, a folder written whole and switched into place in one step.

`OutputSet` stages the files of a result in a hidden directory beside its folder and switches them in at
once (`labrig.staging`); `labrig.files` re-exports it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Callable
from pathlib import Path

from .files import AllOrNothing, StreamedFile, remove_stale_temporaries, temporary_beside, writable_directory
from .staging import check_set_name, directory_lock, interrupts_deferred, open_staging, plain_file_name, recover
from .validate import InputError

__all__ = ["OutputSet"]


class OutputSet(AllOrNothing):
    """The files of one result, named ``name``: the folder ``directory/name``, replaced all at once or not at all.

    Opening the set locks it (`labrig.staging`): a second writer of the same ``name`` in the same
    directory, in this or another process, gets `SetBusyError` (an `InputError`) until this one ends.
    Each file is written into the set's hidden staging directory beside the folder (`stage`); streamed
    writers (movies, trajectories) are given a staged path and adopted (`adopt`). `commit` closes the
    streams, then switches: the staging directory takes the folder's place in one atomic step
    (`labrig.staging.switch_into`), so that a process killed at any moment leaves the folder the whole
    earlier set or the whole new one, byte for byte. The earlier set's files that this one does not
    write are carried over into it, except those it drops (`drop`: removed) or keeps under another name
    (`keep_as`). `update` names a shared file of ``directory`` (a summary table of its sets): its new
    version is written beside it before the switch and renamed into place right after it, under the
    directory's lock (a kill between the two leaves that file one set behind); Ctrl-C waits for both. If
    the ``with`` block raises, the staging directory is deleted and every stream aborted: the earlier
    set stays as it was. Opening a set also clears temporary files that killed processes left in the
    directory (`remove_stale_temporaries`) and their staging directories.

    Examples
    --------
    A run's files (here two small ones; a movie would be ``files.adopt(MovieWriter(files.stage("run.mp4")))``):

    >>> with OutputSet("out", "run") as files:
    ...     _ = files.stage("run.toml").write_text("seed = 1")
    ...     _ = files.stage("run.csv").write_text("rms_nm,0.5")
    >>> files.written
    [PosixPath('out/run/run.toml'), PosixPath('out/run/run.csv')]
    >>> sorted(p.name for p in Path("out/run").iterdir())
    ['run.csv', 'run.toml']
    """

    def __init__(self, directory: str | os.PathLike, name: str):
        self.directory = Path(directory)
        self.name = check_set_name(name)
        if os.path.islink(self.path) or (self.path.exists() and not self.path.is_dir()):
            raise InputError(f"{str(self.path)!r} is {'a symbolic link' if os.path.islink(self.path) else 'a file'}: "
                             f"the run {name!r} writes a folder of that name there (move it, or choose another --out)")
        _refuse_folders(self.path)
        #: Whether this set made ``directory`` (an aborted set then removes it again if it is empty).
        self.made_directory = not writable_directory(self.directory).exists()
        self.directory.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(self.directory)
        self._staging = open_staging(self.directory, self.name)
        self._staged: list[str] = []
        self._streams: list[StreamedFile] = []
        self._updates: list[tuple[str, Callable[[Path, Path], object]]] = []
        self._drops: list[str] = []
        self._keeps: list[tuple[str, str]] = []
        self._committed = False
        #: Files of the new set, staged ones first (in the order they were staged), then those carried over.
        self.written: list[Path] = []
        #: Earlier files removed by the switch (`drop`).
        self.removed: list[Path] = []
        #: Earlier files kept under another name by the switch (`keep_as`): ``(old path, new path)``.
        self.kept: list[tuple[Path, Path]] = []
        #: Shared files of ``directory`` rewritten with the switch (`update`).
        self.updated: list[Path] = []

    @property
    def path(self) -> Path:
        """The set's folder, ``directory/name``."""
        return self.directory / self.name

    @property
    def staging(self) -> Path:
        """The set's staging directory (where its files are written until the switch)."""
        return self._staging.path

    def target(self, name: str) -> Path:
        """Where the file ``name`` of the set goes (in its folder)."""
        return self.path / name

    def name_beside(self, name: str, source: str | os.PathLike | None) -> str:
        """``name``, or ``STEM.ran.SUFFIX`` when ``name`` in the set's folder is the file ``source`` (the input a
        run was started from, which a set never writes over: it is carried over as it is)."""
        target = self.target(name)
        if source is not None and target.exists() and Path(source).exists() and target.samefile(source):
            return f"{target.stem}.ran{target.suffix}"
        return name

    def _claim(self, name: str, shared: bool = False) -> Path:
        if not plain_file_name(name) or len(os.fsencode(name)) > 255:
            raise ValueError(f"a file of an output set must be a plain file name of at most 255 bytes, got {name!r}")
        if name in (self._staged if not shared else [n for n, _ in self._updates]):
            raise ValueError(f"{name!r} is already staged in the output set {self.name!r}")
        if (self.directory / name if shared else self.target(name)).is_dir():
            raise IsADirectoryError(f"cannot write {str(self.target(name))!r}: it is a directory")
        return self.staging / name

    def stage(self, name: str) -> Path:
        """The path to write the file ``name`` of the set to (in the staging directory); `commit` puts it in place."""
        path = self._claim(name)
        self._staged.append(name)
        return path

    def adopt(self, stream: StreamedFile) -> StreamedFile:
        """Make ``stream`` (opened on a `stage`d path) part of the set: closed by `commit`, aborted by `abort`;
        a stream that wrote nothing leaves its file out of the set."""
        if Path(stream.path).parent != self.staging:
            stream.abort()
            raise ValueError(f"open the stream on files.stage({Path(stream.path).name!r}), not on {stream.path}")
        self._streams.append(stream)
        return stream

    def update(self, name: str, write: Callable[[Path, Path], object]) -> None:
        """Rewrite the shared file ``directory/name`` with the switch: ``write(current, staged)`` reads ``current``
        (which may not exist) and writes the new version to ``staged``, which replaces it right after the switch.
        It runs under the directory's lock, so concurrent sets updating one file (a summary table) never lose
        each other's rows."""
        self._claim(name, shared=True)
        self._updates.append((name, write))

    def drop(self, name: str) -> None:
        """Leave the earlier file ``name`` out of the new set, unless the set writes it (`removed` lists it)."""
        if not plain_file_name(name):
            raise ValueError(f"a file of an output set must be a plain file name, got {name!r}")
        self._drops.append(name)

    def keep_as(self, name: str, new_name: str) -> None:
        """Carry the earlier file ``name`` into the new set as ``new_name`` (``new_name-2`` ... if taken); the set's
        own ``name``, if it writes one, replaces it (`kept` lists the pair)."""
        if not (plain_file_name(name) and plain_file_name(new_name)):
            raise ValueError(f"file names of an output set must be plain, got {name!r} and {new_name!r}")
        self._keeps.append((name, new_name))

    def commit(self) -> list[Path]:
        """Put the set in place at once and, right after, the shared files (written beside them first); returns the
        set's files. Committing twice does nothing more."""
        if self._committed:
            return self.written
        updates: list[tuple[Path, Path]] = []
        try:
            names = self._close_streams()
            with directory_lock(self.directory), interrupts_deferred(f"the files of {self.name} were written"):
                recover(self.directory)
                carried = self._carry_over(names)
                for name, write in self._updates:
                    updates.append(self._rewrite(name, write))
                self._staging.switch(then=lambda: self._replace_all(updates))
                self._committed = True
                self.written = [self.target(name) for name in names + carried]
                self.updated = [path for _, path in updates]
        except BaseException:
            for tmp, _ in updates:
                tmp.unlink(missing_ok=True)
            self.abort()
            raise
        finally:
            self._staged, self._updates = [], []
        return self.written

    @staticmethod
    def _replace_all(updates: list[tuple[Path, Path]]) -> None:
        """Move each rewritten table into place (``(temporary, path)`` pairs, in order)."""
        for temporary, path in updates:
            os.replace(temporary, path)

    def _close_streams(self) -> list[str]:
        """Close the streams; the staged names that hold a file (a stream that wrote nothing has none)."""
        empty = set()
        for stream in self._streams:
            if stream.close() is None:
                empty.add(Path(stream.path).name)
        self._streams = []
        names = []
        for name in self._staged:
            if os.path.lexists(self.staging / name):
                names.append(name)
            elif name not in empty:
                raise RuntimeError(f"{name!r} was staged in the output set {self.name!r} but never written")
        return names

    def _carry_over(self, names: list[str]) -> list[str]:
        """Link the earlier set's files that the new one keeps into the staging directory (with the directory's
        lock held): those kept under new names (`keep_as`), then every other one this set neither writes nor
        drops. Fills `kept` and `removed`; returns the names carried over."""
        if not self.path.is_dir():
            return []
        _refuse_folders(self.path)
        earlier = sorted(os.listdir(self.path))
        taken = set(names)
        for old, new in self._keeps:
            if old in earlier and os.path.isfile(self.target(old)) and not os.path.islink(self.target(old)):
                new = _free_name(new, taken | set(earlier) - {old})
                _preserve(self.target(old), self.staging / new)
                taken.add(new)
                self.kept.append((self.target(old), self.target(new)))
        moved = {old.name for old, _ in self.kept}
        dropped = set(self._drops) | moved
        self.removed = [self.target(name) for name in earlier
                        if name in set(self._drops) - taken and os.path.isfile(self.target(name))]
        carried = [name for name in earlier if name not in taken and name not in dropped]
        for name in carried:
            _preserve(self.target(name), self.staging / name)
        return sorted(taken - set(names)) + carried

    def _rewrite(self, name: str, write: Callable[[Path, Path], object]) -> tuple[Path, Path]:
        """Write the new version of the shared file ``name`` (the directory's lock held) to a temporary file beside
        it; returns (temporary file, file), for the switch to rename the one onto the other."""
        path = self.directory / name
        tmp = temporary_beside(path)
        try:
            write(path, tmp)
            if not tmp.stat().st_size:
                raise RuntimeError(f"the update of {name!r} in the output set {self.name!r} wrote nothing")
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        return tmp, path

    def abort(self) -> None:
        """Drop every staged file and stream; the earlier set stays as it was (after the switch: delete the earlier
        set, which the staging directory then holds). A directory that this set made is removed when nothing is
        left in it: a refused run leaves nothing behind."""
        for stream in self._streams:
            stream.abort()
        self._streams, self._staged, self._updates = [], [], []
        self._staging.discard()
        if self.made_directory and not self._committed:
            with contextlib.suppress(OSError):  # not empty (another writer's files): it stays
                self.directory.rmdir()

    def finish(self) -> list[Path]:
        """`commit` (what the end of a ``with`` block calls)."""
        return self.commit()


def _refuse_folders(path: Path) -> None:
    """`InputError` if the set's folder ``path`` holds a folder (a set is replaced whole: it would be lost)."""
    with contextlib.suppress(FileNotFoundError, NotADirectoryError), os.scandir(path) as entries:
        for entry in entries:
            if entry.is_dir(follow_symlinks=False):
                raise InputError(f"{str(path)!r} holds the folder {entry.name!r}: a run replaces its folder as a "
                                 "whole; move that folder out first")


def _free_name(name: str, taken: set) -> str:
    """``name``, or ``STEM-2.SUFFIX``, ``STEM-3.SUFFIX``, ... the first not in ``taken``."""
    stem, suffix = os.path.splitext(name)
    candidate, k = name, 1
    while candidate in taken:
        k += 1
        candidate = f"{stem}-{k}{suffix}"
    return candidate


def _preserve(path: Path, copy: Path) -> None:
    """``copy`` as a second name of ``path`` (a hard link; a symbolic link is copied as a link), or a copy where
    links are not possible."""
    if os.path.islink(path):
        os.symlink(os.readlink(path), copy)
        return
    try:
        os.link(path, copy)
    except OSError:
        shutil.copy2(path, copy)
