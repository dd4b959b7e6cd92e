"""
Atomic file writes: a reader (or a crash) sees either the old file or the new one, never a partial file.

Every file is written to a temporary file in the same folder, flushed to disk, then moved into place with
``os.replace`` (atomic on POSIX and Windows when both paths are on one file system). A write interrupted by an
exception, Ctrl-C or ``SIGKILL`` leaves the previous file untouched; after a ``SIGKILL`` the temporary file
(``.<stem>.<pid>.<random>.tmp<suffix>``) may remain beside it.
"""

import os
import pathlib
import secrets
import stat
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import IO, Any

__all__ = ["atomic_open", "atomic_path", "atomic_save", "atomic_write_text", "check_writable_folder", "save_path_with_suffix"]


def _fsync_folder(folder: str) -> None:
    """Make the rename itself durable (where the platform allows opening a folder)."""
    with suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_file(path: str) -> None:
    with open(path, "rb") as file:
        os.fsync(file.fileno())


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[pathlib.Path]:
    """
    A temporary path beside ``path`` for any writer that takes a path (``savefig``, ``Image.save``, ...); when the
    block ends without an exception, the file written there is synced and moved onto ``path``. On any exception
    (``KeyboardInterrupt`` included) it is removed and ``path`` keeps its previous content. The temporary name keeps
    the suffix of ``path``, so writers that choose the format from the suffix choose the same one.

    The file keeps what ``os.replace`` would otherwise change: an existing file's permission bits (a ``chmod 600``
    model stays private), and a symbolic link (``latest.zip``) stays a link: its target is written.

    :param path: the final file; its folder must exist
    :return: the temporary path to write
    """
    path = os.path.realpath(os.fspath(path))  # through symbolic links, to the file they name
    folder, name = os.path.split(path)
    stem, suffix = os.path.splitext(name)
    temporary = os.path.join(folder, f".{stem}.{os.getpid()}.{secrets.token_hex(4)}.tmp{suffix}")
    try:
        yield pathlib.Path(temporary)
        _fsync_file(temporary)
        with suppress(FileNotFoundError):
            os.chmod(temporary, stat.S_IMODE(os.stat(path).st_mode))
        os.replace(temporary, path)
    except BaseException:
        with suppress(OSError):
            os.unlink(temporary)
        raise
    _fsync_folder(folder)


@contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb", **open_kwargs: Any) -> Iterator[IO[Any]]:
    """
    Open a temporary file beside ``path`` for writing; when the block ends without an exception, the file is synced
    and moved onto ``path`` (see :func:`atomic_path`).

    :param path: the final file; its folder must exist
    :param mode: a write mode of ``open`` (``"wb"``, ``"w"``)
    :param open_kwargs: other arguments of ``open`` (``newline=""``, ``encoding=...``)
    :return: the open temporary file
    """
    if "w" not in mode:
        raise ValueError(f"atomic_open writes whole files: mode must contain 'w', got {mode!r}")
    # "x": a new file, created with the usual permissions (the umask applies, as for the file it replaces)
    with atomic_path(path) as temporary, open(temporary, mode.replace("w", "x"), **open_kwargs) as file:
        yield file


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> pathlib.Path:
    """
    Write a text file atomically.

    :param path: the file
    :param text: its content
    :param encoding: the text encoding
    :return: the path
    """
    with atomic_open(path, "w", encoding=encoding) as file:
        file.write(text)
    return pathlib.Path(path)


def save_path_with_suffix(path: str | os.PathLike, suffix: str) -> pathlib.Path:
    """
    The file SB3's ``save_util.open_path`` would write for ``path``: ``suffix`` is added when the name has none,
    a path that is a folder becomes ``<path>_2`` (with SB3's warning), and missing parent folders are created.

    :param path: the path given to ``save``
    :param suffix: the default suffix without the dot (``"zip"``, ``"pkl"``)
    :return: the file to write
    """
    target = pathlib.Path(path)
    if target.suffix == "" and suffix:
        target = pathlib.Path(f"{target}.{suffix}")
    if target.is_dir():
        import warnings

        warnings.warn(f"Path '{target}' is a folder. Will save instead to {target}_2")
        target = pathlib.Path(f"{target}_2")
    target.parent.mkdir(parents=True, exist_ok=True)
    return target


def atomic_save(
    write: Callable[[IO[bytes]], None], path: str | os.PathLike | IO[bytes], suffix: str = ""
) -> pathlib.Path | None:
    """
    Run ``write(file)`` on a temporary file and move it onto the file SB3 would write for ``path``. A file object
    (not a path) is handed to ``write`` as it is.

    :param write: writes the whole content into an open binary file (e.g. ``model.save``, ``pickle.dump``)
    :param path: a path as SB3's ``save`` methods take it, or an open binary file
    :param suffix: the default suffix, as in :func:`save_path_with_suffix`
    :return: the file written, or None for a file object
    """
    if not isinstance(path, str | os.PathLike):
        write(path)
        return None
    target = save_path_with_suffix(path, suffix)
    with atomic_open(target, "wb") as file:
        write(file)  # type: ignore[arg-type]
    return target


def check_writable_folder(folder: str | os.PathLike, what: str) -> pathlib.Path:
    """
    Check, before any work is done, that files can be written in ``folder``: it is a folder where files can be
    created, or it does not exist yet and its nearest existing parent is one. Nothing is created.

    :param folder: the output folder
    :param what: how to name it in the message (e.g. ``"--out"``)
    :return: the folder
    :raises ValueError: one line naming the folder and the reason
    """
    target = pathlib.Path(folder)
    existing = target
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if existing == target and not target.is_dir():
        raise ValueError(f"{what}: {os.fspath(target)} exists and is not a folder")
    if existing != target and not existing.is_dir():
        raise ValueError(f"{what}: cannot create the folder {os.fspath(target)}: {os.fspath(existing)} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{what}: cannot write to the folder {os.fspath(target)} ({os.fspath(existing)}: permission denied)")
    probe = existing / f".write-test.{os.getpid()}.{secrets.token_hex(4)}"
    try:
        probe.touch(exist_ok=False)
        probe.unlink()
    except OSError as error:
        reason = error.strerror or str(error)
        raise ValueError(f"{what}: cannot write to the folder {os.fspath(target)} ({reason})") from error
    return target
