"""Execution engines: where the independent tasks of a reconstruction run.

Feature extraction (one task per image) and pair verification (one task per pair)
are independent of each other. The pipelines hand them to an engine, which maps a
pure, module-level function over the tasks' arguments; registration, triangulation
and bundle adjustment stay with the caller. The geometry never imports an engine's
library: it receives an :class:`Engine` and calls :meth:`Engine.map`.

- :class:`LocalEngine` (the default): in this process, one task after the other.
- :class:`scene3D.engines.dask_engine.DaskEngine`: tasks on the workers of a Dask
  cluster, or of worker processes it starts on this machine (the optional extra
  ``distributed``).

An engine for a cluster lives in its own module and imports its library only when
it is built, so that a missing optional extra is a one-line error at the command,
not an ``ImportError`` deep inside.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any, Protocol, TypeVar

R = TypeVar("R")

#: ``progress(label, done, total)``: called as tasks finish (``done`` of ``total``).
Progress = Callable[[str, int, int], None]


class Engine(Protocol):
    """Runs independent tasks: ``fn(*args)`` for every tuple of arguments.

    Attributes
    ----------
    name : str
        How the engine is described to the user ("local", "dask tcp://...").
    """

    name: str

    def map(self, fn: Callable[..., R], arguments: Iterable[tuple], *, label: str = "tasks",
            progress: Progress | None = None) -> Iterator[R]:
        """``fn(*a)`` for each tuple ``a`` of ``arguments``, yielded in their order.

        ``fn`` must be a module-level function (it may be sent to another process)
        without side effects; ``label`` names the tasks in progress reports. An
        exception raised by a task is raised here.

        Parameters
        ----------
        fn : callable
            A module-level function without side effects.
        arguments : iterable of tuple
            The arguments of each task.
        label : str, default "tasks"
            Names the tasks in progress reports.
        progress : callable or None, default None
            ``progress(label, done, total)``; None for no reports.

        Yields
        ------
        object
            Each task's result, in the order of ``arguments``.
        """
        ...

    def share(self, value: Any) -> Any:
        """A handle to ``value`` that later tasks may take as an argument in its place.

        Locally the value itself; on a cluster, the value is sent to the workers
        once instead of with every task that needs it.

        Parameters
        ----------
        value : Any
            A value taken as immutable.

        Returns
        -------
        Any
        """
        ...


class LocalEngine:
    """The default engine: every task in this process, one after the other."""

    name = "local"

    def map(self, fn: Callable[..., R], arguments: Iterable[tuple], *, label: str = "tasks",
            progress: Progress | None = None) -> Iterator[R]:
        """``fn(*a)`` for each tuple ``a`` of ``arguments``, in this process, in order.

        Parameters
        ----------
        fn : callable
            A function without side effects.
        arguments : iterable of tuple
            The arguments of each task.
        label : str, default "tasks"
            Names the tasks in progress reports.
        progress : callable or None, default None
            ``progress(label, done, total)`` after each task; None for no reports.

        Yields
        ------
        object
            Each task's result.
        """
        arguments = list(arguments)
        for done, args in enumerate(arguments, start=1):
            result = fn(*args)
            if progress is not None:
                progress(label, done, len(arguments))
            yield result

    def share(self, value: Any) -> Any:
        """``value`` itself (nothing to send in one process).

        Parameters
        ----------
        value : Any
            A value taken as immutable.

        Returns
        -------
        Any
        """
        return value


__all__ = ["Engine", "LocalEngine", "Progress"]
