"""Output files that never cost a user a file: checked before any work, written completely or
not at all.

Every writer of the plugin goes through :func:`atomic_output` (one file) or
:class:`OutputSet` (several files committed together):

* The file is written under its final name inside a private temporary folder created in the
  destination's folder (``tempfile.mkdtemp``: a new random name, created exclusively with
  mode 0700, so no existing file or symlink is ever opened through it and concurrent runs never
  share one). Drivers that need the file extension keep it, and side files a driver makes
  (journals, shapefile parts) stay in that folder.
* On success the file (with side files of the same stem) is renamed over the destination with
  ``os.replace``: the destination is, at every moment, either the old file or the whole new one;
  of concurrent runs to the same destination the last rename wins, whole.
* Whatever happens, the temporary folder is then removed with its content: only files this run
  created. Files get the mode a new file gets under the umask (0666 & ~umask), whatever the
  driver chose (SQLite: 0644).
* A destination that is a symlink is written where the link points (the link stays).

:func:`check_outputs` runs before any work: each output (with the files derived from it, e.g. a
report's JSON beside the HTML, a GeoPackage's ``-wal``) must differ from every input file and
from every other output — compared as resolved real paths, by device and inode where the file
exists and case-insensitively where the file system is — and its folder must exist and be
writable. Messages name both parameters.
"""
from __future__ import annotations

import errno
import os
import shutil
import sys
import tempfile
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Mapping, Sequence

from .errors import InputError

# Files a driver or QGIS keeps beside a file, by its extension: they belong to it.
_COMPANIONS = {".gpkg": ("-wal", "-shm", "-journal"), ".sqlite": ("-wal", "-shm", "-journal"),
               ".tif": (".aux.xml", ".ovr"), ".tiff": (".aux.xml", ".ovr"), ".vrt": (".aux.xml", ".ovr")}
_SQLITE = (".gpkg", ".sqlite")
_IN_USE = ("-wal", "-shm")  # a SQLite database open in another program (QGIS opens GeoPackages in WAL mode)


class OutputError(InputError):
    """An output cannot be written where asked (it would replace an input or another output, its
    folder is missing or read-only, the disk is full); nothing was written."""


@dataclass(frozen=True)
class Output:
    """A file an output parameter writes: ``label`` says how it relates to the parameter's own
    file ('' for that file itself, e.g. 'its JSON report')."""
    path: Path
    label: str = ""


# --- where a path really is ----------------------------------------------------------------------
def destination(path) -> Path:
    """The absolute path a write to ``path`` lands on: symlinks (of the file and its folders)
    resolved, so that the link itself survives and its target is what gets replaced."""
    return Path(os.path.realpath(os.path.expanduser(str(path))))


def _case_insensitive(folder: Path) -> bool:
    """Whether names in ``folder`` are matched case-insensitively (e.g. a FAT or macOS volume):
    found through the nearest folder up the tree, on the same device, whose name has letters."""
    try:
        device = folder.stat().st_dev
    except OSError:
        return False
    for f in (folder, *folder.parents):
        try:
            if f.stat().st_dev != device:
                return False
        except OSError:
            return False
        if f.name != f.name.swapcase():
            try:
                return os.path.samefile(f, f.with_name(f.name.swapcase()))
            except OSError:
                return False
    return False


def file_key(path) -> tuple:
    """A key equal for two paths exactly when they name the same file: (device, inode) of an
    existing file (symlinks, hard links, other spellings on case-insensitive systems), else the
    real folder's (device, inode) and the name (case-folded where the folder ignores case)."""
    real = destination(path)
    try:
        st = real.stat()
        return "file", st.st_dev, st.st_ino
    except OSError:
        pass
    try:
        st = real.parent.stat()
    except OSError:
        return "path", str(real)
    name = real.name.casefold() if _case_insensitive(real.parent) else real.name
    return "name", st.st_dev, st.st_ino, name


