"""Reading images from paths or arrays into BGR ``uint8``, at their working size.

The book's size rule and the halving are :mod:`scene3D.io.halving`'s; which files of a
folder or a glob are images is :mod:`scene3D.io.image_folders`'. Their names are
importable from here too. A JPEG file is decoded straight at a reduced size
(:func:`load_working_image`), so the full-size image is never decoded or held in memory.
"""

from __future__ import annotations

import logging
import os
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from ..geometry.camera import different_sizes_message, has_distortion, undistort_image
from ..geometry.conventions import image_size
from .halving import BOOK_MAX_WIDTH_PX, halve, halving_levels  # noqa: F401 - here too
from .heif import (  # noqa: F401 - register_heif_opener, from here as before
    decode_heif,
    heif_size,
    is_heif,
    register_heif_opener,
)
from .image_folders import (  # noqa: F401 - public here too
    IMAGE_SUFFIXES,
    folder_images,
    glob_files,
    glob_patterns,
    is_folder_image,
)
from .image_integrity import check_header, header_size, intact_image_data, jpeg_cut_short

logger = logging.getLogger(__name__)

ImageSource = str | os.PathLike | np.ndarray

#: ``cv2.imdecode`` flags keeping depth (16-bit stays 16-bit) and grey or colour as stored.
_AS_STORED = cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR

#: Bytes searched for a JPEG/PNG size header (EXIF, ICC etc. come first; 256 KiB is plenty).
_HEADER_BYTES = 1 << 18


def check_image_file(path: str | os.PathLike) -> Path:
    """``path`` as a :class:`~pathlib.Path`, once it is known to name a file.

    Parameters
    ----------
    path : str or os.PathLike
        An image file.

    Returns
    -------
    Path


    Raises
    ------
    FileNotFoundError
        If nothing is there, or a folder is (saying which).
    """
    path = Path(path)
    if not path.is_file():
        what = "a folder, not an image file" if path.is_dir() else "image not found"
        raise FileNotFoundError(f"{what}: '{path}'")
    return path


def refuse_single_path(value: object, name: str, accepted: str = "image paths") -> None:
    """Raise ``TypeError`` when ``value``, where a list of paths is expected, is one path
    (a str would otherwise be taken character by character).

    Parameters
    ----------
    value : object
        The argument.
    name : str
        Its name, for the message.
    accepted : str, default "image paths"
        What the list holds, for the message.

    Raises
    ------
    TypeError
        ``value`` is one path.
    """
    if isinstance(value, (str, bytes, os.PathLike)):
        raise TypeError(f"`{name}` must be a list of {accepted}, got one path "
                        f"'{os.fsdecode(value)}'; for a folder list its photos, e.g. "
                        "sorted(Path(folder).glob('*.jpg'))")


def _read_bytes(path: str | os.PathLike) -> np.ndarray:
    """The bytes of an image file ``(n,) uint8``; checks that it exists and is not empty."""
    path = check_image_file(path)
    data = np.fromfile(path, dtype=np.uint8)  # works with non-ASCII paths too
    if data.size == 0:
        raise ValueError(f"cannot read image '{path}': the file is empty")
    return data


