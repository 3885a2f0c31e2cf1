"""The ``scene3d`` command: ``scene3d reconstruct|calibrate|evaluate|reconstruct-views|report
|dense-views|export ...``."""

from __future__ import annotations

import gc
import os
import sys
from collections.abc import Callable
from typing import NoReturn

from .. import __version__
from ..memory import keep_freed_memory

# Before numpy loads: OpenBLAS's worker threads otherwise spin for about 0.1 s after
# numpy starts (and after each BLAS call), taking one of the cores that OpenCV's
# parallel decoding and SIFT need. With a short timeout they sleep at once; BLAS stays
# multi-threaded. A value the user has set is kept.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")
# Before cv2 loads: OpenCV's and FFmpeg's own warnings ("[ WARN:0@0.169] global
# cap_v4l.cpp:915 open VIDEOIO(V4L2:/dev/video0): can't open camera by index", "moov atom
# not found") would come before the command's one-line error, which says the same for the
# user. Errors stay; values the user has set are kept.
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

COMMANDS = {
    "reconstruct": "reconstruct a scene from two photos (chapter4.py)",
    "calibrate": "calibrate a camera from chessboard, ChArUco or circle-grid views (calibrate.py)",
    "evaluate": "compare two-view poses with a Strecha-format ground truth",
    "reconstruct-views": "incremental SfM over many photos, with bundle adjustment",
    "report": "the self-contained HTML report of a COLMAP model (text or binary)",
    "dense-views": "a dense cloud (and a mesh) from a sparse model and its photos",
    "export": "a COLMAP model as nerfstudio's transforms.json (NeRF, splatting)",
}

USAGE = "usage: scene3d {" + ",".join(COMMANDS) + "} [options]   (scene3d COMMAND --help)"


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``scene3d COMMAND ...`` to the command's own ``main``."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] in ("-h", "--help"):
        text = USAGE + "\n\ncommands:\n" + "\n".join(f"  {k:<18} {v}"
                                                      for k, v in COMMANDS.items())
        print(text, file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    if argv[0] == "--version":
        print(f"scene3d {__version__}")
        return 0
    command, rest = argv[0], argv[1:]
    if command == "reconstruct":
        from .chapter4 import main as run
    elif command == "calibrate":
        from .calibrate import main as run
    elif command == "evaluate":
        from .evaluate import main as run
    elif command == "reconstruct-views":
        # Before numpy loads: bundle adjustment's matrices are small (a Schur complement
        # of 6 numbers a camera), and OpenBLAS's threads wait on each other when a core is
        # shared: ten times the time on a busy machine, level on a quiet one
        # (docs/benchmarks.md#one-blas-thread-for-the-adjustment). A value the user has set
        # is kept.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
        from .multiview import main as run
    elif command == "report":
        from .report import main as run
    elif command == "dense-views":
        from .dense_views import main as run
    elif command == "export":
        from .export import main as run
    else:
        print(f"{USAGE}\nerror: unknown command {command!r}", file=sys.stderr)
        return 2
    try:
        return run(rest, prog=f"scene3d {command}")
    except SystemExit as exc:  # argparse's usage errors and --help
        return int(exc.code or 0)


def exit_process(code: int) -> NoReturn:
    """End a command-line process with exit status ``code``, leaving its objects to the
    operating system.

    Python's shutdown otherwise runs full garbage collections over every object the run
    imported or made (about 32 000 after ``chapter4.py``: numpy, OpenCV's bindings,
    scene3D) only to free memory the exit returns anyway, which doubled the time a
    ``chapter4.py --no-plots`` run took to end (docs/benchmarks.md#whole-process-speed).
    :func:`gc.freeze` takes them out of the collector's sight; ``atexit`` handlers and
    the flushing of open files still run. For the scripts' entry points only: in a
    process that goes on (``main`` called from Python), frozen objects are never
    collected.
    """
    gc.freeze()
    sys.exit(code)


#: The exit status of a command whose stdout was closed under it (``scene3d --help |
#: head -1``): 128 + SIGPIPE, what the shell reports for a program a closed pipe ends.
EXIT_STDOUT_CLOSED = 141


def run_script(command: Callable[[], int]) -> NoReturn:
    """A script's whole process: ``command`` (a command's ``main``) with freed memory kept
    for reuse (:func:`scene3D.memory.keep_freed_memory`, docs/cli.md, memory), then
    :func:`exit_process` with its exit status.

    A closed stdout (the reader of a pipe gone, as ``head`` goes after its lines) ends the
    command quietly with :data:`EXIT_STDOUT_CLOSED`, not a traceback: stdout is flushed
    here, so that the closed pipe shows before Python's exit, and then pointed at
    ``os.devnull``, so that the exit's own flush does not fail again (Python's documented
    way, "Note on SIGPIPE" in the ``signal`` module).
    """
    keep_freed_memory()
    try:
        code = command()
        sys.stdout.flush()
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = EXIT_STDOUT_CLOSED
    exit_process(code)


def console_main() -> NoReturn:
    """The ``scene3d`` console script: :func:`main` in a process of its own."""
    run_script(main)
