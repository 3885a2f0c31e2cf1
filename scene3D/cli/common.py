"""What every scene3D command shares: logging flags, exit codes, error reporting."""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from ..engines import Engine, LocalEngine, Progress
from ..errors import (
    RESULT_WARNING,
    CalibrationError,
    DatasetError,
    EngineError,
    ReconstructionError,
    first_line,
    plural,
)

if TYPE_CHECKING:
    import numpy as np

    from ..geometry.intrinsics_prior import FocalPrior

EXIT_OK = 0
EXIT_FAILED = 1  # valid input, but the reconstruction / calibration failed
EXIT_USAGE = 2  # bad usage or bad input

#: What a command adds to a library error that a flag avoids: ``(error type, reason) ->
#: suffix``. The library's messages name no flag (a notebook user typed none); the commands
#: print them with the flag that would have avoided the failure.
FLAG_HINTS: dict[tuple[type, str], str] = {
    (ReconstructionError, "no_dense_range"): " (run without --dense)",
    (ReconstructionError, "no_dense_points"): " (run without --dense)",
    (EngineError, "no_workers"): ", or run without --scheduler",
}


def with_flag_hint(exc: BaseException) -> str:
    """``str(exc)``, followed by the flag that avoids it (:data:`FLAG_HINTS`), if any."""
    reason = getattr(exc, "reason", None)
    hint = next((suffix for (kind, why), suffix in FLAG_HINTS.items()
                 if isinstance(exc, kind) and why == reason), "")
    return f"{exc}{hint}"


#: ``--workers`` takes at most this many worker processes per core of the machine.
MAX_WORKERS_PER_CORE = 4


def exit_codes_help(failed: str, success: str = "success") -> str:
    """The ``--help`` sentence on exit codes; ``failed`` says what exit code 1 means."""
    return f"Exit codes: 0 {success}; 1 {failed}; 2 bad usage or input"


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser, with a usage error in one line and exit code 2: ``error: argument
    --max-width: must be at least 1, got 0 (see chapter4.py --help)``, not the usage block
    first."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"error: {message} (see {self.prog} --help)\n")


class UsageError(Exception):
    """A command-line mistake the user can fix (exit code 2)."""


