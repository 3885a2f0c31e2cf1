"""The ``--out`` folder of ``reconstruct`` and ``reconstruct-views`` (and the record
of calibrate's ``--save-undistorted`` folder, :func:`previous_outputs`).

A run creates the folder (removed again if the run fails and leaves it empty), refuses
a ``reconstruction.json`` there that scene3D did not write, lists the files it writes
in its own ``reconstruction.json`` (``"files"``, relative to the folder), and, once its
files are in place, removes those of the previous run it did not write again: a
report.html after ``--no-report``, a model-2/ when fewer models came out. Nothing else in
the folder is touched: a file a run would write that is already there and is no earlier
run's output (nor listed by one), or that is one of the run's inputs, is refused, not
replaced.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Iterable
from pathlib import Path, PurePosixPath

from .common import UsageError, note_created_folders, remove_empty_folders

logger = logging.getLogger(__name__)

SUMMARY_FILE = "reconstruction.json"
#: The summary's key for the files a run wrote, relative to ``--out``, '/'-separated.
FILES_KEY = "files"
#: A key every summary scene3D has written holds (also before ``FILES_KEY`` existed).
_OWN_SUMMARY_KEY = "conventions"


def out_help(default: str) -> str:
    """``--out``'s help text, the same for both commands."""
    return (f"output folder (default: {default}); a successful run replaces an earlier "
            "run's files there and removes those it does not write again (as listed in "
            "that run's reconstruction.json); anything else in the folder is kept, and "
            "a run that would replace a file no earlier run wrote, or one of its inputs, "
            "stops before any work (exit code 2)")


def prepare_output_dir(path: Path) -> Path:
    """Create ``path`` (and parents) or raise ``UsageError`` naming why it cannot be used.

    The folders created are noted (:func:`~scene3D.cli.common.note_created_folders`) one
    by one as ``mkdir`` makes them, so that a failed run removes those and no other
    (``new/../old`` creates ``new`` only).
    """
    if path.exists() and not path.is_dir():
        raise UsageError(f"--out '{path}' exists and is not a folder")
    for folder in (*reversed(path.parents), path):
        if folder.exists():
            continue
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise UsageError(f"cannot create output folder '{path}': {exc.strerror}") from exc
        note_created_folders([folder])
    if not os.access(path, os.W_OK | os.X_OK):
        raise UsageError(f"output folder '{path}' is not writable")
    return path


def previous_outputs(out: Path, summary_file: str = SUMMARY_FILE,
                     own_key: str = _OWN_SUMMARY_KEY, option: str = "--out") -> list[Path]:
    """The files the previous run in ``out`` recorded in its summary (none without one):
    the ``FILES_KEY`` list of ``out / summary_file``, a JSON object that holds ``own_key``.

    Raises ``UsageError`` when ``out`` holds a ``summary_file`` that scene3D did not
    write (the error names the command's ``option``): it would be replaced.
    """
    summary = out / summary_file
    if not summary.is_file():
        return []
    try:
        text = summary.read_bytes()
    except OSError as exc:
        raise UsageError(f"cannot read '{summary}' (of an earlier run?): "
                         f"{exc.strerror or exc}") from None
    try:
        recorded = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        recorded = None
    if not isinstance(recorded, dict) or own_key not in recorded:
        raise UsageError(f"'{summary}' was not written by scene3D and would be replaced; "
                         f"choose another {option}")
    files = recorded.get(FILES_KEY)
    if not isinstance(files, list):
        return []
    return [out / name for name in files if isinstance(name, str) and _within(name)]


def _within(name: str) -> bool:
    """Whether a recorded name stays inside the folder (relative, no '..')."""
    path = PurePosixPath(name)
    return bool(name) and not path.is_absolute() and ".." not in path.parts \
        and "\\" not in name


def recorded_files(out: Path, paths: list[Path]) -> list[str]:
    """``paths`` inside ``out`` as the summary records them: relative, '/'-separated."""
    return sorted({path.relative_to(out).as_posix() for path in paths})


