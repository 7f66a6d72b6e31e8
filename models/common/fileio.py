"""The one output module: checked output paths and atomic writes, for the apps and the library.

Every file mmlearn writes goes through here:

* :func:`check_output_file` / :func:`check_output_dir` check an output path *before* any
  work, by actually creating (and removing) a temporary file beside the target (or in the
  folder): ``os.access`` is not enough (it says yes to root on read-only or virtual file
  systems). A missing parent folder is an error unless ``create_dirs`` says to create it.
* :func:`atomic_write_text`, :func:`atomic_write_bytes` and :func:`atomic_output` (for
  writers that want a file object: ``savefig``, ``np.save``) write to a uniquely named
  temporary file in the target's folder, fsync it, rename it over the target and fsync the
  folder, so a reader (or a crash at any moment) sees either the old file or the new one,
  never a half-written one, and no fixed temporary name can collide between two writers.

A path that cannot be written raises :class:`OutputPathError` (a ``ValueError``) with a
one-line message naming the path and, when given, the flag (``what``) it came from.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

__all__ = ["OutputPathError", "check_output_file", "check_output_dir", "atomic_write_text",
           "atomic_write_bytes", "atomic_output", "fsync_dir"]


class OutputPathError(ValueError):
    """An output path that cannot be written (missing or unwritable folder, a folder where a
    file is expected, ...); the message names the path and the flag it came from."""


def _prefix(what: str | None) -> str:
    return f"{what}: " if what else ""


def _reason(e: OSError) -> str:
    return e.strerror or type(e).__name__


def fsync_dir(folder) -> None:
    """fsync a folder, so a rename or a new file in it survives a crash of the machine
    (best effort: a file system that cannot sync folders is left alone)."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _probe(folder: Path, name: str, what: str | None) -> None:
    """Create and remove a temporary file in ``folder``; an OutputPathError if that fails."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".probe", dir=folder)
    except OSError as e:
        raise OutputPathError(f"{_prefix(what)}cannot write in folder {folder} "
                              f"({_reason(e)})") from None
    os.close(fd)
    try:
        os.unlink(tmp)
    except OSError:  # pragma: no cover - created but not removable: still writable
        pass


def _ensure_folder(folder: Path, what: str | None, create_dirs: bool,
                   flag_hint: str | None) -> None:
    if folder.is_dir():
        return
    if folder.exists() or any(p.exists() and not p.is_dir() for p in folder.parents):
        raise OutputPathError(f"{_prefix(what)}{_first_file(folder)} is a file, not a folder")
    if not create_dirs:
        hint = f" (create it, or pass {flag_hint})" if flag_hint else ""
        raise OutputPathError(f"{_prefix(what)}folder {folder} does not exist{hint}")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputPathError(f"{_prefix(what)}cannot create folder {folder} "
                              f"({_reason(e)})") from None


def _first_file(folder: Path) -> Path:
    """The first existing non-folder along ``folder`` (the reason it cannot be a folder)."""
    for p in [*reversed(folder.parents), folder]:
        if p.exists() and not p.is_dir():
            return p
    return folder


def check_output_file(path, *, what: str | None = None, create_dirs: bool = False,
                      flag_hint: str | None = None) -> Path | None:
    """Check that ``path`` can be written as a file, before any work: it is not a folder,
    its folder exists (or, with ``create_dirs``, is created) and a temporary file can be
    created and removed there. ``what`` (a flag such as ``--plot``) starts the message of
    the :class:`OutputPathError` raised otherwise; ``flag_hint`` names the flag that would
    create a missing folder. ``None`` or ``""``: nothing to check. Returns the path."""
    if path is None or str(path) == "":
        return None
    p = Path(path)
    if p.is_dir():
        raise OutputPathError(f"{_prefix(what)}{p} is a folder, expected a file name")
    folder = p.parent if str(p.parent) else Path(".")
    _ensure_folder(folder, what, create_dirs, flag_hint)
    _probe(folder, p.name, what)
    return p


def check_output_dir(path, *, what: str | None = None, create: bool = True,
                     create_dirs: bool = False, flag_hint: str | None = None) -> Path | None:
    """Check that ``path`` is a folder files can be written in, before any work: with
    ``create`` a missing folder is made when its parent exists (``create_dirs``: its
    missing parents too); a file there is an error; a temporary file is created in it and
    removed. Raises :class:`OutputPathError`; returns the path (None for None / "")."""
    if path is None or str(path) == "":
        return None
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputPathError(f"{_prefix(what)}{p} is a file, expected a folder")
    if not p.exists():
        parent = p.parent if str(p.parent) else Path(".")
        if not create:
            hint = f" (create it, or pass {flag_hint})" if flag_hint else ""
            raise OutputPathError(f"{_prefix(what)}folder {p} does not exist{hint}")
        _ensure_folder(parent, what, create_dirs, flag_hint)
        try:
            p.mkdir(exist_ok=True)
        except OSError as e:
            raise OutputPathError(f"{_prefix(what)}cannot create folder {p} "
                                  f"({_reason(e)})") from None
    _probe(p, "mmlearn", what)
    return p


@contextlib.contextmanager
def atomic_output(path, *, binary: bool = True, create_dirs: bool = False,
                  encoding: str = "utf-8"):
    """A file object to write ``path`` atomically: everything written goes to a uniquely
    named temporary file in the same folder, which on a normal exit of the ``with`` block
    is flushed, fsynced, given the usual permissions (0666 less the umask, not mkstemp's
    0600), renamed over ``path``, and the folder fsynced. On an exception the temporary
    file is removed and ``path`` is unchanged. A missing folder raises
    :class:`OutputPathError` unless ``create_dirs``::

        with atomic_output("frame.npy") as f:
            np.save(f, depth)
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    _ensure_folder(folder, None, create_dirs, None)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb" if binary else "w",
                       **({} if binary else {"encoding": encoding})) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    fsync_dir(folder)


def atomic_write_bytes(path, data: bytes, *, create_dirs: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`). Returns the path."""
    with atomic_output(path, create_dirs=create_dirs) as f:
        f.write(data)
    return Path(path)


def atomic_write_text(path, text: str, *, create_dirs: bool = False,
                      encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (a uniquely named temporary file in the same
    folder, fsync, rename, fsync of the folder), so a reader never sees a half-written
    file. The file gets the usual permissions (0666 less the umask). A missing folder
    raises :class:`OutputPathError` unless ``create_dirs``. Returns the path."""
    if not isinstance(text, str):
        raise TypeError(f"atomic_write_text writes a str, got {type(text).__name__}")
    with atomic_output(path, binary=False, create_dirs=create_dirs, encoding=encoding) as f:
        f.write(text)
    return Path(path)
