"""Atomic file writes: a file is complete or not there, and a block of files all or none.

Every writer of :mod:`scene3D.io` goes through :func:`atomic_write_pieces` (or
:func:`atomic_write_bytes`): the data land in a temporary file beside the target that is
renamed over it only when complete, so an interrupted run never leaves a half-written
file. Within :func:`all_or_nothing` the renames wait until every file of the block is
written, so a run that fails while writing (a full disk, say) leaves the earlier results
as they were, not half replaced.
"""

from __future__ import annotations

import io
import os
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

#: The renames that :func:`all_or_nothing` holds back: (temporary file, target) pairs.
_staged: ContextVar[list[tuple[Path, Path]] | None] = ContextVar("staged", default=None)


@contextmanager
def all_or_nothing() -> Iterator[None]:
    """Write the block's files (this module's writers) all, or, if it raises, none.

    Each file is written to its temporary name as usual; the renames over the targets
    wait for the end of the block and happen only if it succeeds (renames need no space,
    so they do not fail for want of it). If it raises, the temporary files are removed
    and every target keeps what it held. Within another such block it adds its files to
    that block's, placed (or not) when the outer block ends.
    """
    if _staged.get() is not None:
        yield
        return
    staged: list[tuple[Path, Path]] = []
    token = _staged.set(staged)
    try:
        yield
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    finally:
        _staged.reset(token)
    try:
        for tmp, path in staged:
            os.replace(tmp, path)
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)


def place_file(tmp: Path, path: Path) -> None:
    """Rename the complete file ``tmp`` over ``path`` now, or at the end of the enclosing
    :func:`all_or_nothing` block.

    Parameters
    ----------
    tmp : Path
        The complete temporary file.
    path : Path
        Its target.
    """
    staged = _staged.get()
    if staged is not None:
        staged.append((tmp, path))
        return
    try:
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def written_bytes(path: str | os.PathLike) -> bytes:
    """The content of a file this module wrote: within :func:`all_or_nothing`, from its
    temporary file while the rename waits; else from ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        A file this module wrote.

    Returns
    -------
    bytes
    """
    path = Path(path)
    for tmp, target in reversed(_staged.get() or []):
        if target == path:
            return tmp.read_bytes()
    return path.read_bytes()


def check_target(path: Path) -> None:
    """Raise ``IsADirectoryError`` when a folder stands where the file ``path`` is to go
    (the rename over it would fail only after every other file was written).

    Parameters
    ----------
    path : Path
        Where a file is to be written.

    Raises
    ------
    IsADirectoryError
        A folder stands at ``path``.
    """
    if path.is_dir():
        raise IsADirectoryError(21, "a folder stands where this file is to be written",
                                str(path))


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and a rename.

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    data : bytes
        Its content.

    Returns
    -------
    Path
    """
    return atomic_write_pieces(path, (data,))


def atomic_write_pieces(path: str | os.PathLike, pieces: Iterable[bytes | Path]) -> Path:
    """Write ``pieces`` one after the other to ``path`` through a temporary file and a
    rename: bytes as they are, a :class:`~pathlib.Path` as that file's whole content.

    Files are copied by the kernel where it can (``os.copy_file_range`` on Linux), never
    read into Python: a report's plotly.js costs a few milliseconds that way, a tenth of
    reading, decoding, joining, encoding and writing it (docs/benchmarks.md#whole-process-speed).

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    pieces : iterable of bytes or Path
        Its content, in order.

    Returns
    -------
    Path
    """
    path = Path(path)
    check_target(path)
    # A name no other writer uses (pid and clock), created exclusively beside the target.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{time.monotonic_ns()}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except OSError as exc:  # named by the file the user asked for, not its temporary name
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    try:
        with os.fdopen(fd, "wb", buffering=0) as f:
            for piece in pieces:
                if isinstance(piece, Path):
                    _copy_file_into(piece, f)
                else:
                    _write_all(f, piece)
    except OSError as exc:  # a full disk, say
        tmp.unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    place_file(tmp, path)
    return path


def _write_all(target: io.RawIOBase, data: bytes) -> None:
    """Write all of ``data`` to the unbuffered ``target``, which may take less at a time."""
    view = memoryview(data)
    while view:
        view = view[target.write(view):]


def _copy_file_into(source: Path, target: io.RawIOBase) -> None:
    """Append the whole of ``source`` to the unbuffered, open ``target``."""
    with open(source, "rb") as src:
        left = os.fstat(src.fileno()).st_size
        if hasattr(os, "copy_file_range"):
            try:
                while left > 0:
                    copied = os.copy_file_range(src.fileno(), target.fileno(), left)
                    if copied == 0:
                        break
                    left -= copied
                return
            except OSError:  # a file system without it: copy through Python from here on
                pass
        while chunk := src.read(1 << 20):
            _write_all(target, chunk)


def write_files(folder: str | os.PathLike, files: dict[str, bytes]) -> list[Path]:
    """Write several files into ``folder`` (created if needed), each atomically.

    Parameters
    ----------
    folder : str or os.PathLike
        Target folder.
    files : dict[str, bytes]
        Content by file name.

    Returns
    -------
    list of Path
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [atomic_write_bytes(folder / name, data) for name, data in files.items()]


def write_text_files(folder: str | os.PathLike, files: dict[str, str]) -> list[Path]:
    """Write several text files (UTF-8) into ``folder`` (created if needed), each
    atomically (:func:`write_files`).

    Parameters
    ----------
    folder : str or os.PathLike
        Target folder.
    files : dict[str, str]
        Text by file name.

    Returns
    -------
    list of Path
    """
    return write_files(folder, {name: text.encode("utf-8") for name, text in files.items()})
