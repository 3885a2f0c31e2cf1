"""HEIC/HEIF photos (as iPhones take them), which OpenCV cannot decode: recognised by their
first bytes and read with Pillow and ``pillow-heif`` (the ``heic`` extra), their pixels in
the sensor's layout as a JPEG's are (:func:`scene3D.io.images.read_image`).
"""

from __future__ import annotations

import io
import os

import numpy as np

from ..errors import first_line

#: Major brands of the ISO media file box ("ftyp") of HEIC/HEIF photos (as iPhones take
#: them), which OpenCV cannot decode (AVIF, another brand of that container, it can).
_HEIF_BRANDS = {b"heic", b"heix", b"heim", b"heis", b"hevc", b"hevx", b"mif1", b"msf1"}


#: Brands of that container that mark AV1 images (AVIF), which OpenCV decodes itself.
_AVIF_BRANDS = {b"avif", b"avis"}


def is_heif(head: bytes | np.ndarray) -> bool:
    """Whether the first bytes of a file are those of a HEIC/HEIF photo: an ISO media
    ``ftyp`` box naming a HEIF brand and no AVIF one (an AVIF file may name ``mif1``
    first and ``avif`` among its compatible brands).

    Parameters
    ----------
    head : bytes or uint8 ndarray
        The file's first bytes (64 suffice).

    Returns
    -------
    bool
    """
    head = bytes(memoryview(head).cast("B")[:64])
    if head[4:8] != b"ftyp":
        return False
    end = min(int.from_bytes(head[:4], "big"), len(head))
    brands = {head[8:12]} | {head[i:i + 4] for i in range(16, end - 3, 4)}
    return head[8:12] in _HEIF_BRANDS and not brands & _AVIF_BRANDS


def register_heif_opener() -> bool:
    """Let Pillow open HEIC/HEIF files; False when ``pillow-heif`` is not installed."""
    try:
        from pillow_heif import register_heif_opener as register
    except ImportError:
        return False
    register()
    return True


def require_heif_opener(path: str | os.PathLike) -> None:
    """:func:`register_heif_opener`, or a ``ValueError`` naming ``path`` and how to get
    ``pillow-heif``.

    Parameters
    ----------
    path : path
        The HEIC/HEIF file, for the message.

    Raises
    ------
    ValueError
        ``pillow-heif`` is not installed.
    """
    if not register_heif_opener():
        raise ValueError(f"cannot read image '{path}': a HEIC/HEIF photo, which needs "
                         "pillow-heif (pip install 'scene3D[heic]'), or convert it to JPEG "
                         "(heif-convert, or export as JPEG from the photo app)")


def _damaged_heif(path: str | os.PathLike, exc: Exception) -> ValueError:
    """The error for a HEIC/HEIF file libheif cannot read, with its reason."""
    return ValueError(f"cannot read image '{path}': a damaged HEIC/HEIF file "
                      f"({first_line(exc)})")


#: How to undo each EXIF orientation (1-8) on an (H, W, ...) array: what libheif applied
#: to the stored pixels to show them (2, 4, 5, 7 mirror; 3, 6, 8 turn).
_UNDO_ORIENTATION = {
    2: lambda a: a[:, ::-1], 3: lambda a: a[::-1, ::-1], 4: lambda a: a[::-1],
    5: lambda a: a.swapaxes(0, 1), 6: lambda a: np.rot90(a, 1),
    7: lambda a: a[::-1, ::-1].swapaxes(0, 1), 8: lambda a: np.rot90(a, -1),
}


def _open_heif(source, path: str | os.PathLike):
    """The Pillow image of a HEIC/HEIF file (``source``: its path or a file object) and
    the EXIF orientation libheif applied."""
    from PIL import Image

    require_heif_opener(path)
    try:
        img = Image.open(source)
        img.size  # noqa: B018 - the header is read here
    except Exception as exc:  # noqa: BLE001 - libheif's errors come as several types
        raise _damaged_heif(path, exc) from None
    return img, img.info.get("original_orientation") or 1


def decode_heif(data: np.ndarray, path: str | os.PathLike) -> np.ndarray:
    """A HEIC/HEIF photo's primary image as stored, BGR ``uint8`` (grey ``(H, W)``),
    alpha dropped. libheif turns the pixels as the file says they are shown; the
    turn its EXIF orientation records is undone, so that a portrait photo's pixels keep
    the sensor's layout as a JPEG's do (:func:`scene3D.io.images.read_image`).

    Parameters
    ----------
    data : (n,) uint8
        The file's bytes.
    path : path
        The file, for messages.

    Returns
    -------
    (H, W, 3) or (H, W) uint8

    Raises
    ------
    ValueError
        ``pillow-heif`` is not installed, or libheif cannot read the file.
    """
    img, orientation = _open_heif(io.BytesIO(data.tobytes()), path)
    try:
        with img:
            grey = img.mode in ("L", "I;16", "I")
            pixels = np.asarray(img.convert("L" if grey else "RGB"))
    except Exception as exc:  # noqa: BLE001 - as in _open_heif
        raise _damaged_heif(path, exc) from None
    if not grey:
        pixels = pixels[:, :, ::-1]  # RGB -> BGR
    undo = _UNDO_ORIENTATION.get(orientation)
    return np.ascontiguousarray(undo(pixels) if undo else pixels)


def heif_size(path: str | os.PathLike) -> tuple[int, int]:
    """``(width, height)`` of a HEIC/HEIF photo as stored, from its header.

    Parameters
    ----------
    path : path

    Returns
    -------
    tuple[int, int]
        As :func:`decode_heif` would give its pixels (turned back when its EXIF
        orientation turned them).

    Raises
    ------
    ValueError
        ``pillow-heif`` is not installed, or libheif cannot read the file.
    """
    img, orientation = _open_heif(path, path)
    with img:
        w, h = img.size
    return (h, w) if orientation in (5, 6, 7, 8) else (w, h)