def remove_stale_outputs(out: Path, previous: list[Path], written: list[Path]) -> list[Path]:
    """Remove the previous run's files this run did not write, then the folders of theirs
    left empty; return the files removed. A file reached through a link, or that is one
    of ``written`` under another spelling (a case-insensitive disk), stays; one that
    cannot be removed is named in a warning."""
    kept = {_file_id(path) for path in written} - {None}
    inside = out.resolve()
    removed = []
    for path in previous:
        if path in written or not path.is_file() or _file_id(path) in kept:
            continue
        if path.resolve() != inside / path.relative_to(out):  # a link on the way
            continue
        try:
            path.unlink()
        except OSError as exc:
            logger.warning("could not remove '%s' of an earlier run: %s", path,
                           exc.strerror or exc)
            continue
        removed.append(path)
    # Their folders left empty (not those holding this run's files or the user's).
    remove_empty_folders(parent for path in previous for parent in path.parents
                         if parent != out and out in parent.parents)
    return removed


def _file_id(path: Path) -> tuple[int, int] | None:
    """The (device, inode) of a file, None when it is missing."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return stat.st_dev, stat.st_ino


class OutputFolder:
    """A run's ``--out``: created and checked on construction (:func:`prepare_output_dir`,
    :func:`previous_outputs`); :meth:`check_free` refuses to replace a file that is not
    the previous run's, :meth:`record` lists the run's files for its summary (checking
    them so) and :meth:`remove_stale` clears what the previous run left that this one did
    not write. ``inputs`` are the run's photos and calibration: never written over.
    ``names`` are glob patterns, relative to the folder, of every file the command may
    write (``model-*/points.ply``): with a summary from before the file list (2026-12-03),
    the files that match them are taken to be that run's."""

    def __init__(self, path: Path, inputs: Iterable[Path] = (), names: Iterable[str] = ()
                 ) -> None:
        self.path = prepare_output_dir(path)
        self.names = tuple(names)
        self.previous = previous_outputs(self.path)
        if not self.previous and (self.path / SUMMARY_FILE).is_file():
            self.previous = self.matching()  # scene3D's summary, without the file list
        self.inputs = {_file_id(p) for p in inputs} - {None}

    def matching(self) -> list[Path]:
        """The files in the folder that ``names`` match: those the command may write."""
        return sorted({found for pattern in self.names for found in self.path.glob(pattern)
                       if found.is_file()})

    def check_free(self, paths: Iterable[Path]) -> None:
        """Raise :class:`UsageError` when one of ``paths`` (files this run is to write)
        is one of the run's inputs, or is there already and the previous run did not
        write it (a file of the user's, which would be replaced)."""
        previous = {_file_id(p) for p in self.previous} - {None}
        for path in paths:
            found = _file_id(path)
            if found is None or not path.is_file():  # a folder there: the writer says so
                continue
            if found in self.inputs:
                raise UsageError(f"--out '{self.path}': the run would write '{path}', one "
                                 "of its inputs; choose another folder for the outputs")
            if found not in previous:
                raise UsageError(f"--out '{self.path}' holds '{path}', which no earlier "
                                 "scene3D run there wrote, and the run would replace it; "
                                 "move it or choose another --out")

    def record(self, paths: list[Path]) -> list[str]:
        """The summary's ``FILES_KEY`` entry for ``paths`` (:func:`recorded_files`), once
        :meth:`check_free` has passed them: call it before the files are put in place."""
        self.check_free(paths)
        return recorded_files(self.path, paths)

    def remove_stale(self, written: list[Path]) -> list[Path]:
        """:func:`remove_stale_outputs` once the run's files are in place; the files
        removed."""
        return remove_stale_outputs(self.path, self.previous, written)


def remove_earlier_files(paths: list[Path]) -> list[Path]:
    """Remove ``paths``, an earlier run's files this one did not write again, once the new
    files are in place; return those removed. One that cannot be removed is named in a
    warning."""
    removed = []
    for path in paths:
        try:
            path.unlink()
        except FileNotFoundError:
            continue
        except OSError as exc:
            logger.warning("could not remove '%s' of an earlier run: %s", path,
                           exc.strerror or exc)
            continue
        removed.append(path)
    return removed
