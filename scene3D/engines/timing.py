"""Seconds per pipeline stage: a timer the stages run inside, instead of a dict of sums.

A pipeline makes one :class:`StageTimer` and hands it to the code it calls, which times
its work with ``with timer.stage("matching"): ...``; the result records
:attr:`StageTimer.seconds`. It lives beside the engines (which run the stages' tasks)
and imports nothing of scene3D, so that the two-view and many-view code can both use it.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager


class StageTimer:
    """Wall-clock seconds spent in named stages, in the order the stages were first seen.

    A stage that runs again adds to its seconds. A stage entered inside another one
    pauses the outer stage's clock: every second is counted in exactly one stage, so the
    seconds add up to the time spent in all of them (the ``total`` results report).
    A stage left by an exception still records its time.

    Parameters
    ----------
    stages : iterable of str, default ()
        Stages to list first (at 0 s until they run), fixing their order in
        :attr:`seconds` whatever order they run in.

    Examples
    --------
    >>> timer = StageTimer(["features", "matching"])
    >>> with timer.stage("matching"):
    ...     pass
    >>> list(timer.seconds)
    ['features', 'matching']
    """

    def __init__(self, stages: Iterable[str] = ()) -> None:
        self._seconds: dict[str, float] = dict.fromkeys(stages, 0.0)
        self._inner: list[float] = []  # per open stage: seconds of the stages inside it

    def declare(self, *stages: str) -> None:
        """List the ``stages`` not seen yet (at 0 s), after those already listed.

        Parameters
        ----------
        *stages : str
            Stage names; those already listed keep their place and seconds.
        """
        for name in stages:
            self._seconds.setdefault(name, 0.0)

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the ``with`` block as stage ``name`` (added to its earlier seconds).

        Parameters
        ----------
        name : str
            The stage, a key of :attr:`seconds`.

        Yields
        ------
        None
        """
        start = time.perf_counter()
        self._inner.append(0.0)
        try:
            yield
        finally:
            elapsed = time.perf_counter() - start
            inner = self._inner.pop()
            self.add(name, elapsed - inner)
            if self._inner:  # the enclosing stage's clock does not count this block
                self._inner[-1] += elapsed

    def add(self, name: str, seconds: float) -> None:
        """Add ``seconds`` measured elsewhere (e.g. by another timer) to stage ``name``.

        Parameters
        ----------
        name : str
            The stage.
        seconds : float
            Seconds to add.
        """
        self._seconds[name] = self._seconds.get(name, 0.0) + float(seconds)

    @property
    def seconds(self) -> dict[str, float]:
        """dict[str, float]: a copy of the seconds per stage, in the stages' order."""
        return dict(self._seconds)

    @property
    def total_s(self) -> float:
        """float: the seconds of all stages, summed in their order."""
        return sum(self._seconds.values())
