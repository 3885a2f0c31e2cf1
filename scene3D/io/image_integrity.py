"""Truncated and damaged JPEG, PNG and TIFF files, found from their structure before decoding.

OpenCV's decoders say little of a damaged file, and only on stderr, without its name:
libjpeg decodes a JPEG whose compressed data holds garbage with grey filler in place of
the blocks it lost ("Corrupt JPEG data: premature end of data segment"), and libpng and
libtiff print their own lines before OpenCV gives up. :func:`intact_image_data` walks a
file's structure instead (JPEG markers, PNG chunks, the TIFF directory and the strips it
points to) and raises a one-line ``ValueError`` naming the file and the damage, before a
decoder sees it. No pixel is decoded: the scan of a 3 MB JPEG for its markers takes about
0.5 ms, 1 to 2 % of decoding it (docs/troubleshooting.md).

What the structure cannot show: bytes lost or changed inside a JPEG's compressed data
that leave its markers in place. libjpeg then decodes shifted or missing blocks, with a
line of its own on stderr or none.
"""

from __future__ import annotations

import logging
import os

import numpy as np

logger = logging.getLogger(__name__)

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

#: JPEG markers without a length field: TEM, RST0-RST7, SOI, EOI.
_JPEG_BARE_MARKERS = frozenset({0x01, *range(0xD0, 0xDA)})

#: TIFF tags of the image data's offsets and byte counts: strips, then tiles.
_TIFF_DATA_TAGS = ((273, 279), (324, 325))


def intact_image_data(data: np.ndarray, path: str | os.PathLike) -> np.ndarray:
    """The bytes of an image file ``(n,) uint8``, once its structure shows it whole.

    JPEG: every marker segment in place up to the first scan, and the compressed data
    of each scan free of markers other than restart markers in order. A file that ends
    in a scan, without its end-of-image marker, is left to the decoder: OpenCV decodes
    one that lost only that marker whole and refuses one cut short
    (:func:`jpeg_cut_short` then names the cause). Stray bytes
    between the segments before the first scan (which hold no pixel) are dropped, with a
    warning naming the file. PNG: chunks up to ``IEND``. TIFF: the first directory and the
    image data it points to within the file. Other formats pass unchecked.

    Parameters
    ----------
    data : (n,) uint8 ndarray
        The file's bytes.
    path : str or os.PathLike
        The file, for messages.

    Returns
    -------
    (n',) uint8 ndarray


    Raises
    ------
    ValueError
        Naming ``path``: the file is truncated, or its structure is damaged.
    """
    head = data[:8].tobytes()
    if head[:2] == b"\xff\xd8":
        return _check_jpeg(data, path)
    if head == _PNG_SIGNATURE:
        _check_png(data, path)
    elif head[:4] in (b"II*\x00", b"MM\x00*"):
        _check_tiff(data, path)
    return data


def jpeg_cut_short(data: np.ndarray, path: str | os.PathLike) -> ValueError | None:
    """The error for a JPEG file ``data`` that its decoder refused and that does not end
    with an end-of-image marker (cut short); None for any other file.

    Parameters
    ----------
    data : (n,) uint8 ndarray
        The file's bytes.
    path : str or os.PathLike
        The file, for the message.

    Returns
    -------
    ValueError or None
    """
    if data[:2].tobytes() == b"\xff\xd8" and data[-2:].tobytes() != b"\xff\xd9":
        return _truncated(path, "JPEG", "it ends before its end-of-image marker")
    return None


def _truncated(path: str | os.PathLike, kind: str, detail: str) -> ValueError:
    return ValueError(f"cannot read image '{path}': a truncated {kind} file ({detail})")