def companions(path) -> list[Output]:
    """The files a driver or QGIS keeps beside ``path`` (GeoPackage -wal/-shm/-journal, GDAL
    .aux.xml/.ovr), which belong to it."""
    path = Path(path)
    return [Output(Path(str(path) + s), f"its side file {path.name}{s}")
            for s in _COMPANIONS.get(path.suffix.lower(), ())]


# --- checks before any work ----------------------------------------------------------------------
def check_destination(path, parameter: str = "") -> None:
    """OutputError (naming ``parameter`` when given) unless ``path`` can be written: its folder
    exists and is writable, the path is not a folder, and a GeoPackage there is not open in
    another program."""
    real = destination(path)
    shown = f"{parameter}: cannot write {path}" if parameter else f"cannot write {path}"
    if real.is_dir():
        raise OutputError(f"{shown}: it is a folder; give a file name")
    folder = real.parent
    if not folder.is_dir():
        raise OutputError(f"{shown}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{shown}: folder {folder} is not writable")
    if real.exists() and not real.is_file():
        raise OutputError(f"{shown}: it is not a regular file")
    busy = [s for s in _IN_USE if Path(str(real) + s).exists()] if real.suffix.lower() in _SQLITE else []
    if busy:
        raise OutputError(f"{shown}: it is open in another program ({real.name}{busy[0]} exists); close it there "
                          "or choose another name")


def check_folder_destination(folder, parameter: str = "") -> None:
    """OutputError (naming ``parameter`` when given) unless ``folder`` is a writable folder or can
    be created (its nearest existing ancestor is a writable folder)."""
    real = destination(folder)
    prefix = f"{parameter}: " if parameter else ""
    if real.exists() and not real.is_dir():
        raise OutputError(f"{prefix}{folder} is a file, not a folder")
    existing = next(p for p in (real, *real.parents) if p.exists())
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"{prefix}cannot write into {folder}: folder {existing} is not writable")


@contextmanager
def new_folder(folder: Path):
    """Create ``folder`` (and missing parents) for the ``with`` block; remove the ones it created,
    if still empty, when the block raises."""
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the folder {folder}: {exc.strerror or exc}") from None
    try:
        yield
    except BaseException:
        for p in created:  # deepest first
            try:
                p.rmdir()
            except OSError:
                break
        raise


def check_outputs(inputs: Mapping[str, Iterable], outputs: Mapping[str, Sequence]) -> None:
    """Refuse, before any work, outputs that would replace an input or each other, and
    destinations that cannot be written.

    inputs: {parameter: files it reads}. outputs: {parameter: files it writes}, the parameter's
    own file first, then derived files as :class:`Output` (path, label) or plain paths; each
    file's :func:`companions` are added. Empty or None paths are skipped.
    Raises OutputError naming both parameters, e.g. 'OUTPUT_REPORT: its JSON report
    /r/result.json is the file of OUTPUT_SCENE; choose another name'.
    """
    seen: dict[tuple, tuple[str, Output]] = {}
    for parameter, files in inputs.items():
        for f in files:
            if f:
                seen.setdefault(file_key(f), (parameter, Output(Path(f))))
    for parameter, files in outputs.items():
        mine = {}
        for f in [g for f in _listed(files) for g in (f, *companions(f.path))]:
            key = file_key(f.path)
            if key in seen:
                raise OutputError(_clash(parameter, f, *seen[key]))
            mine.setdefault(key, (parameter, f))
        seen.update(mine)
    for parameter, files in outputs.items():
        for f in _listed(files):
            check_destination(f.path, f"{parameter} ({f.label})" if f.label else parameter)


def _listed(files: Sequence) -> list[Output]:
    """Paths and Outputs as Outputs, without empty ones (outputs not asked for)."""
    files = [f if isinstance(f, Output) else Output(Path(f)) if f else None for f in files]
    return [f for f in files if f is not None and f.path]


def _clash(parameter: str, output: Output, other: str, other_file: Output) -> str:
    what = f"{output.label} {output.path}" if output.label else str(output.path)
    theirs = f"{other_file.label} of {other}" if other_file.label else f"the file of {other}"
    return (f"{parameter}: {what} is {theirs} ({other_file.path}); it would be replaced: choose another "
            "name or folder")


