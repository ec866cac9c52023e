"""Output files written whole or not at all (docs/design.md, "File formats"): every file a command writes goes to a
temporary file beside it (``.NAME.XXXXXXXX.tmp``, in the same folder, so on the same file system), is flushed and
synced to disk, and only then renamed over ``NAME`` (``os.replace``, atomic on POSIX and Windows). An interrupted write
(an error, Ctrl-C, a full disk) removes the temporary file and leaves the old ``NAME``, or none, as it was; a
process killed outright (SIGKILL, SIGTERM, a power cut) can leave a stray ``.NAME.XXXXXXXX.tmp`` beside it,
never a partial ``NAME``."""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from optcal.core.errors import InputError

# The one-line refusals of an existing output without --force: the calibration files' wording, and the other
# commands' (optcal.app.commands._common.refuse_overwrite's).
EXISTS = "{path} exists; pass --force to overwrite it or choose another -o path"
EXISTS_OUTPUT = "{path} exists; choose another output path or pass --force to overwrite it"

_umask: int | None = None


def _default_mode() -> int:
    """0666 less the process's umask: the mode ``open(path, "w")`` gives a new file (mkstemp's is 0600). The umask
    is read once (reading it means setting it) and kept."""
    global _umask
    if _umask is None:
        _umask = os.umask(0o022)
        os.umask(_umask)
    return 0o666 & ~_umask


def _temporary(target: Path, binary: bool, encoding: str | None, newline: str | None) -> tuple[IO[Any], str]:
    """An open temporary file beside ``target`` and its path."""
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        fh = os.fdopen(fd, "wb" if binary else "w", **({} if binary else {"encoding": encoding, "newline": newline}))
    except BaseException:
        os.close(fd)
        os.unlink(tmp)
        raise
    return fh, tmp


def _sync_folder(folder: Path) -> None:
    """Make the rename itself durable (POSIX; best effort: some file systems refuse to sync a folder)."""
    if os.name != "posix":
        return
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


@contextmanager
def atomic_write(path, *, overwrite: bool, binary: bool = False, encoding: str | None = None,
                 newline: str | None = None, check: Callable[[str], None] | None = None,
                 exists: str = EXISTS) -> Iterator[IO[Any]]:
    """A file handle (text, or bytes with ``binary``) whose content replaces ``path`` when the ``with`` block
    ends without an exception: written to a temporary file in the same folder, flushed, fsynced, checked by
    ``check(temporary_path)`` (if given; it raises to refuse), given the mode of the file it replaces (or
    ``open``'s default for a new one) and renamed into place. On any exception (KeyboardInterrupt included)
    the temporary file is removed and ``path`` is left as it was. An existing ``path`` is refused unless
    ``overwrite`` (``exists``: the one-line message, ``{path}`` filled in); a symbolic link is kept and its
    target replaced. OSErrors become one-line :class:`InputError` s naming ``path``."""
    path = Path(path)
    if not overwrite and path.exists():
        raise InputError(exists.format(path=path))
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        fh, tmp = _temporary(target, binary, encoding, newline)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        try:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        finally:
            fh.close()
        if check is not None:
            check(tmp)
        try:
            mode = stat.S_IMODE(os.stat(target).st_mode)
        except FileNotFoundError:
            mode = _default_mode()
        os.chmod(tmp, mode)
        if not overwrite and path.exists():  # appeared while we wrote: still not ours to replace
            raise InputError(exists.format(path=path))
        os.replace(tmp, target)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if os.path.lexists(tmp):
            os.unlink(tmp)
    _sync_folder(target.parent)


def write_atomic(path, content: str | bytes, *, overwrite: bool, encoding: str | None = None,
                 check: Callable[[str], None] | None = None, exists: str = EXISTS) -> None:
    """:func:`atomic_write` for content already in memory: ``Path.write_text`` / ``write_bytes`` whole or not
    at all."""
    binary = isinstance(content, bytes)
    with atomic_write(path, overwrite=overwrite, binary=binary, encoding=encoding, check=check,
                      exists=exists) as fh:
        fh.write(content)


def _sync_tree(path: Path) -> None:
    """fsync every file under ``path`` (a file or a folder) and the folders holding them (best effort)."""
    files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
    for f in files:
        with open(f, "rb") as fh:
            os.fsync(fh.fileno())
    for folder in {f.parent for f in files}:
        _sync_folder(folder)


@contextmanager
def atomic_output(path, *, overwrite: bool, exists: str = EXISTS) -> Iterator[Path]:
    """:func:`atomic_write` for a writer that creates its output itself, a file or a folder (rosbags' writers,
    which refuse an existing path; a ROS 2 bag is a folder): a path not yet made, ``path``'s name inside a new
    temporary folder beside it (``.NAME.XXXXXXXX.tmp/NAME``, so the writer names what it makes inside after
    ``NAME``). When the ``with`` block ends without an exception what was written there is synced and renamed
    to ``path``; on any exception the temporary folder is removed and ``path`` left as it was. An existing
    file is replaced in one rename; an existing folder (or a file replaced by a folder) is first renamed into
    the temporary folder, then removed: a process killed between the two renames leaves the new output in
    ``.NAME.XXXXXXXX.tmp`` and no ``NAME``. An existing ``path`` is refused unless ``overwrite``."""
    import shutil

    path = Path(path)
    if not overwrite and path.exists():
        raise InputError(exists.format(path=path))
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        tmpdir = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    inner = tmpdir / target.name
    try:
        yield inner
        if not os.path.lexists(inner):
            raise InputError(f"cannot write {path}: the writer made nothing")
        _sync_tree(inner)
        if not overwrite and path.exists():  # appeared while we wrote: still not ours to replace
            raise InputError(exists.format(path=path))
        if target.exists() and (target.is_dir() or inner.is_dir()):
            os.rename(target, tmpdir / f"{target.name}.old")
        os.replace(inner, target)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    _sync_folder(target.parent)