def path_arg(text: str) -> Path:
    """argparse type: a path, not empty (``Path("")`` would quietly be the current folder,
    as an unset shell variable gives) and valid UTF-8 (:func:`require_utf8`)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must name a file or folder, got ''")
    try:
        require_utf8(Path(text))
    except UsageError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return Path(text)


def require_utf8(path: Path) -> None:
    """Raise :class:`UsageError` when ``path`` is not valid UTF-8 (bytes of another
    system's encoding): OpenCV, JSON and the reports cannot carry its name."""
    from ..io.paths import utf8_name_problem  # OpenCV only when a path is given

    problem = utf8_name_problem(path)
    if problem:
        raise UsageError(problem)


def _number(text: str, kind: type, name: str) -> float:
    """``kind(text)`` (``int`` or ``float``), or argparse's error saying it must be ``name``."""
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {name}, got {text!r}") from None


def positive_float(text: str) -> float:
    """argparse type: a number > 0."""
    value = _number(text, float, "a number")
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def finite_positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = positive_float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def finite_non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0 (NaN, which every comparison fails, refused)."""
    value = _number(text, float, "a number")
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    value = _number(text, int, "a whole number")
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


def non_negative_int(text: str) -> int:
    """argparse type: a whole number >= 0."""
    value = _number(text, int, "a whole number")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text}")
    return value


def focal_sigma_text(focal_px: float, sigma_px: float) -> str:
    """A focal length's sigma as printed: ``+-1.4`` (px), or beyond a quarter in ``log f``
    a factor, ``(1 sigma: a factor of 2.7)`` (+-px would suggest a symmetric bound)."""
    sigma_log = sigma_px / focal_px
    return (f"+-{sigma_px:.1f}" if sigma_log <= 0.25
            else f"(1 sigma: a factor of {math.exp(sigma_log):.1f})")


def read_camera_prior(paths: list[Path]) -> FocalPrior:
    """:func:`scene3D.io.exif.read_camera_prior` for a command run without ``--calib``: photos
    of two cameras or zoom settings
    (:class:`~scene3D.geometry.intrinsics_prior.CameraMismatchError`) are a
    :class:`UsageError` that names ``--calib``, not the library's ``K``."""
    from ..geometry.intrinsics_prior import CameraMismatchError
    from ..io.exif import read_camera_prior as read_prior

    try:
        return read_prior(paths)
    except CameraMismatchError as exc:
        raise UsageError(f"{exc.problem}; or, if one calibration holds for them all, give it "
                         "with --calib FILE") from None


def read_camera_priors(paths: list[Path], mode: str) -> tuple[np.ndarray, list[FocalPrior]]:
    """:func:`scene3D.io.exif.read_camera_priors` for a command run without ``--calib``:
    with ``mode`` ``"single"``, photos of two cameras or zoom settings are a
    :class:`UsageError` that names ``--calib`` and ``--camera-mode``."""
    from ..geometry.intrinsics_prior import CameraMismatchError
    from ..io.exif import read_camera_priors as read_priors

    try:
        return read_priors(paths, mode)
    except CameraMismatchError as exc:
        raise UsageError(f"{exc.problem} with --camera-mode single; drop it to give each "
                         "camera its own focal length, or, if one calibration holds for "
                         "them all, give it with --calib FILE") from None


def check_image_paths(paths: list[Path]) -> None:
    """Raise :class:`UsageError` when a name is not valid UTF-8 (:func:`require_utf8`) or
    one file is given twice (a view cannot pair with itself): the same path, a symbolic
    link to it or a hard link (the same file on disk)."""
    seen: dict[object, Path] = {}
    for path in paths:
        require_utf8(path)
        try:
            stat = path.stat()
            key: object = (stat.st_dev, stat.st_ino)
        except OSError:  # missing: said where the file is read
            key = path.resolve()
        if key in seen:
            raise UsageError(f"image given twice: '{path}'"
                             + (f" (also as '{seen[key]}')" if str(seen[key]) != str(path) else ""))
        seen[key] = path


def check_report_viewer() -> None:
    """Raise :class:`UsageError` (before any work) when the report's 3D view cannot be
    made: plotly.js comes from the ``plotly`` package."""
    from ..report.viewer import MissingViewerError, plotly_js_path

    try:
        plotly_js_path()
    except MissingViewerError as exc:
        hint = ", or use --no-report" if exc.reason == "no_plotly" else ""
        raise UsageError(f"{exc}{hint}") from None


def add_common_args(parser: argparse.ArgumentParser,
                    quiet_stdout: str = "the files written") -> None:
    """``-v/--verbose``, ``-q/--quiet`` (keeping ``quiet_stdout`` on stdout) and
    ``--debug``."""
    group = parser.add_argument_group("output and diagnostics")
    group.add_argument("-v", "--verbose", action="count", default=0,
                       help="more log messages on stderr (-vv for debug)")
    group.add_argument("-q", "--quiet", action="store_true",
                       help=f"only errors on stderr, and on stdout only {quiet_stdout}")
    group.add_argument("--debug", action="store_true",
                       help="show the full traceback of an error")


def add_size_args(parser: argparse.ArgumentParser, default_width: int, note: str) -> None:
    """``--max-width PX`` or ``--no-pyr-down``: the working size of the images."""
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--max-width", type=positive_int, default=default_width, metavar="PX",
                      help=f"halve the images while wider than this, averaging 2x2 "
                           f"pixels (default {default_width}: {note})")
    size.add_argument("--no-pyr-down", action="store_true",
                      help="work at full resolution (slower, sometimes more accurate; "
                           "the name is the book's, which halves with cv2.pyrDown)")


_FEATURE_HELP = {
    "sift": "sift (default)",
    "surf": "surf (the book's; falls back to sift when OpenCV lacks it)",
    "orb": "orb",
    "akaze": "akaze",
    "flow": "flow (tracked corners)",
}


