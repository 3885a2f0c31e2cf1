"""What the Dask engine's tasks run on the workers (:mod:`scene3D.engines.dask_engine`).

:func:`run_task` wraps every task: it sets OpenCV's threads once per process, stages the
files the client sent as bytes (:class:`FileBytes`) as temporary copies under their own
names, names the worker in a task's ``OSError`` or ``ValueError``, and counts the
finished tasks (:func:`finished_tasks`). The other functions answer the client's questions
about a worker (:func:`file_sizes`, :func:`scene3d_version`). Nothing here imports Dask
but :func:`worker_address`, when it runs on a worker.
"""

from __future__ import annotations

import os
import tempfile
from collections import Counter
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, TypeVar

R = TypeVar("R")


@dataclass(frozen=True)
class FileBytes:
    """A file's content sent with a task, for a worker that cannot read the file itself.

    Attributes
    ----------
    path : str
        The file's absolute path on the client (the name of the worker's copy).
    data : bytes
        Its content.
    """

    path: str
    data: bytes


_TASK_COUNTS: Counter[str] = Counter()  # tasks finished in this process, by engine/label
_OPENCV_THREADS: list[int | None] = []  # the setting made in this process, once


def configure_process(opencv_threads: int | None) -> None:
    """Set OpenCV's threads in this process, once per setting.

    Parameters
    ----------
    opencv_threads : int or None
        ``cv2.setNumThreads``; None leaves OpenCV's setting alone.
    """
    if _OPENCV_THREADS == [opencv_threads]:
        return
    if opencv_threads is not None:
        import cv2

        cv2.setNumThreads(opencv_threads)
    _OPENCV_THREADS[:] = [opencv_threads]


def worker_address() -> str:
    """The address of the Dask worker this runs on, or ``"this process"`` off a worker.

    Returns
    -------
    str
    """
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "this process"


def with_worker(exc: Exception, staged: dict[str, str]) -> Exception:
    """``exc`` with the worker named (and staged copies named as the original files);
    ``exc`` itself when its type takes more than a message.

    Parameters
    ----------
    exc : Exception
        What a task raised.
    staged : dict of str to str
        The temporary copies' paths and the files they stand for.

    Returns
    -------
    Exception
    """
    message = str(exc)
    for copy, original in staged.items():
        message = message.replace(copy, original)
    try:
        return type(exc)(f"{message} (on worker {worker_address()})")
    except TypeError:  # e.g. UnicodeDecodeError
        return exc


def run_task(fn: Callable[..., R], tag: str, opencv_threads: int | None, *args: Any) -> R:
    """Run ``fn(*args)`` on a worker: files staged, OpenCV's threads set, errors located.

    Parameters
    ----------
    fn : callable
        The task's module-level function.
    tag : str
        ``"ENGINE_ID/LABEL"``, under which the finished task is counted.
    opencv_threads : int or None
        For :func:`configure_process`.
    *args
        The task's arguments; a :class:`FileBytes` becomes the path of a temporary copy.

    Returns
    -------
    object
        What ``fn`` returns.
    """
    configure_process(opencv_threads)
    staged: dict[str, str] = {}
    sends = any(isinstance(a, FileBytes) for a in args)
    with tempfile.TemporaryDirectory(prefix="scene3D-") if sends else nullcontext("") as folder:
        real_args = []
        for k, arg in enumerate(args):
            if isinstance(arg, FileBytes):
                copy = Path(folder) / str(k) / PurePath(arg.path).name
                copy.parent.mkdir()
                copy.write_bytes(arg.data)
                staged[str(copy)] = arg.path
                arg = copy
            real_args.append(arg)
        try:
            result = fn(*real_args)
        except (OSError, ValueError) as exc:
            if type(exc).__module__ != "builtins":  # a library's own error: left as it is
                raise
            located = with_worker(exc, staged)
            if located is exc:
                raise
            raise located from None
    _TASK_COUNTS[tag] += 1
    return result


def shared_value(value: Any) -> Any:
    """The task of a value shared from the client: the value itself.

    Parameters
    ----------
    value : Any
        The shared value.

    Returns
    -------
    Any
        ``value``.
    """
    return value


def file_sizes(paths: list[str]) -> list[int | None]:
    """The size of each file as this process sees it (None: cannot read it).

    Parameters
    ----------
    paths : list of str
        Absolute paths.

    Returns
    -------
    list of int or None
        Bytes.
    """
    sizes: list[int | None] = []
    for path in paths:
        try:
            sizes.append(os.stat(path).st_size if os.access(path, os.R_OK) else None)
        except OSError:
            sizes.append(None)
    return sizes


def finished_tasks(engine_id: str) -> dict[str, int]:
    """The tasks of one engine that this process finished, by label.

    Parameters
    ----------
    engine_id : str
        The engine's id (the first part of the tags of :func:`run_task`).

    Returns
    -------
    dict of str to int
    """
    return {tag.split("/", 1)[1]: n for tag, n in _TASK_COUNTS.items()
            if tag.startswith(engine_id + "/")}


def scene3d_version() -> str:
    """The scene3D version this process runs.

    Returns
    -------
    str
    """
    from .. import __version__

    return __version__