def _decode(data: np.ndarray, flags: int, path: str | os.PathLike) -> np.ndarray:
    head = data[:_HEADER_BYTES]
    if is_heif(head):
        return decode_heif(data, path)
    check_header(head, data.size, path)
    data = intact_image_data(data, path)
    try:
        img = cv2.imdecode(data, flags | cv2.IMREAD_IGNORE_ORIENTATION)
    except cv2.error as exc:  # OpenCV asserts rather than returning None for some files
        size = header_size(head)
        claim = f" (its header says {size[0]}x{size[1]} pixels)" if size is not None else ""
        if "validateInputImageSize" in str(exc):
            raise ValueError(f"cannot read image '{path}': too large for OpenCV{claim}, or a "
                             "damaged file") from None
        raise ValueError(f"cannot read image '{path}': a damaged image file{claim}") from None
    if img is None or img.size == 0:
        raise jpeg_cut_short(data, path) or ValueError(
            f"cannot read image '{path}': not an image file, or a damaged one")
    return img


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as stored: grey or colour, 8 or 16 bits (an alpha channel is dropped).

    The pixels are taken as stored: EXIF orientation is not applied, so that
    they match the sensor layout a calibration describes. HEIC/HEIF photos (iPhones'
    default) are read with ``pillow-heif`` when it is installed (``scene3D[heic]``), in
    8 bits, with the rotation their EXIF orientation records undone likewise.

    Parameters
    ----------
    path : str or os.PathLike
        An image file.


    Returns
    -------
    (H, W) or (H, W, 3) ndarray
        ``img[y, x]``: ``(H, W)`` for a grey file, ``(H, W, 3)`` in OpenCV's **BGR**
        channel order for a colour one (alpha dropped); ``uint8``, or ``uint16`` for a
        16-bit file. :func:`load_working_image` converts to BGR ``uint8``.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is empty or not an image OpenCV can decode: damaged, too large
        for OpenCV, or a JPEG whose header claims more pixels than the file holds; a
        truncated JPEG, PNG or TIFF file, or a JPEG whose compressed data holds garbage
        (:func:`scene3D.io.image_integrity.intact_image_data`, before any decoder prints
        to stderr); or a HEIC/HEIF photo without ``pillow-heif`` installed (the message
        says how).
    """
    return _decode(_read_bytes(path), _AS_STORED, path)


def read_image_size(path: str | os.PathLike) -> tuple[int, int]:
    """``(width, height)`` of an image file as stored: from its header (JPEG and PNG here,
    TIFF, WebP and others through Pillow), else by decoding it.

    Raises ``FileNotFoundError`` / ``ValueError`` like :func:`read_image`.

    Parameters
    ----------
    path : str or os.PathLike
        An image file.

    Returns
    -------
    (int, int)
    """
    path = Path(path)
    if path.is_file():
        with open(path, "rb") as f:
            head = f.read(_HEADER_BYTES)
            check_header(head, os.fstat(f.fileno()).st_size, path)  # JPEG only
        if is_heif(head):  # read from its header, without decoding
            return heif_size(path)
        size = header_size(head) or _pillow_size(path)
        if size is not None:
            return size
    return image_size(read_image(path))


def _pillow_size(path: Path) -> tuple[int, int] | None:
    """``(width, height)`` from the header Pillow reads (a 16-bit TIFF is not decoded for
    its size), or None when Pillow cannot tell: then decoding says what is wrong."""
    import warnings

    from PIL import Image

    try:
        # Pillow's warnings are not the user's: a large photo is no decompression bomb here,
        # and a damaged file (a truncated TIFF: "Corrupt EXIF data") is reported in one
        # line when decoding it, not also in Pillow's two.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(path) as img:
                return int(img.width), int(img.height)
    except Exception:  # noqa: BLE001 - unknown format, damaged, a decompression bomb: decode
        return None


def to_bgr8(img: np.ndarray, name: str = "image") -> np.ndarray:
    """Convert grey, BGR or BGRA images of ``uint8``/``uint16`` depth to BGR ``uint8``.

    16-bit images are scaled by the bit depth their values use: the fewest of 8 to 16
    bits that hold the largest value, so that full-range 16-bit data are divided by 257
    and the 12-bit data of many machine-vision cameras (stored in ``uint16``, at most
    4095) by 16.06, instead of coming out nearly black.

    Parameters
    ----------
    img : (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) ndarray
        Grey, BGR or BGRA image, ``uint8`` or ``uint16``.
    name : str, default "image"
        The image's name in messages.

    Returns
    -------
    (H, W, 3) uint8 ndarray


    Raises
    ------
    TypeError
        When ``img`` is no numpy array (None, a list, bytes).
    ValueError
        For other dtypes or channel counts, or an empty image.
    """
    if not isinstance(img, np.ndarray):
        raise TypeError(f"`{name}` must be a path or a numpy array, got {type(img).__name__}")
    if img.size == 0 or img.ndim not in (2, 3):
        raise ValueError(f"`{name}` must be an (H, W) or (H, W, C) image, got shape {img.shape}")
    if img.dtype == np.uint16:
        bits = max(8, int(img.max()).bit_length())
        # Rounded to the nearest level, with no float copy (a 24-megapixel colour image's
        # would take 290 MB); no value lies half-way between two levels.
        img = cv2.convertScaleAbs(img, alpha=255.0 / (2**bits - 1))
    elif img.dtype != np.uint8:
        raise ValueError(f"`{name}` must be uint8 or uint16, got {img.dtype}")
    if img.ndim == 2 or img.shape[2] == 1:
        return cv2.cvtColor(img.reshape(img.shape[:2]), cv2.COLOR_GRAY2BGR)
    if img.shape[2] == 3:
        return np.ascontiguousarray(img)
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    raise ValueError(f"`{name}` must have 1, 3 or 4 channels, got {img.shape[2]}")


def bgr_order(source: ImageSource, rgb: bool = False) -> ImageSource:
    """``source`` in OpenCV's channel order: with ``rgb``, a colour array (RGB or RGBA, as
    PIL, imageio and matplotlib give) as BGR or BGRA (a copy); a path, a grey array, or
    any array without ``rgb`` as it is (arrays are taken as BGR, as cv2 loads them, and
    never guessed at).

    Parameters
    ----------
    source : str, os.PathLike or ndarray
        An image file, or an image ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``.
    rgb : bool, default False
        The array's channels are red, green, blue (and alpha).

    Returns
    -------
    str, os.PathLike or ndarray
    """
    if not rgb or not isinstance(source, np.ndarray) or source.ndim != 3:
        return source
    if source.shape[2] == 3:
        return np.ascontiguousarray(source[..., ::-1])
    if source.shape[2] == 4:
        return np.ascontiguousarray(source[..., [2, 1, 0, 3]])
    return source


def load_bgr(source: ImageSource, name: str = "image") -> np.ndarray:
    """Load a path or take an array, and return it as BGR ``uint8`` ``(H, W, 3)``.

    Parameters
    ----------
    source : str, os.PathLike or ndarray
        An image file or an image array (:func:`to_bgr8`).
    name : str, default "image"
        An array's name in messages.

    Returns
    -------
    (H, W, 3) uint8 ndarray
    """
    if isinstance(source, (str, os.PathLike)):
        return to_bgr8(read_image(source), name=str(source))
    return to_bgr8(source, name=name)



#: ``cv2.imdecode`` flags that make libjpeg decode at 1/2, 1/4 and 1/8 size.
_REDUCED_COLOR = {1: cv2.IMREAD_REDUCED_COLOR_2, 2: cv2.IMREAD_REDUCED_COLOR_4,
                  3: cv2.IMREAD_REDUCED_COLOR_8}


def _check_halvable(size: tuple[int, int], levels: int, label: str | os.PathLike) -> None:
    """Raise ``ValueError`` naming ``label`` when halving ``size`` ``levels`` times leaves
    no pixel (a strip far wider than high), as :func:`halve` would."""
    if size[0] >> levels == 0 or size[1] >> levels == 0:
        raise ValueError(f"'{label}': a {size[0]}x{size[1]} image cannot be halved {levels} "
                         f"times (to {size[0] >> levels}x{size[1] >> levels} pixels)")


def load_working_image(
    source: ImageSource, K: np.ndarray, dist: np.ndarray,
    max_width: int | None = BOOK_MAX_WIDTH_PX, name: str = "image",
) -> tuple[np.ndarray, tuple[int, int], int]:
    """The working image of a path or array: BGR ``uint8``, undistorted, halved to ``max_width``.

    ``K`` and ``dist`` describe the native image; it is undistorted at native
    resolution (where the model holds) and then halved while wider than
    ``max_width`` (None: never). A JPEG file without distortion to remove is
    decoded straight at the reduced size, which is faster and needs less memory
    than decoding it whole.

    Parameters
    ----------
    source : str, os.PathLike or ndarray
        An image file or array at its native size.
    K : (3, 3) ndarray
        Native intrinsics (OpenCV pixels).
    dist : (n,) ndarray
        OpenCV distortion coefficients (empty for none).
    max_width : int or None, default BOOK_MAX_WIDTH_PX
        Largest working width (px); None for no halving.
    name : str, default "image"
        An array's name in messages.


    Returns
    -------
    image : (h, w, 3) uint8
    native_size : (width, height) of the source
    levels : int
        Halvings applied; the working ``K`` is ``scale_intrinsics_halved(K, levels)``.
    """
    if isinstance(source, (str, os.PathLike)):
        data = _read_bytes(source)
        size = header_size(data[:_HEADER_BYTES])
        levels = halving_levels(size[0], max_width) if size is not None else 0
        if levels:
            _check_halvable(size, levels, source)
        if levels and not has_distortion(dist) and bytes(data[:2]) == b"\xff\xd8":
            direct = min(levels, 3)
            img = to_bgr8(_decode(data, _REDUCED_COLOR[direct], source), str(source))
            k = 1 << direct
            if image_size(img) == ((size[0] + k - 1) // k, (size[1] + k - 1) // k):
                # libjpeg rounds partial blocks up; keep the whole ones only, as halve() does.
                img = img[:size[1] >> direct, :size[0] >> direct]
                return halve(img, levels - direct), size, levels
            # The header did not describe the image: decode it whole below.
        img = to_bgr8(_decode(data, _AS_STORED, source), str(source))
    else:
        img = to_bgr8(source, name=name)
    native = image_size(img)
    levels = halving_levels(native[0], max_width)
    _check_halvable(native, levels, source_label(source, name))
    if has_distortion(dist):
        img = undistort_image(img, K, dist)
    return halve(img, levels), native, levels


def iter_working_images(
    sources: Sequence[ImageSource], K: np.ndarray, dist: np.ndarray,
    max_width: int | None = BOOK_MAX_WIDTH_PX, names: Sequence[str] | None = None,
) -> Iterator[tuple[np.ndarray, tuple[int, int], int]]:
    """:func:`load_working_image` of photos of one camera, in order, two decoding at once
    (decoding releases the GIL) and no more than two held ahead of the consumer.

    Yields ``(image, native_size, levels)`` per source.

    Parameters
    ----------
    sources : sequence of str, os.PathLike or ndarray
        Image files or arrays of one camera at their native size.
    K : (3, 3) ndarray
        Native intrinsics (OpenCV pixels).
    dist : (n,) ndarray
        OpenCV distortion coefficients.
    max_width : int or None, default BOOK_MAX_WIDTH_PX
        Largest working width (px); None for no halving.
    names : sequence of str or None, default None
        Names of the sources in messages; None for "image i".

    Yields
    ------
    image : (h, w, 3) uint8 ndarray
    native_size : (int, int)
    levels : int


    Raises
    ------
    ValueError
        At the first source whose size differs from the first's: one calibration
        holds for one size (:func:`scene3D.geometry.camera.different_sizes_message`).
    """
    names = list(names) if names is not None else [f"image {i}" for i in range(len(sources))]
    first: tuple[str, tuple[int, int]] | None = None

    def checked(src: ImageSource, name: str, job: Future
                ) -> tuple[np.ndarray, tuple[int, int], int]:
        nonlocal first
        img, size, levels = job.result()
        label = source_label(src, name)
        first = first or (label, size)
        if size != first[1]:
            raise ValueError(different_sizes_message(label, size, *first))
        return img, size, levels

    with ThreadPoolExecutor(max_workers=2) as pool:
        pending: deque[tuple[ImageSource, str, Future]] = deque()
        for src, name in zip(sources, names):
            pending.append((src, name, pool.submit(load_working_image, src, K, dist,
                                                   max_width, name)))
            if len(pending) == 2:
                yield checked(*pending.popleft())
        while pending:
            yield checked(*pending.popleft())


def load_working_images(
    sources: Sequence[ImageSource], K: np.ndarray, dist: np.ndarray,
    max_width: int | None = BOOK_MAX_WIDTH_PX, names: Sequence[str] | None = None,
) -> tuple[list[np.ndarray], tuple[int, int] | None, int]:
    """All of :func:`iter_working_images` at once: the working images, their common
    native ``(width, height)`` (None for no sources) and the number of halvings.

    Raises ``ValueError`` when the sources differ in size.

    Parameters
    ----------
    sources : sequence of str, os.PathLike or ndarray
        Image files or arrays of one camera at their native size.
    K : (3, 3) ndarray
        Native intrinsics (OpenCV pixels).
    dist : (n,) ndarray
        OpenCV distortion coefficients.
    max_width : int or None, default BOOK_MAX_WIDTH_PX
        Largest working width (px); None for no halving.
    names : sequence of str or None, default None
        Names of the sources in messages.

    Returns
    -------
    images : list of (h, w, 3) uint8 ndarray
    native_size : (int, int) or None
    levels : int
    """
    loaded = list(iter_working_images(sources, K, dist, max_width, names))
    if not loaded:
        return [], None, 0
    return [img for img, _, _ in loaded], loaded[0][1], loaded[0][2]


def source_label(source: ImageSource, name: str) -> str:
    """How messages name an image: a path as given, an array by ``name``.

    Parameters
    ----------
    source : str, os.PathLike or ndarray
        An image file or array.
    name : str
        An array's name.

    Returns
    -------
    str
    """
    return os.fspath(source) if isinstance(source, (str, os.PathLike)) else name