def add_feature_arg(parser: argparse.ArgumentParser, modes: list[str]) -> None:
    """``--feature``: one of ``modes`` (lower-case names of
    :data:`scene3D.features.FEATURE_MODES`), SIFT by default."""
    parser.add_argument("--feature", default="sift", type=str.lower, choices=modes,
                        help="features: " + ", ".join(_FEATURE_HELP.get(m, m) for m in modes))


def add_bundle_adjust_arg(parser: argparse.ArgumentParser) -> None:
    """``--bundle-adjust``: finish the two-view pose with a bundle adjustment."""
    parser.add_argument("--bundle-adjust", action="store_true",
                        help="finish with a two-view bundle adjustment of pose and points "
                             "(70-160 ms more a pair; on our benchmark no more accurate than "
                             "the default refinement)")


def add_engine_args(parser: argparse.ArgumentParser,
                    tasks: str = "features per image, pairs") -> None:
    """``--scheduler ADDRESS`` or ``--workers N``: where the independent tasks run
    (built by :func:`open_engine`); ``tasks`` names them in the help."""
    group = parser.add_argument_group(
        f"where the tasks run ({tasks}; default: in this process)")
    where = group.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="on the workers of a running Dask cluster, such as "
                            "tcp://10.0.0.5:8786 ('dask scheduler', then 'dask worker "
                            "ADDRESS' on each machine); needs the extra 'distributed'")
    where.add_argument("--workers", type=positive_int, metavar="N",
                       help="on N worker processes started on this machine (a Dask "
                            "LocalCluster, one thread each); needs the extra 'distributed'")
    # git's --progress: lines on a terminal by default, forced for a log or a pipe.
    group.add_argument("--progress", action="store_true",
                       help="progress lines on stderr even when it is not a terminal "
                            "(a log file, a pipe); -q still silences them")


class _Reporting:
    """An engine whose tasks report their progress (``StderrProgress``) unless a caller
    passes its own ``progress``: the pipelines map without one."""

    def __init__(self, engine: Engine, progress: Progress) -> None:
        self._engine, self._progress = engine, progress
        self.name = engine.name

    def map(self, fn: Callable[..., Any], arguments: Iterable[tuple], *, label: str = "tasks",
            progress: Progress | None = None) -> Iterator[Any]:
        if progress is not None:
            return self._engine.map(fn, arguments, label=label, progress=progress)
        # The engines report only finished tasks; "0 of N" when the map starts sets the
        # clock, or the time so far and the time left would leave out the first task's.
        arguments = list(arguments)
        if arguments:
            self._progress(label, 0, len(arguments))
        return self._engine.map(fn, arguments, label=label, progress=self._progress)

    def share(self, value: Any) -> Any:
        return self._engine.share(value)


@contextmanager
def open_engine(args: argparse.Namespace) -> Iterator[Engine]:
    """The engine that ``--scheduler`` / ``--workers`` ask for (in this process without
    either), its tasks' progress on stderr (``StderrProgress``: on a terminal or with
    ``--progress``, not with ``-q``),
    closed (with the workers it started) when the block ends.

    Raises :class:`UsageError` in one line when Dask is not installed.
    """
    scheduler, workers = getattr(args, "scheduler", None), getattr(args, "workers", None)
    progress = StderrProgress(not args.quiet,
                              terminal=True if getattr(args, "progress", False) else None)
    if scheduler is None and workers is None:
        yield _Reporting(LocalEngine(), progress)
        return
    from ..engines.dask_engine import (
        INSTALL_HINT,
        DaskEngine,
        MissingExtraError,
        require_distributed,
    )

    option = "--scheduler" if scheduler is not None else "--workers"
    cores = os.cpu_count() or 1
    if workers is not None and workers > MAX_WORKERS_PER_CORE * cores:
        raise UsageError(f"--workers {workers}: this machine has {cores} cores, and local "
                         f"workers beyond {MAX_WORKERS_PER_CORE * cores} only wait for them "
                         "(--scheduler runs the tasks on a cluster)")
    try:
        require_distributed()
    except MissingExtraError:
        raise UsageError(f"{option} needs Dask: {INSTALL_HINT}") from None
    # Dask's own log (its handler, its format): warnings, its INFO lines with -vv.
    logging.getLogger("distributed").setLevel(
        logging.ERROR if args.quiet else logging.INFO if args.verbose >= 2 else logging.WARNING)
    engine = DaskEngine.connect(scheduler) if scheduler is not None else \
        DaskEngine.local(workers)
    log = logging.getLogger("scene3D.cli")
    try:
        if not args.quiet:
            print(f"tasks on {engine.describe()}", file=sys.stderr)
        yield _Reporting(engine, progress)
        task_counts = engine.task_counts()
        for worker, counts in sorted(task_counts.items()):
            log.info("worker %s ran %s", worker, ran_tasks(counts))
        gone = engine.submitted.total() - sum(sum(c.values()) for c in task_counts.values())
        if gone > 0:
            log.info("%s finished on workers that have since left (their counts went "
                     "with them)", plural(gone, "task"))
    finally:
        engine.close()