def _umask() -> int:
    """The process's umask, read without changing it where the system shows it (Linux); else
    set and restored at once."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# --- writing ---------------------------------------------------------------------------------
class OutputSet:
    """Files written under temporary names and renamed over their destinations together by
    :meth:`commit` (each rename atomic); :meth:`discard` removes every temporary file. Use
    :func:`atomic_outputs`, which calls one or the other."""

    def __init__(self) -> None:
        self._folders: dict[Path, Path] = {}  # destination folder -> private temporary folder
        self._files: dict[Path, Path] = {}  # destination -> temporary path

    def path(self, final) -> Path:
        """The temporary path to write ``final`` to: ``final``'s name inside a private folder in
        ``final``'s (resolved) folder. OutputError when it cannot be written there
        (:func:`check_destination`)."""
        if destination(final) in self._files:
            return self._files[destination(final)]
        check_destination(final)
        final = destination(final)
        folder = final.parent
        if folder not in self._folders:
            try:
                self._folders[folder] = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".part",
                                                              dir=folder))
            except OSError as exc:
                raise OutputError(f"cannot write {final}: {os_failure(final, exc)}") from None
        tmp = self._folders[folder] / final.name
        if tmp in self._files.values():  # the same name for two folders' files is fine, twice in one is not
            raise OutputError(f"cannot write {final}: another output of this run has the same name")
        self._files[final] = tmp
        return tmp

    def commit(self) -> list[Path]:
        """Rename every written file (and its side files: same stem, e.g. shapefile parts) over
        its destination; OutputError (and nothing renamed) when one is missing."""
        missing = [str(f) for f, tmp in self._files.items() if not tmp.is_file()]
        if missing:
            raise OutputError(f"cannot write {', '.join(missing)}: nothing was written")
        mode = 0o666 & ~_umask()  # what a new file gets (mkstemp gives 0600, SQLite 0644)
        try:
            for final, tmp in self._files.items():
                for side in sorted(tmp.parent.glob(tmp.stem + ".*")):  # side files first, the file last
                    if side != tmp and side.name not in {t.name for t in self._files.values()}:
                        os.chmod(side, mode)
                        os.replace(side, final.with_name(side.name))
                os.chmod(tmp, mode)
                os.replace(tmp, final)
        except OSError as exc:
            where = exc.filename or final
            raise OutputError(f"cannot write {where}: {os_failure(where, exc)}") from None
        finally:
            self.discard()
        return list(self._files)

    def discard(self) -> None:
        """Remove the temporary folders with everything in them (all made by this run)."""
        for tmp in self._folders.values():
            shutil.rmtree(tmp, ignore_errors=True)
        self._folders.clear()


@contextmanager
def atomic_outputs() -> Iterator[OutputSet]:
    """An :class:`OutputSet`, committed when the block ends normally and discarded when it raises
    (also on cancel): the destinations get all the new files or keep what they held. Write errors
    (OSError: disk full, permissions) become OutputError naming the file."""
    files = OutputSet()
    try:
        yield files
    except OSError as exc:
        files.discard()
        raise OutputError(f"cannot write {exc.filename or 'the output'}: "
                          f"{os_failure(exc.filename or 'the output', exc)}") from None
    except BaseException:
        files.discard()
        raise
    files.commit()


@contextmanager
def output_set(files: OutputSet | None) -> Iterator[OutputSet]:
    """``files`` itself (its owner commits it), or a new set committed when the block ends
    normally (:func:`atomic_outputs`): for writers that may be part of a larger set."""
    if files is not None:
        yield files
        return
    with atomic_outputs() as own:
        yield own


@contextmanager
def atomic_output(path, files: OutputSet | None = None) -> Iterator[Path]:
    """The temporary path to write ``path`` to; renamed over ``path`` when the block ends
    normally, removed when it raises (see the module docstring). With ``files``, the path is
    taken from that set and its owner commits it with the others."""
    with output_set(files) as own:
        tmp = own.path(path)
        try:
            yield tmp
        except OSError as exc:  # a full disk, a quota: named by the destination, not the temporary path
            raise OutputError(f"cannot write {path}: {os_failure(path, exc)}") from None


def write_text(path, text: str, files: OutputSet | None = None, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` completely or not at all (OutputError naming the file); with
    ``files``, as part of that set."""
    with atomic_output(path, files) as tmp:
        tmp.write_text(text, encoding=encoding)


