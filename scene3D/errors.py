"""Exceptions raised by scene3D, and the helpers their messages share.

Bad input raises the built-in ``ValueError`` / ``FileNotFoundError`` with a
message naming the argument. A computation that ran on valid input but could not
give a trustworthy answer raises one of the errors below.
"""

from __future__ import annotations

import logging
import warnings

#: Set on the log record of a warning that a result also carries in its ``warnings``
#: (a pose that may not be trustworthy, and why): a command that prints the result with
#: its warnings drops these records rather than say the same thing twice.
RESULT_WARNING = "scene3d_result_warning"


def warn_moved(old: str, new: str) -> None:
    """Say that the module ``old`` moved to ``new``: the one thing a shim left at a moved
    module's old path does besides re-exporting it.

    A shim calls it once, when it is first imported (a module runs once per process),
    with its ``__name__``. The ``DeprecationWarning`` reads ``"OLD moved to NEW"`` and
    points at the line that imported the old path.

    Parameters
    ----------
    old : str
        The old module's full name (the shim's ``__name__``).
    new : str
        Its new one (``"scene3D.geometry.camera"``).
    """
    # stacklevel 3: past this function and the shim, to the importer (the warnings module
    # skips the import machinery's own frames).
    warnings.warn(f"{old} moved to {new}", DeprecationWarning, stacklevel=3)


def plural(count: int, noun: str) -> str:
    """``count`` and ``noun`` for messages: ``"1 pose"``, ``"0 poses"``, ``"2 inner corners"``
    (the last word takes an ``s``; the nouns of scene3D's messages are all regular).

    Parameters
    ----------
    count : int
        The number.
    noun : str
        A regular noun, singular.

    Returns
    -------
    str
    """
    return f"{count} {noun}{'s' * (count != 1)}"


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message, or its type's name when it has none.

    Parameters
    ----------
    exc : BaseException
        The exception.

    Returns
    -------
    str
    """
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def log_result_warnings(logger: logging.Logger, warnings: tuple[str, ...]) -> None:
    """Log each of a result's ``warnings`` at WARNING level, marked :data:`RESULT_WARNING`.

    Parameters
    ----------
    logger : logging.Logger
        The library logger to use.
    warnings : tuple of str
        The result's warnings.
    """
    for warning in warnings:
        logger.warning("%s", warning, extra={RESULT_WARNING: True})


class ReconstructionError(RuntimeError):
    """A two-view (or multi-view) reconstruction could not be trusted.

    Attributes
    ----------
    reason : str
        Short machine-readable cause: ``"too_few_matches"``, ``"too_few_inliers"``,
        ``"no_parallax"``, ``"planar_scene"``, ``"no_cheirality_winner"``,
        ``"too_few_points"``; from dense matching ``"no_dense_range"``, ``"no_dense_points"``
        (the sparse result stands without it).
    counts : dict[str, int | float]
        The numbers behind the decision (matches, inliers, parallax, ...).
    message : str
        The sentence that says why, without the counts.
    """

    def __init__(self, reason: str, message: str, **counts: int | float) -> None:
        self.reason = reason
        self.counts = dict(counts)
        details = ", ".join(f"{k}={_fmt(v)}" for k, v in self.counts.items())
        super().__init__(f"{message} ({details})" if details else message)
        self.message = message

    def __reduce__(self) -> tuple:  # picklable, for tasks run in other processes
        return _rebuild_reconstruction_error, (self.reason, self.message, self.counts)


class CalibrationError(RuntimeError):
    """Camera calibration ran on readable data but failed (e.g. too few usable views).

    Attributes
    ----------
    reason : str
        Short machine-readable cause: ``"failed"``, or ``"corners_do_not_fit"`` when
        the result's RMS error is above the accepted limit (typically a wrong board).
    rms_px : float or None
        With ``"corners_do_not_fit"``: the RMS reprojection error that was refused.
    """

    def __init__(self, message: str, reason: str = "failed",
                 rms_px: float | None = None) -> None:
        self.reason = reason
        self.rms_px = rms_px
        super().__init__(message)

    def __reduce__(self) -> tuple:
        return type(self), (self.args[0], self.reason, self.rms_px)


class DatasetError(RuntimeError):
    """A dataset file is not available locally and could not be downloaded and verified."""


class EngineError(RuntimeError):
    """An execution engine could not run its tasks: a task was given up after the workers
    running it died too often, or the cluster went away (see :mod:`scene3D.engines`).

    Attributes
    ----------
    reason : str
        Short machine-readable cause: ``"scheduler_lost"``, ``"no_workers"`` (the cluster
        has had no worker for the engine's limit), ``"task_given_up"``, ``"task_cancelled"``,
        or ``"failed"``.
    """

    def __init__(self, message: str, reason: str = "failed") -> None:
        self.reason = reason
        super().__init__(message)

    def __reduce__(self) -> tuple:
        return type(self), (self.args[0], self.reason)


def _rebuild_reconstruction_error(reason: str, message: str, counts: dict
                                  ) -> ReconstructionError:
    return ReconstructionError(reason, message, **counts)


def _fmt(value: int | float) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)
