"""Which files are images: those of a folder (by their endings, hidden names left out)
and those a glob matches.

:mod:`scene3D.io.paths` expands lists of folders, globs and files with these.
"""

from __future__ import annotations

import glob
import os
from pathlib import Path

#: File endings taken as images when a folder is given (HEIC/HEIF need ``pillow-heif``).
IMAGE_SUFFIXES = frozenset({".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".pgm",
                            ".ppm", ".heic", ".heif"})


def is_folder_image(path: Path) -> bool:
    """Whether a file found in a folder is taken as an image: its ending is one of
    :data:`IMAGE_SUFFIXES` and it is not hidden (a name starting with '.', such as the
    ``._IMG_0001.jpg`` files macOS leaves on other disks).

    Parameters
    ----------
    path : Path
        A file.

    Returns
    -------
    bool
    """
    return path.suffix.lower() in IMAGE_SUFFIXES and not path.name.startswith(".")


def folder_images(folder: Path) -> list[Path]:
    """The images of ``folder`` (:func:`is_folder_image`), sorted.

    Parameters
    ----------
    folder : Path
        A folder.

    Returns
    -------
    list of Path
    """
    return sorted(p for p in Path(folder).iterdir() if is_folder_image(p))


def glob_patterns(spec: str) -> list[str]:
    """The patterns a glob ``spec`` is read as: itself, then, when its folder part exists
    as written (``'photos [2024]/*.jpg'``, whose brackets a glob reads as a set of
    characters), the same with that folder taken literally (:func:`glob.escape`).

    Parameters
    ----------
    spec : str
        A glob pattern.

    Returns
    -------
    list of str
    """
    head, tail = os.path.split(spec)
    if head and glob.has_magic(head) and os.path.isdir(head):
        return [spec, os.path.join(glob.escape(head), tail)]
    return [spec]


def glob_files(spec: str) -> list[Path]:
    """The files a glob ``spec`` matches, sorted, by the first of :func:`glob_patterns`
    that matches any.

    Parameters
    ----------
    spec : str
        A glob pattern.

    Returns
    -------
    list of Path
    """
    for pattern in glob_patterns(spec):
        files = sorted(Path(p) for p in glob.glob(pattern) if Path(p).is_file())
        if files:
            return files
    return []

