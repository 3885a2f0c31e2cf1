"""A starting camera matrix for photos without a calibration: EXIF focal length or a prior.

Pure functions on already-read EXIF values (:class:`ExifCamera`; reading them is
:mod:`scene3D.io.exif`'s job). The result, :class:`FocalPrior`, is what the focal
self-calibration of a pair (:mod:`scene3D.selfcalibration`) starts from, and what a
multi-view bundle adjustment can use as the prior of its one focal length.

The camera model without a calibration file: one focal length ``f`` (square pixels),
the principal point at the image centre, ``((w - 1) / 2, (h - 1) / 2)`` in the
package's pixel convention (integer coordinates at pixel centres, see
:mod:`scene3D.geometry`), no distortion. Images are taken as stored: an EXIF
orientation tag is not applied, so ``w`` and ``h`` are the stored width and height.

Focal length from EXIF, in this order:

1. ``FocalLengthIn35mmFilm``. CIPA DC-008 (Exif 2.3) defines the 35 mm equivalent
   through the diagonal: ``f35 = f * 43.27 mm / sensor diagonal``, so
   ``f_px = f35 / 43.27 * sqrt(w^2 + h^2)``. COLMAP up to 3.12 used
   ``f35 / 35 * max(w, h)`` and OpenSfM uses ``f35 / 36 * max(w, h)`` (the long side
   of the 36 x 24 mm frame); for a 3:2 image the diagonal and the 36 mm long side
   agree, for a 4:3 phone photo the long-side rule gives a focal length 4 % longer
   than the diagonal one (3 % shorter with 35 mm). COLMAP moved to the diagonal in 2025
   (colmap/colmap#3617). The tag is a whole number of millimetres: 0.5 mm of rounding
   is 1.5 % at 32 mm.
2. ``FocalLength`` (mm) with ``FocalPlaneXResolution`` (pixels per
   ``FocalPlaneResolutionUnit``: 2 inch, 3 cm, 4 mm, 5 um): ``f_px = f_mm * pixels
   per mm``, scaled by ``w / PixelXDimension`` when the EXIF records another width
   (the photo was resized and kept its EXIF).

Without a usable EXIF focal length: ``1.2 * max(w, h)``, COLMAP's default (a
horizontal field of view of 45 deg on the long side; OpenSfM's is 0.85).

The prior's uncertainty, ``sigma_log`` (a standard deviation of ``log f``):
:data:`EXIF_SIGMA_LOG` for EXIF values (rounding, makers' definitions, focus
breathing) and :data:`DEFAULT_PRIOR_SIGMA_LOG` for the default, wide enough that
two standard deviations span 0.44 to 3.3 times the longer side, from wide-angle
phone cameras to short telephotos.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .camera import different_sizes_message
from .conventions import FloatArray

#: Diagonal of the 36 x 24 mm frame, the CIPA reference for the 35 mm equivalent.
CIPA_DIAGONAL_MM = 43.27

#: The default focal length, as a multiple of the longer image side (COLMAP's).
DEFAULT_FOCAL_FACTOR = 1.2

#: Standard deviation of ``log f`` for the default focal length.
DEFAULT_PRIOR_SIGMA_LOG = 0.5

#: Standard deviation of ``log f`` for an EXIF focal length: whole-millimetre rounding
#: of the 35 mm equivalent (up to 2 % at 26 mm), makers that use the frame's width
#: rather than its diagonal (4 % on a 4:3 sensor), nominal lens focal lengths and
#: focus breathing (a few percent).
EXIF_SIGMA_LOG = 0.03

#: Plausible 35 mm-equivalent focal lengths (diagonal definition), in mm: a diagonal
#: field of view from 139 deg (8 mm, wider than any rectilinear lens a pinhole model
#: suits) to 0.8 deg (3000 mm, the longest superzoom cameras). Outside, an EXIF value
#: is taken as wrong, not as a camera.
PLAUSIBLE_FOCAL_35MM = (8.0, 3000.0)

#: EXIF FocalPlaneResolutionUnit -> millimetres per unit (1 means "no absolute unit").
RESOLUTION_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}

#: Two EXIF focal lengths closer than this (relative) count as the same zoom setting.
SAME_FOCAL_TOLERANCE = 0.01


@dataclass(frozen=True)
class ExifCamera:
    """The EXIF values that describe the camera of one photo, as read (None: absent).

    Attributes
    ----------
    make, model : str or None
        ``Make`` and ``Model`` (stripped).
    focal_length_mm : float or None
        ``FocalLength``, the lens's focal length in mm.
    focal_length_35mm : float or None
        ``FocalLengthIn35mmFilm`` (0 in EXIF means unknown).
    focal_plane_x_resolution : float or None
        ``FocalPlaneXResolution``, pixels per ``focal_plane_resolution_unit``.
    focal_plane_resolution_unit : int or None
        ``FocalPlaneResolutionUnit`` (2 inch, 3 cm, 4 mm, 5 um).
    pixel_x_dimension, pixel_y_dimension : int or None
        ``PixelXDimension``/``PixelYDimension``, the image size the camera recorded.
    orientation : int or None
        ``Orientation`` (1-8); recorded, never applied.
    error : str or None
        Why the EXIF block could not be read (corrupt), if it could not.
    """

    make: str | None = None
    model: str | None = None
    focal_length_mm: float | None = None
    focal_length_35mm: float | None = None
    focal_plane_x_resolution: float | None = None
    focal_plane_resolution_unit: int | None = None
    pixel_x_dimension: int | None = None
    pixel_y_dimension: int | None = None
    orientation: int | None = None
    error: str | None = None

    @property
    def camera_name(self) -> str | None:
        """``"Make Model"`` (the make not repeated), or None when both are absent."""
        make, model = self.make or "", self.model or ""
        if make and model.lower().startswith(make.lower()):
            make = ""
        name = f"{make} {model}".strip()
        return name or None


@dataclass(frozen=True)
class FocalPrior:
    """Where the focal length of photos without a calibration starts, and how sure it is.

    Attributes
    ----------
    focal_px : float
        Focal length in pixels of the stored images (``image_size``).
    image_size : tuple[int, int]
        (width, height) of the stored images.
    sigma_log : float
        Standard deviation of ``log(focal_px)``: :data:`EXIF_SIGMA_LOG` or
        :data:`DEFAULT_PRIOR_SIGMA_LOG`.
    source : str
        ``"exif"`` or ``"prior"`` (the default ``1.2 * max(w, h)``).
    description : str
        Where the value comes from, for people ("EXIF FocalLengthIn35mmFilm 32 mm").
    warnings : tuple[str, ...]
        EXIF problems met on the way (corrupt block, implausible value, a photo
        without EXIF among photos with it).
    camera_name : str or None
        EXIF make and model, when known.
    """

    focal_px: float
    image_size: tuple[int, int]
    sigma_log: float
    source: str
    description: str
    warnings: tuple[str, ...] = ()
    camera_name: str | None = None

    @property
    def K(self) -> FloatArray:
        """``(3, 3)`` intrinsics of the stored images: this focal length, centred principal
        point (:func:`intrinsics_from_focal`)."""
        return intrinsics_from_focal(self.focal_px, self.image_size)


def principal_point_at_centre(image_size: tuple[int, int]) -> tuple[float, float]:
    """The image centre ``((w - 1) / 2, (h - 1) / 2)``: pixel centres at integer coordinates.

    Parameters
    ----------
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    (float, float)
    """
    w, h = image_size
    return (w - 1) / 2.0, (h - 1) / 2.0


def intrinsics_from_focal(focal_px: float, image_size: tuple[int, int]) -> FloatArray:
    """``K`` ``(3, 3)`` with focal length ``focal_px`` (square pixels), the principal point at
    the centre of an image of ``image_size`` (width, height), no skew.

    Parameters
    ----------
    focal_px : float
        Focal length (px), positive.
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    (3, 3) float64 ndarray

    Raises
    ------
    ValueError
        If ``focal_px`` is not a positive number.
    """
    if not (math.isfinite(focal_px) and focal_px > 0):
        raise ValueError(f"`focal_px` must be a positive number, got {focal_px}")
    cx, cy = principal_point_at_centre(image_size)
    return np.array([[focal_px, 0.0, cx], [0.0, focal_px, cy], [0.0, 0.0, 1.0]])


def default_focal_px(image_size: tuple[int, int]) -> float:
    """COLMAP's default focal length, :data:`DEFAULT_FOCAL_FACTOR` times the longer side.

    Parameters
    ----------
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    float
        Focal length (px).
    """
    return DEFAULT_FOCAL_FACTOR * max(image_size)


def focal_35mm_from_px(focal_px: float, image_size: tuple[int, int]) -> float:
    """The 35 mm-equivalent focal length (CIPA, diagonal) of ``focal_px`` on ``image_size``.

    Parameters
    ----------
    focal_px : float
        Focal length (px).
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    float
        Focal length (mm, 35 mm equivalent).
    """
    return focal_px * CIPA_DIAGONAL_MM / math.hypot(*image_size)


def focal_px_from_35mm(focal_35mm: float, image_size: tuple[int, int]) -> float:
    """Pixels from a 35 mm-equivalent focal length: ``f35 / 43.27 * diagonal`` (CIPA).

    Parameters
    ----------
    focal_35mm : float
        Focal length (mm, 35 mm equivalent).
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    float
        Focal length (px).
    """
    return focal_35mm / CIPA_DIAGONAL_MM * math.hypot(*image_size)


def _usable(value: float | None) -> bool:
    return value is not None and math.isfinite(value) and value > 0


class ExifFocal(NamedTuple):
    """What :func:`focal_from_exif` found.

    Attributes
    ----------
    focal_px : float or None
        Focal length in pixels of the stored image; None when the EXIF gives none.
    description : str
        What it rests on, or why there is none.
    problem : bool
        The EXIF records a focal length that cannot be used (a corrupt block, 0, an
        implausible value): worth a warning, unlike a photo without one.
    """

    focal_px: float | None
    description: str
    problem: bool = False


def _recorded_size(exif: ExifCamera, image_size: tuple[int, int]) -> tuple[int, int] | None:
    """The size the camera recorded (EXIF PixelX/YDimension) in the stored orientation."""
    x, y = exif.pixel_x_dimension, exif.pixel_y_dimension
    if not (x and y and x > 0 and y > 0):
        return None
    w, h = image_size
    rotated = w != h and x != y and (x > y) != (w > h)  # pixels rotated since taken
    return (y, x) if rotated else (x, y)


def focal_from_exif(exif: ExifCamera, image_size: tuple[int, int]) -> ExifFocal:
    """The focal length in pixels that the EXIF values give for a stored image of
    ``image_size`` (width, height), or why they give none.

    See the module docstring for the order and the definitions. A photo whose
    stored aspect ratio differs from the recorded one (EXIF PixelX/YDimension) was
    cropped: the 35 mm equivalent describes the recorded frame, so its diagonal is
    used (a crop keeps the focal length in pixels) and the description says so.
    Values outside :data:`PLAUSIBLE_FOCAL_35MM` are refused.

    Parameters
    ----------
    exif : ExifCamera
        The photo's EXIF values.
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    ExifFocal
    """
    if exif.error is not None:
        return ExifFocal(None, f"the EXIF block is corrupt ({exif.error})", True)
    w, h = image_size
    recorded = _recorded_size(exif, image_size)
    cropped = recorded is not None and abs(recorded[0] * h / (recorded[1] * w) - 1.0) > 0.01
    note = (f" (cropped from {recorded[0]}x{recorded[1]}: the EXIF value may not hold)"
            if cropped else "")
    if _usable(exif.focal_length_35mm):
        f35 = float(exif.focal_length_35mm)
        frame = recorded if cropped else image_size
        focal_px = focal_px_from_35mm(f35, frame)
        how = f"EXIF FocalLengthIn35mmFilm {f35:g} mm{note}"
    elif (_usable(exif.focal_length_mm) and _usable(exif.focal_plane_x_resolution)
          and exif.focal_plane_resolution_unit in RESOLUTION_UNIT_MM):
        f_mm = float(exif.focal_length_mm)
        px_per_mm = (float(exif.focal_plane_x_resolution)
                     / RESOLUTION_UNIT_MM[exif.focal_plane_resolution_unit])
        # The resolution refers to the recorded image; a resized copy scales it.
        scale = 1.0 if recorded is None or cropped else w / recorded[0]
        focal_px = f_mm * px_per_mm * scale
        how = (f"EXIF FocalLength {f_mm:g} mm at {px_per_mm:g} px/mm"
               + (f", resized by {scale:.3g}" if scale != 1.0 else "") + note)
    elif exif.focal_length_35mm == 0 or exif.focal_length_mm == 0:
        return ExifFocal(None, "the EXIF focal length is 0 (unknown)", True)
    elif _usable(exif.focal_length_mm):
        return ExifFocal(None, f"EXIF FocalLength {exif.focal_length_mm:g} mm comes without "
                               "the sensor size (FocalLengthIn35mmFilm or "
                               "FocalPlaneXResolution)")
    else:
        return ExifFocal(None, "no EXIF focal length")
    f35 = focal_35mm_from_px(focal_px, image_size)
    low, high = PLAUSIBLE_FOCAL_35MM
    if not low <= f35 <= high:
        return ExifFocal(None, f"{how} is implausible (a 35 mm equivalent of {f35:.1f} mm, "
                               f"outside {low:g}-{high:g} mm)", True)
    return ExifFocal(focal_px, how)


def focal_prior(exif: ExifCamera | None, image_size: tuple[int, int]) -> FocalPrior:
    """The focal length to start from for one photo: from EXIF when usable, else the default.

    Parameters
    ----------
    exif : ExifCamera or None
        The photo's EXIF values (None: no EXIF at all).
    image_size : tuple[int, int]
        (width, height) of the stored image.
    """
    return camera_prior([("image", exif, image_size)])


class CameraMismatchError(ValueError):
    """The photos come from two cameras, or from one at two zoom settings, by their EXIF
    (:func:`check_one_camera`): no focal length can start from them. A calibration that
    holds for them all would serve; the message says how to give it in Python (``K``),
    a command says how on its command line.

    Attributes
    ----------
    problem : str
        What differs, naming the photos, without the remedy.
    """

    def __init__(self, problem: str) -> None:
        super().__init__(f"{problem}; or, if one calibration holds for them all, use its "
                         "`K` (scene3D.io.calibration.load_calibration)")
        self.problem = problem

    def __reduce__(self) -> tuple:  # picklable, for tasks run in other processes
        return type(self), (self.problem,)


#: The EXIF focal lengths that :func:`check_one_camera` compares, each with its own kind
#: only: a real focal length is not comparable with a 35 mm equivalent.
_FOCAL_KINDS = (("focal_length_mm", ""), ("focal_length_35mm", ", 35 mm equivalent"))


def check_one_camera(photos: Sequence[tuple[str, ExifCamera | None, tuple[int, int]]]) -> None:
    """Raise ``ValueError`` unless the photos can share one camera matrix:
    :class:`CameraMismatchError` when their EXIF names two cameras or zoom settings.

    ``photos`` are ``(name, exif, (width, height))``. They must have one stored
    size, one EXIF make and model (among those that record one) and one EXIF focal
    length (among those that record one: a zoom lens at two settings is two cameras),
    like compared with like: ``FocalLength`` values with each other, and
    ``FocalLengthIn35mmFilm`` values with each other. A photo whose EXIF focal length
    cannot be used (a corrupt block, 0, an implausible value: :func:`focal_from_exif`)
    is left out of that comparison; :func:`camera_prior` warns about it and ignores it.

    Parameters
    ----------
    photos : sequence of (str, ExifCamera or None, (int, int))
        Each photo's name, EXIF values and ``(width, height)`` in px.

    Raises
    ------
    ValueError
        No photos, or photos of different sizes; :class:`CameraMismatchError` for two
        cameras or zoom settings.
    """
    if not photos:
        raise ValueError("no photos given")
    name0, _, size0 = photos[0]
    for name, _, size in photos[1:]:
        if tuple(size) != tuple(size0):
            raise ValueError(different_sizes_message(name, tuple(size), name0, tuple(size0)))
    named = [(n, e.camera_name) for n, e, _ in photos if e is not None and e.camera_name]
    for name, camera in named[1:]:
        if camera != named[0][1]:
            raise CameraMismatchError(f"'{name}' was taken with a {camera} and "
                                      f"'{named[0][0]}' with a {named[0][1]}: one camera is "
                                      "needed")
    for field, kind in _FOCAL_KINDS:
        zooms = [(n, float(getattr(e, field))) for n, e, _ in photos
                 if e is not None and _usable(getattr(e, field))
                 and not focal_from_exif(e, size0).problem]
        for name, focal in zooms[1:]:
            if abs(focal / zooms[0][1] - 1.0) > SAME_FOCAL_TOLERANCE:
                raise CameraMismatchError(f"'{name}' was taken at {focal:g} mm and "
                                          f"'{zooms[0][0]}' at {zooms[0][1]:g} mm (EXIF{kind}): "
                                          "one focal length is needed")


def camera_prior(photos: Sequence[tuple[str, ExifCamera | None, tuple[int, int]]]
                 ) -> FocalPrior:
    """One focal-length prior for photos of one camera (:func:`check_one_camera`).

    The first photo whose EXIF gives a plausible focal length (:func:`focal_from_exif`)
    sets it (they agree, as checked); otherwise the default ``1.2 * max(w, h)``.
    What was wrong with an EXIF block on the way is kept in ``warnings``, each
    naming the photo.

    Parameters
    ----------
    photos : sequence of (str, ExifCamera or None, (int, int))
        Each photo's name, EXIF values and ``(width, height)`` in px.

    Returns
    -------
    FocalPrior


    Raises
    ------
    ValueError
        The photos differ in size; :class:`CameraMismatchError` in camera or EXIF focal
        length.
    """
    check_one_camera(photos)
    size = tuple(photos[0][2])
    camera = next((e.camera_name for _, e, _ in photos if e is not None and e.camera_name),
                  None)
    warnings: list[str] = []
    found: tuple[float, str] | None = None
    without: list[str] = []
    why_none = "no EXIF focal length"  # or the first photo's reason, when more specific
    for name, exif, _ in photos:
        result = focal_from_exif(exif, size) if exif is not None else None
        if result is None or result.focal_px is None:
            if result is not None and result.problem:
                warnings.append(f"'{name}': {result.description}; its EXIF focal length is "
                                "not used")
            else:
                if result is not None and not without:
                    why_none = result.description
                without.append(name)
        elif found is None:
            found = (result.focal_px, result.description)
    if found is not None:
        if without:
            warnings.append(f"{', '.join(repr(n) for n in without)} "
                            f"{'has' if len(without) == 1 else 'have'} no EXIF focal length: "
                            "taken to share the others'")
        return FocalPrior(found[0], size, EXIF_SIGMA_LOG, "exif", found[1], tuple(warnings),
                          camera)
    return FocalPrior(default_focal_px(size), size, DEFAULT_PRIOR_SIGMA_LOG, "prior",
                      f"{why_none}: {DEFAULT_FOCAL_FACTOR:g} x the longer side "
                      "(COLMAP's default)", tuple(warnings), camera)


#: How photos are grouped into cameras (:func:`camera_groups`).
CAMERA_MODES = ("auto", "single", "per_photo")


def _same_camera(exif: ExifCamera | None, size: tuple[int, int], other: ExifCamera | None,
                 other_size: tuple[int, int]) -> bool:
    """Whether two photos can share a camera: one stored size, and no EXIF value that
    both record (make and model, a focal length of one kind) differs."""
    if tuple(size) != tuple(other_size):
        return False
    if exif is None or other is None:
        return True
    if exif.camera_name and other.camera_name and exif.camera_name != other.camera_name:
        return False
    for field, _ in _FOCAL_KINDS:
        a, b = getattr(exif, field), getattr(other, field)
        if _usable(a) and _usable(b) and abs(float(a) / float(b) - 1.0) > SAME_FOCAL_TOLERANCE:
            return False
    return True


def camera_groups(photos: Sequence[tuple[str, ExifCamera | None, tuple[int, int]]],
                  mode: str = "auto") -> np.ndarray:
    """Which camera took each photo, as a user expects: ``(V,) int``, cameras numbered in
    the order of their first photo.

    ``"auto"``: one camera per stored size, EXIF make and model and EXIF focal length
    (a zoom lens at two settings is two cameras, as in COLMAP's automatic camera mode);
    a photo that records none of these shares the camera of the first photo of its size.
    Photos without EXIF of different sizes are so each their own camera. ``"single"``:
    one camera for all (:func:`check_one_camera` then says when they cannot share one).
    ``"per_photo"``: a camera for every photo (internet photos, zoom changing shot to shot).

    Parameters
    ----------
    photos : sequence of (str, ExifCamera or None, (int, int))
        Each photo's name, EXIF values and ``(width, height)`` in px.
    mode : str, default "auto"
        One of :data:`CAMERA_MODES`.

    Returns
    -------
    (V,) int ndarray
    """
    if mode not in CAMERA_MODES:
        raise ValueError(f"camera mode {mode!r} is not one of {', '.join(CAMERA_MODES)}")
    if mode == "single":
        return np.zeros(len(photos), dtype=int)
    if mode == "per_photo":
        return np.arange(len(photos))
    # Photos that record their camera first, each with every photo of a camera (a photo
    # that records less could otherwise join two cameras that differ); then the others.
    members: list[list[int]] = []
    out = np.empty(len(photos), dtype=int)

    def complete(exif: ExifCamera | None) -> bool:
        return exif is not None and bool(exif.camera_name) and any(
            _usable(getattr(exif, field)) for field, _ in _FOCAL_KINDS)

    order = sorted(range(len(photos)), key=lambda v: (not complete(photos[v][1]), v))
    for v in order:
        _, exif, size = photos[v]
        for c, group in enumerate(members):
            if all(_same_camera(exif, size, photos[u][1], photos[u][2]) for u in group):
                group.append(v)
                out[v] = c
                break
        else:
            out[v] = len(members)
            members.append([v])
    # Cameras numbered in the order of their first photo.
    first = sorted(range(len(members)), key=lambda c: min(members[c]))
    renumber = np.empty(len(members), dtype=int)
    renumber[first] = np.arange(len(members))
    return renumber[out]


def camera_priors(photos: Sequence[tuple[str, ExifCamera | None, tuple[int, int]]],
                  mode: str = "auto") -> tuple[np.ndarray, list[FocalPrior]]:
    """The cameras of photos (:func:`camera_groups`) and a focal-length prior for each
    (:func:`camera_prior` of its photos).

    Parameters
    ----------
    photos : sequence of (str, ExifCamera or None, (int, int))
        Each photo's name, EXIF values and ``(width, height)`` in px.
    mode : str, default "auto"
        One of :data:`CAMERA_MODES`.

    Returns
    -------
    view_camera : (V,) int ndarray
        The camera of each photo.
    priors : list of FocalPrior
        One per camera.

    Raises
    ------
    ValueError
        An unknown ``mode``; with ``"single"``, photos that cannot share a camera.
    """
    view_camera = camera_groups(photos, mode)
    priors = [camera_prior([photos[v] for v in np.flatnonzero(view_camera == c)])
              for c in range(int(view_camera.max()) + 1 if len(photos) else 0)]
    return view_camera, priors