def _check_jpeg(data: np.ndarray, path: str | os.PathLike) -> np.ndarray:
    """:func:`intact_image_data` of a JPEG file."""
    n = int(data.size)
    ff = np.flatnonzero(data[:-1] == 0xFF)
    codes = data[ff + 1]
    is_marker = (codes != 0x00) & (codes != 0xFF)  # not a stuffed 0xFF, not a fill byte
    markers, codes = ff[is_marker], codes[is_marker]
    not_restart = np.flatnonzero((codes < 0xD0) | (codes > 0xD7))
    truncated = _truncated(path, "JPEG", "it ends before its end-of-image marker")
    stray: list[tuple[int, int]] = []
    restart_interval, scanned, i = 0, False, 2
    while True:
        if i + 2 > n:
            if scanned:  # no end-of-image marker: cut short, or only that marker lost
                break
            raise truncated
        if data[i] != 0xFF:  # bytes where a marker belongs
            k = int(np.searchsorted(markers, i))
            if k == len(markers):
                raise truncated
            if scanned:
                raise _damaged_jpeg(path, f"{int(markers[k]) - i} stray bytes after its "
                                          f"compressed data at byte {i}")
            stray.append((i, int(markers[k])))
            i = int(markers[k])
            continue
        code = int(data[i + 1])
        if code == 0xFF:  # fill byte
            i += 1
            continue
        if code == 0xD9:  # EOI
            break
        if (code < 0xC0 and code != 0x01) or code == 0xD8:
            raise _damaged_jpeg(path, f"an invalid marker 0x{code:02x} at byte {i}")
        if code in _JPEG_BARE_MARKERS:
            i += 2
            continue
        if i + 4 > n:
            raise truncated
        end = i + 2 + (int(data[i + 2]) << 8 | int(data[i + 3]))
        if end < i + 4:
            raise _damaged_jpeg(path, f"a marker segment of length 0 or 1 at byte {i}")
        if end > n:
            raise truncated
        if code == 0xDD and end >= i + 6:  # DRI: restart markers every so many blocks
            restart_interval = int(data[i + 4]) << 8 | int(data[i + 5])
        if code == 0xDA:  # SOS: the compressed data runs to the next marker but RSTn
            scanned = True
            k = int(np.searchsorted(markers, end))
            j = int(np.searchsorted(not_restart, k))
            if j == len(not_restart):  # the scan runs to the end of the file
                break
            restarts = codes[k:not_restart[j]].astype(np.int64) - 0xD0
            if restarts.size and (not restart_interval or np.any(
                    restarts != np.arange(restarts.size) % 8)):
                raise _damaged_jpeg(path, "restart markers missing or out of order in its "
                                          f"compressed data after byte {end}")
            end = int(markers[not_restart[j]])
        i = end
    if stray:
        logger.warning("'%s': %d stray bytes between the JPEG's header segments, left out "
                       "(they hold no pixel)", path, sum(b - a for a, b in stray))
        data = np.delete(data, np.concatenate([np.arange(a, b) for a, b in stray]))
    return data


def _damaged_jpeg(path: str | os.PathLike, detail: str) -> ValueError:
    return ValueError(f"cannot read image '{path}': a damaged JPEG file ({detail}: part of "
                      "the image would be filler or garbage)")


def _check_png(data: np.ndarray, path: str | os.PathLike) -> None:
    """Raise ``ValueError`` naming ``path`` unless the PNG's chunks reach ``IEND``."""
    view = memoryview(data)
    i = len(_PNG_SIGNATURE)
    while i + 8 <= len(view):
        if view[i + 4:i + 8] == b"IEND":
            return
        i += 12 + int.from_bytes(view[i:i + 4], "big")
    raise _truncated(path, "PNG", "it ends before its IEND chunk")


def _check_tiff(data: np.ndarray, path: str | os.PathLike) -> None:
    """Raise ``ValueError`` naming ``path`` unless the TIFF's first directory and the image
    data it points to (strips or tiles) lie within the file. BigTIFF passes unchecked."""
    order = "<" if data[0] == ord("I") else ">"
    n = int(data.size)

    def number(at: int, size: int) -> int:
        return int(np.frombuffer(data[at:at + size].tobytes(), f"{order}u{size}")[0])

    directory = number(4, 4)
    if directory + 2 > n or directory + 6 + 12 * number(directory, 2) > n:
        raise _truncated(path, "TIFF", f"its directory at byte {directory} lies past its end")
    entries = {}
    for at in range(directory + 2, directory + 2 + 12 * number(directory, 2), 12):
        entries[number(at, 2)] = at

    def values(tag: int) -> np.ndarray | None:
        at = entries.get(tag)
        if at is None or number(at + 2, 2) not in (3, 4):  # SHORT or LONG
            return None
        size, count = 2 if number(at + 2, 2) == 3 else 4, number(at + 4, 4)
        start = at + 8 if size * count <= 4 else number(at + 8, 4)
        if start + size * count > n:
            raise _truncated(path, "TIFF", f"tag {tag}'s values at byte {start} lie past its "
                                           "end")
        return np.frombuffer(data[start:start + size * count].tobytes(), f"{order}u{size}")

    for offsets_tag, counts_tag in _TIFF_DATA_TAGS:
        offsets, counts = values(offsets_tag), values(counts_tag)
        if offsets is not None and counts is not None and offsets.size == counts.size:
            end = int((offsets.astype(np.int64) + counts).max(initial=0))
            if end > n:
                raise _truncated(path, "TIFF", f"its image data runs to byte {end}, past its "
                                               f"{n} bytes")
