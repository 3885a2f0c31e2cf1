"""Paths given by the user: the images that files, folders and globs name, which files a
folder or a glob lists, and names that cannot travel.

The folders and globs themselves are read by :func:`scene3D.io.images.folder_images` and
:func:`scene3D.io.images.glob_files`; this module expands a list of them
(:func:`image_files`), says whether one of them would list a given file (an output about
to be written among the inputs, :func:`lists_file`) and whether a name can be carried by
OpenCV, JSON and the reports (:func:`utf8_name_problem`).
"""

from __future__ import annotations

import fnmatch
import os
from collections.abc import Sequence
from pathlib import Path

from .images import IMAGE_SUFFIXES, folder_images, glob_files, glob_patterns, is_folder_image


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


def image_files(specs: Sequence[str]) -> list[Path]:
    """The images that files, folders and globs name, in the order given.

    A folder gives its images (:func:`scene3D.io.images.folder_images`: sorted, hidden
    names starting with '.', such as macOS's ``._IMG.jpg``, left out), a glob the files it
    matches (sorted), a file itself.

    Parameters
    ----------
    specs : sequence of str
        Files, folders or globs such as ``"photos/*.jpg"``.

    Returns
    -------
    list of Path
        Perhaps with a file twice (the caller decides).

    Raises
    ------
    FileNotFoundError
        A spec that is neither a file nor a folder and matches nothing: the message names
        the missing folder or image (the first missing folder on the way, as an unset
        variable in ``$DATA/images`` leaves), else the glob.
    """
    paths: list[Path] = []
    for spec in specs:
        p = Path(spec)
        if p.is_dir():
            paths += folder_images(p)
        elif p.is_file():
            paths.append(p)
        else:
            matched = glob_files(spec)
            if not matched:
                raise FileNotFoundError(_nothing_at(spec))
            paths += matched
    return paths


def _nothing_at(spec: str) -> str:
    """Why ``spec`` (neither a file nor a folder) gives no image: a missing folder or image
    named as such (with the first missing folder on the way, as an unset variable in
    ``$DATA/images`` leaves), else a glob that matches nothing."""

    def missing(path: Path) -> str:
        first = next((a for a in reversed(path.parents) if not a.exists()), path)
        return f" ('{first}' does not exist)" if first != path else ""

    def is_glob(text: str) -> bool:  # as glob.has_magic
        return any(c in text for c in "*?[")

    path = Path(spec)
    if not is_glob(spec):
        what = "image" if path.suffix.lower() in IMAGE_SUFFIXES else "folder"
        return f"{what} not found: '{spec}'{missing(path)}"
    folder = path.parent
    if not is_glob(str(folder)) and not folder.is_dir():
        return f"no image matches '{spec}': folder not found: '{folder}'{missing(folder)}"
    return f"no image matches '{spec}'"