class StderrProgress:
    """``progress(label, done, total)`` for :meth:`scene3D.engines.Engine.map`: lines such
    as "pairs: 12 of 40 done, 3.1 s so far, about 7.2 s left" on stderr, at most one a
    ``interval_s`` per label, and the last one ("pairs: 40 of 40 done in 10.4 s") always.

    Quiet when stderr is not a terminal (a log file, a pipe, a test's capture), as tqdm's
    ``disable=None`` and git are; ``terminal=True`` (the command's ``--progress``, after
    git's flag of that name) writes the lines anyway, ``terminal=False`` never. Silent when
    ``enabled`` is False (``-q``), whatever ``terminal`` says. The time left assumes the
    remaining tasks take as long as the finished ones did on average.
    """

    def __init__(self, enabled: bool = True, interval_s: float = 1.0,
                 terminal: bool | None = None) -> None:
        self.enabled, self.interval_s, self.terminal = enabled, interval_s, terminal
        self._last: dict[str, float] = {}
        self._start: dict[str, float] = {}

    def __call__(self, label: str, done: int, total: int) -> None:
        now = time.monotonic()
        start = self._start.setdefault(label, now)
        if done >= total:
            self._start.pop(label)  # a later map with the same label starts its own clock
        if not self.enabled:
            return
        terminal = sys.stderr.isatty() if self.terminal is None else self.terminal
        if not terminal or (done < total and
                            now - self._last.get(label, -1e9) < self.interval_s):
            return
        self._last[label] = now
        elapsed = now - start
        if done >= total:
            line = f"{label}: {done} of {total} done in {duration_text(elapsed)}"
        elif done > 0:
            left = elapsed / done * (total - done)
            line = (f"{label}: {done} of {total} done, {duration_text(elapsed)} so far, "
                    f"about {duration_text(left)} left")
        else:
            line = f"{label}: 0 of {total} done"
        print(line, file=sys.stderr, flush=True)


def duration_text(seconds: float) -> str:
    """'0.4 s', '12 s', '3 min 05 s', '1 h 02 min' (a duration for a progress line).

    Parameters
    ----------
    seconds : float
        Non-negative.

    Returns
    -------
    str
    """
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, secs = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


class _StderrHandler(logging.StreamHandler):
    """Writes to ``sys.stderr`` as it is when a record comes (a test's capture, a
    notebook's stream), not as it was when the command started."""

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


@contextmanager
def command_logging(args: argparse.Namespace) -> Iterator[None]:
    """The command's logging (``-q``, ``-v``, ``--debug``) on stderr while it runs; the
    root logger's handlers and level as they were afterwards (a command run in-process,
    from a notebook or a test, leaves the caller's logging alone)."""
    if args.quiet:
        level = logging.ERROR
    elif args.verbose >= 2 or args.debug:
        level = logging.DEBUG
    elif args.verbose == 1:
        level = logging.INFO
    else:
        level = logging.WARNING
    handler = _StderrHandler()
    handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    # The commands print a result's warnings with the result (stdout, the table).
    handler.addFilter(lambda record: not getattr(record, RESULT_WARNING, False))
    root = logging.getLogger()
    saved_handlers, saved_level = root.handlers[:], root.level
    root.handlers[:] = [handler]
    root.setLevel(level)
    try:
        yield
    finally:
        root.handlers[:] = saved_handlers
        root.setLevel(saved_level)


