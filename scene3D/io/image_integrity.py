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


# -- headers: the size a file claims, and whether its bytes can hold it ------------------

def header_size(head: bytes | np.ndarray) -> tuple[int, int] | None:
    """``(width, height)`` from the first bytes of a JPEG or PNG file, or None.

    Reads the JPEG frame header (SOFn marker) or the PNG IHDR chunk; None for
    other formats, or when the header is not within ``head``.

    Parameters
    ----------
    head : bytes or uint8 ndarray
        The file's first bytes.

    Returns
    -------
    (int, int) or None
    """
    head = memoryview(head).cast("B")
    if bytes(head[:8]) == b"\x89PNG\r\n\x1a\n" and len(head) >= 24:
        return (int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big"))
    frame = _jpeg_frame(head)
    return frame[1] if frame is not None else None


def _jpeg_frame(head: memoryview) -> tuple[int, tuple[int, int], list[tuple[int, int]]] | None:
    """The first JPEG frame header in ``head``: ``(marker, (width, height), sampling)``.

    ``sampling`` holds each component's ``(H, V)`` sampling factors (empty when the
    header is cut off within them); None when ``head`` is not a JPEG or holds no frame.
    """
    if bytes(head[:2]) != b"\xff\xd8":
        return None
    i = 2
    while i + 9 <= len(head):
        if head[i] != 0xFF:
            return None
        marker = head[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD7:  # TEM, RSTn: no length field
            i += 2
            continue
        # Frame headers SOF0..SOF15, except DHT (C4), JPG (C8) and DAC (CC).
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            height = int.from_bytes(head[i + 5:i + 7], "big")
            width = int.from_bytes(head[i + 7:i + 9], "big")
            if not (width and height):
                return None
            count = head[i + 9] if i + 9 < len(head) else 0
            end = i + 10 + 3 * count
            sampling = ([(head[j] >> 4, head[j] & 15) for j in range(i + 11, end, 3)]
                        if end <= len(head) else [])
            return marker, (width, height), sampling
        i += 2 + int.from_bytes(head[i + 2:i + 4], "big")
    return None


#: JPEG frame markers of Huffman coding (the arithmetic-coded ones, C9-CF, can be
#: smaller than one bit per block).
_HUFFMAN_FRAMES = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7})


def _ceil_div(a: int, b: int) -> int:
    return -(-a // b)


def _jpeg_min_bytes(frame: tuple[int, tuple[int, int], list[tuple[int, int]]]) -> int:
    """A lower bound on the size of a complete Huffman-coded JPEG with this frame header.

    Every 8x8 block of every component carries at least its DC code, a Huffman code
    of at least one bit. Halved for safety; 0 when the bound does not apply.
    """
    marker, (width, height), sampling = frame
    if marker not in _HUFFMAN_FRAMES or not sampling or min(min(s) for s in sampling) < 1:
        return 0
    h_max = max(h for h, _ in sampling)
    v_max = max(v for _, v in sampling)
    blocks = sum(_ceil_div(_ceil_div(width * h, h_max), 8)
                 * _ceil_div(_ceil_div(height * v, v_max), 8) for h, v in sampling)
    return blocks // 16


def check_header(head: bytes | np.ndarray, file_bytes: int, path: str | os.PathLike) -> None:
    """Raise ``ValueError`` when a JPEG's header claims more pixels than its
    ``file_bytes`` can hold (a damaged or tampered header), naming ``path``.

    Cheap: no pixel is decoded.

    Parameters
    ----------
    head : bytes or uint8 ndarray
        The file's first bytes.
    file_bytes : int
        The file's size in bytes.
    path : path
        The file, for the message.

    Raises
    ------
    ValueError
        The header claims more pixels than the file can hold.
    """
    frame = _jpeg_frame(memoryview(head).cast("B"))
    if frame is not None and file_bytes < _jpeg_min_bytes(frame):
        w, h = frame[1]
        raise ValueError(f"cannot read image '{path}': a damaged JPEG file (its header says "
                         f"{w}x{h} pixels, more than its {file_bytes} bytes can hold)")
