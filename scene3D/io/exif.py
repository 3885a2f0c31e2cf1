"""Reading the EXIF values that describe a photo's camera (Pillow), and the focal prior of
a set of photos.

I/O only: the values are turned into a focal length and checked by the pure
functions of :mod:`scene3D.geometry.intrinsics_prior`. Pillow (a dependency of matplotlib,
and of scene3D) is imported on first use. The orientation tag is read and
recorded, never applied: images are used as stored (see :mod:`scene3D.geometry`).
"""

from __future__ import annotations

import logging
import math
import os
import warnings
from collections.abc import Sequence

import numpy as np

from ..geometry.intrinsics_prior import ExifCamera, FocalPrior, camera_prior, camera_priors
from .images import (
    check_image_file,
    read_image_size,
    refuse_single_path,
    register_heif_opener,
    source_label,
)

logger = logging.getLogger(__name__)

# EXIF tag numbers (CIPA DC-008): IFD0, then the Exif sub-IFD.
_MAKE, _MODEL, _ORIENTATION, _EXIF_IFD = 0x010F, 0x0110, 0x0112, 0x8769
_FOCAL_LENGTH, _FOCAL_35MM = 0x920A, 0xA405
_FOCAL_PLANE_X_RES, _FOCAL_PLANE_UNIT = 0xA20E, 0xA210
_PIXEL_X, _PIXEL_Y = 0xA002, 0xA003


def _number(value: object) -> float | None:
    """A finite float from an EXIF value (rational, int, 1-tuple), else None."""
    if isinstance(value, (tuple, list)):
        value = value[0] if len(value) == 1 else None
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return number if math.isfinite(number) else None


def _integer(value: object) -> int | None:
    number = _number(value)
    return int(number) if number is not None and number == int(number) else None


def _text(value: object) -> str | None:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if not isinstance(value, str):
        return None
    value = value.replace("\x00", "").strip()
    return value or None


def read_exif(path: str | os.PathLike) -> ExifCamera | None:
    """The camera's EXIF values of an image file; None when it has no EXIF block.

    A block that is present but cannot be parsed (truncated, not TIFF-structured,
    tags pointing outside it: what Pillow warns about or returns empty for) gives
    an :class:`ExifCamera` whose ``error`` says so, so that the caller can say it
    rather than silently use a default. A file Pillow cannot open at all is taken
    as having no EXIF (reading the image itself will report the problem).

    Parameters
    ----------
    path : str or os.PathLike
        An image file.

    Returns
    -------
    ExifCamera or None


    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    """
    path = check_image_file(path)
    from PIL import Image, UnidentifiedImageError

    register_heif_opener()  # HEIC photos' EXIF, when pillow-heif is installed

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with Image.open(path) as img:
                raw = img.info.get("exif")
                exif = img.getexif()
                ifd0 = dict(exif)
                sub = dict(exif.get_ifd(_EXIF_IFD)) if _EXIF_IFD in ifd0 else {}
        except Image.DecompressionBombError as exc:
            # Pillow refuses to open it before any pixel is read: its EXIF is out of reach
            # too, which is not a corrupt block (reading the image decides about the pixels).
            logger.warning("'%s': Pillow will not open it (%s): its EXIF is not read",
                           path, str(exc).split(",")[0])
            return None
        except (UnidentifiedImageError, OSError) as exc:
            if isinstance(exc, FileNotFoundError):
                raise
            logger.debug("'%s': Pillow cannot open it (%s): no EXIF read", path, exc)
            return None
        except Exception as exc:  # noqa: BLE001 - Pillow's parser raises many types
            return ExifCamera(error=f"{type(exc).__name__}: {exc}")
    problems = [str(w.message).split(".")[0] for w in caught
                if "exif" in str(w.message).lower() or "tag" in str(w.message).lower()]
    if not ifd0 and not sub:
        if raw and len(raw) > 6:
            return ExifCamera(error=problems[0] if problems else
                              "an EXIF block that does not parse as TIFF")
        return None
    if problems:
        return ExifCamera(error=problems[0])
    return ExifCamera(
        make=_text(ifd0.get(_MAKE)),
        model=_text(ifd0.get(_MODEL)),
        focal_length_mm=_number(sub.get(_FOCAL_LENGTH)),
        focal_length_35mm=_number(sub.get(_FOCAL_35MM)),
        focal_plane_x_resolution=_number(sub.get(_FOCAL_PLANE_X_RES)),
        focal_plane_resolution_unit=_integer(sub.get(_FOCAL_PLANE_UNIT)),
        pixel_x_dimension=_integer(sub.get(_PIXEL_X)),
        pixel_y_dimension=_integer(sub.get(_PIXEL_Y)),
        orientation=_integer(ifd0.get(_ORIENTATION)),
    )


def read_camera_prior(paths: Sequence[str | os.PathLike]) -> FocalPrior:
    """The focal-length prior of photos taken with one camera, from their EXIF and sizes.

    Reads each photo's EXIF (:func:`read_exif`) and stored size
    (:func:`scene3D.io.images.read_image_size`) and hands them to
    :func:`scene3D.geometry.intrinsics_prior.camera_prior`: one camera is checked (one
    size, make and model, EXIF focal length) and the focal length taken from EXIF,
    or the default ``1.2 * max(w, h)``. The prior's ``warnings`` name the photos
    whose EXIF could not be used, and errors the photos that differ, by their paths as
    given (:func:`scene3D.io.images.source_label`).

    Parameters
    ----------
    paths : sequence of str or PathLike
        The photos' files: a list, not one path (for a folder:
        ``sorted(Path(folder).glob("*.jpg"))``).

    Raises
    ------
    TypeError
        ``paths`` is one path (a str or Path) rather than a list of them.
    FileNotFoundError
        A photo does not exist.
    ValueError
        A file is not an image, or the photos come from different cameras or sizes.
    """
    refuse_single_path(paths, "paths")
    # The size first: a damaged header is refused before Pillow warns about it.
    sizes = [read_image_size(p) for p in paths]
    photos = [(source_label(p, ""), read_exif(p), size) for p, size in zip(paths, sizes)]
    prior = camera_prior(photos)
    for message in prior.warnings:
        logger.warning("%s", message)
    return prior


def read_camera_priors(paths: Sequence[str | os.PathLike], mode: str = "auto"
                       ) -> tuple[np.ndarray, list[FocalPrior]]:
    """The cameras that took photos and a focal-length prior for each, from their EXIF
    and sizes (:func:`scene3D.geometry.intrinsics_prior.camera_priors`).

    Parameters
    ----------
    paths : sequence of str or PathLike
        The photos' files.
    mode : str, default "auto"
        How photos are grouped into cameras
        (:data:`scene3D.geometry.intrinsics_prior.CAMERA_MODES`).

    Returns
    -------
    view_camera : (V,) int ndarray
        The camera of each photo, numbered in the order of their first photo.
    priors : list of FocalPrior
        One per camera; their warnings are logged.

    Raises
    ------
    FileNotFoundError
        A photo does not exist.
    ValueError
        A file is not an image, an unknown ``mode``, or with ``mode="single"`` photos
        from different cameras or sizes.
    """
    refuse_single_path(paths, "paths")
    sizes = [read_image_size(p) for p in paths]
    photos = [(source_label(p, ""), read_exif(p), size) for p, size in zip(paths, sizes)]
    view_camera, priors = camera_priors(photos, mode)
    for prior in priors:
        for message in prior.warnings:
            logger.warning("%s", message)
    return view_camera, priors