def require_parent_folder(path: Path, option: str) -> None:
    """Raise ``UsageError`` unless the folder that file ``path`` (given as ``option``) goes
    into exists, naming a file that stands in its way."""
    parent = path.parent
    if not parent.is_dir():
        what = "is a file, not a folder" if parent.exists() else "does not exist"
        raise UsageError(f"{option} '{path}': '{parent}' {what}")


def require_writable_folder(folder: Path, what: str) -> None:
    """Raise :class:`UsageError` ``"{what}: {reason}"`` unless a file can be created in
    ``folder``: a read-only folder or file system fails here, before the work, not when
    the results are written (a file is created and removed; root may write where the
    permissions say no, so they are not asked)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".scene3d-write-test-", dir=folder)
    except OSError as exc:
        raise UsageError(f"{what}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)


#: The folders the running command created for its outputs (``note_created_folders``).
_created_folders: ContextVar[list[Path] | None] = ContextVar("scene3d_created_folders",
                                                            default=None)


def note_created_folders(folders: Iterable[Path]) -> None:
    """Record folders the running command created: removed again, if still empty, when it
    fails (a failed run leaves no empty ``--out`` behind)."""
    created = _created_folders.get()
    if created is not None:
        created.extend(folders)


def run_command(args: argparse.Namespace, body: Callable[[argparse.Namespace], int]) -> int:
    """Run ``body(args)`` and turn exceptions into one-line errors and exit codes."""
    created: list[Path] = []
    token = _created_folders.set(created)
    code = EXIT_FAILED  # an exception that escapes (a bug: its traceback shows) too
    try:
        with command_logging(args):
            code = _exit_code(args, body)
    finally:
        _created_folders.reset(token)
        if code != EXIT_OK:
            remove_empty_folders(created)
    return code


def ran_tasks(counts: dict[str, int]) -> str:
    """What a worker ran, for ``-v``: ``"1 features task, 43 pairs tasks"`` (by label),
    or ``"no tasks"``."""
    return ", ".join(plural(n, f"{label} task")
                     for label, n in sorted(counts.items())) or "no tasks"


def remove_empty_folders(folders: Iterable[Path]) -> None:
    """Remove those of ``folders`` that are empty, deepest first (a folder emptied by
    removing its subfolder goes too); a folder that is not empty, or a link, stays."""
    for folder in sorted(set(folders), key=lambda p: len(p.parts), reverse=True):
        try:
            folder.rmdir()
        except OSError:
            pass


def _exit_code(args: argparse.Namespace, body: Callable[[argparse.Namespace], int]) -> int:
    try:
        return body(args)
    except BrokenPipeError:  # stdout closed under the command: not an input error
        raise                # (scene3D.cli.run_script ends the process quietly)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except (ReconstructionError, CalibrationError, EngineError) as exc:
        if args.debug:
            raise
        print(f"error: {with_flag_hint(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except (UsageError, DatasetError, FileNotFoundError, FileExistsError, ValueError,
            OSError) as exc:
        if args.debug:
            raise
        print(f"error: {_message(exc)}", file=sys.stderr)
        return EXIT_USAGE


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.filename and exc.strerror:
        return f"{exc.strerror}: '{exc.filename}'"
    return first_line(exc)


def display_available() -> bool:
    """True when a window can be opened (an X11/Wayland display, or macOS/Windows)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def show_images(paths: list[Path]) -> None:
    """Open the written PNGs in windows (``--show``); warn when there is no display."""
    log = logging.getLogger("scene3D.cli")
    if not display_available():
        log.warning("--show: no display available; the figures are in the written PNG files")
        return
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    for path in paths:
        fig = plt.figure(path.name)
        fig.gca().imshow(mpimg.imread(path))
        fig.gca().set_axis_off()
    plt.show()