@dataclass
class ClosingErrors:
    """What GDAL/OGR said while datasets were closed in a :func:`closing_errors` block ('' if nothing)."""
    message: str = ""


# closing_errors blocks under way, per thread (ident -> innermost last), and the hook they replace:
# the hook is process-wide, blocks of several threads (QGIS tasks, Dask worker threads) overlap.
_CLOSING: dict[int, list[ClosingErrors]] = {}
_CLOSING_LOCK = threading.Lock()
_OUTER_HOOK = [sys.unraisablehook]


def _keep_closing_error(unraisable) -> None:
    """sys.unraisablehook while a :func:`closing_errors` block is open: an error of a thread in such a
    block is kept there, any other goes to the hook the blocks replaced."""
    blocks = _CLOSING.get(threading.get_ident())
    if blocks:
        blocks[-1].message = blocks[-1].message or str(unraisable.exc_value)
    else:
        _OUTER_HOOK[0](unraisable)


@contextmanager
def closing_errors() -> Iterator[ClosingErrors]:
    """A block in which GDAL/OGR datasets are closed (their last references dropped). Closing flushes
    the last blocks, and an error then (a full disk) cannot be raised from a destructor: Python hands
    it to ``sys.unraisablehook``, which prints it to stderr as 'Exception ignored'. Within the block
    the hook keeps it instead (errors of this thread only), and the failure is returned in ``.message``."""
    found = ClosingErrors()
    me = threading.get_ident()
    with _CLOSING_LOCK:
        if not _CLOSING:
            _OUTER_HOOK[0] = sys.unraisablehook
            sys.unraisablehook = _keep_closing_error
        _CLOSING.setdefault(me, []).append(found)
    try:
        yield found
    finally:
        with _CLOSING_LOCK:
            _CLOSING[me].pop()
            if not _CLOSING[me]:
                del _CLOSING[me]
            if not _CLOSING:
                sys.unraisablehook = _OUTER_HOOK[0]


def check_closed(path, closing: ClosingErrors) -> None:
    """OutputError naming ``path`` (its destination, when it is a temporary file of an OutputSet) and
    a full disk when closing it failed (see :func:`closing_errors`)."""
    if closing.message:
        raise OutputError(f"cannot write {destination_of(path)}: {write_failure(path, closing.message)}")


def destination_of(path) -> Path:
    """The destination a temporary path of :meth:`OutputSet.path` (``<folder>/.<name>.<random>.part/<file>``)
    stands for, ``<folder>/<file>``; any other path itself. Messages name the file the user asked for."""
    path = Path(path)
    folder = path.parent.name
    return path.parent.parent / path.name if folder.startswith(".") and folder.endswith(".part") else path


def os_failure(path, exc: OSError) -> str:
    """An OSError writing ``path`` in words: a full disk (or quota) named as such, else the system's text."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"no space left on the device holding {path}"
    return exc.strerror or str(exc)


FULL_DISK_BYTES = 1 << 20  # a device with less than this free after a failed write was filled by it


def write_failure(path, message: str) -> str:
    """A GDAL/OGR write failure of ``path`` in words: a full disk named as such (by GDAL's message, or
    by the device left with almost no free space: GDAL then often reports a follow-up error instead,
    e.g. SQLite's 'no such table')."""
    text = message.lower()
    try:
        nearly_full = shutil.disk_usage(Path(path).parent).free < FULL_DISK_BYTES
    except OSError:
        nearly_full = False
    if nearly_full or any(s in text for s in ("no space left", "disk is full", "disk full", "enospc")):
        return f"no space left on the device holding {destination_of(path)} ({message})"
    return message
