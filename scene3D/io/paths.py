"""Paths given by the user: which files a folder or a glob lists, and names that cannot travel.

The folders and globs themselves are read by :func:`scene3D.io.images.folder_images` and
:func:`scene3D.io.images.glob_files`; this module says whether one of them would list a
given file (an output about to be written among the inputs) and whether a name can be
carried by OpenCV, JSON and the reports.
"""

from __future__ import annotations

import fnmatch
import os
from pathlib import Path

from .images import glob_patterns, is_folder_image


def lists_file(spec: str, path: Path) -> bool:
    """Whether the folder or glob ``spec`` would list the file ``path`` as an image.

    A folder lists its images (:func:`is_folder_image`); a glob matches component by
    component, as :mod:`glob` does (``*`` does not reach across a '/'), by any of its
    :func:`glob_patterns`. ``path`` need not exist (an output about to be written).

    Parameters
    ----------
    spec : str
        A folder, or a glob such as ``"photos/*.jpg"``.
    path : Path

    Returns
    -------
    bool
    """
    if Path(spec).is_dir():
        return path.parent.resolve() == Path(spec).resolve() and is_folder_image(path)
    return any(_glob_matches(name, pattern)
               for glob_pattern in glob_patterns(spec)
               for name, pattern in (
                   (os.path.normpath(path), os.path.normpath(glob_pattern)),
                   (os.path.abspath(path), os.path.abspath(glob_pattern))))


def _glob_matches(name: str, pattern: str) -> bool:
    """Whether glob ``pattern`` matches the path ``name``, component by component (as
    ``glob`` does: ``*`` does not reach across a '/', unlike ``fnmatch`` on whole paths)."""
    names, patterns = Path(name).parts, Path(pattern).parts
    return len(names) == len(patterns) and all(
        fnmatch.fnmatch(n, q) for n, q in zip(names, patterns))


def utf8_name_problem(path: str | os.PathLike) -> str:
    """Why ``path`` cannot be carried by OpenCV, JSON and the reports, or ``''``.

    Parameters
    ----------
    path : path

    Returns
    -------
    str
        ``''``, or the sentence saying that the name is not valid UTF-8 (bytes of another
        system's encoding).
    """
    try:
        os.fspath(path).encode("utf-8")
    except UnicodeEncodeError:
        return (f"the name {os.fspath(path)!r} is not valid UTF-8 (from another system?): "
                "rename it")
    return ""
