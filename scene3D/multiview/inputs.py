"""The photos given to :func:`scene3D.multiview.pipeline.reconstruct_views`: their
cameras' priors without a calibration, and the checks that refuse what cannot be
reconstructed (two views of one name or one photo, a ``K`` for another size, too few
keypoints for any pair).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from ..geometry.camera import check_intrinsics_for_native_size
from ..geometry.intrinsics_prior import FocalPrior, camera_priors
from ..io.images import ImageSource


def default_focal_prior(images: Sequence[ImageSource], names: Sequence[str]) -> FocalPrior:
    """The prior of photos of one camera without a calibration:
    :func:`default_camera_priors` with one camera (``"single"``: photos that cannot share
    one are refused), from their EXIF when they are files, else the default.

    Parameters
    ----------
    images : sequence of path or (H, W, 3) uint8 ndarray
        The images, as files or BGR arrays.
    names : sequence of str
        Their names, one per image.

    Returns
    -------
    FocalPrior
    """
    return default_camera_priors(images, names, "single")[1][0]


def default_camera_priors(images: Sequence[ImageSource], names: Sequence[str],
                          mode: str = "auto") -> tuple[np.ndarray, list[FocalPrior]]:
    """The cameras of photos without a calibration and a prior for each: from their EXIF
    and sizes when they are files (:func:`scene3D.io.exif.read_camera_priors`), else
    from their sizes (:func:`scene3D.geometry.intrinsics_prior.camera_priors`).

    Parameters
    ----------
    images : sequence of path or (H, W, 3) uint8 ndarray
        The images, as files or BGR arrays.
    names : sequence of str
        Their names, one per image.
    mode : str, default "auto"
        How photos are grouped into cameras
        (:data:`scene3D.geometry.intrinsics_prior.CAMERA_MODES`).

    Returns
    -------
    view_camera : (V,) int ndarray
    priors : list of FocalPrior
        One per camera.
    """
    if all(isinstance(src, (str, os.PathLike)) for src in images):
        from ..io.exif import read_camera_priors

        return read_camera_priors(images, mode)  # type: ignore[arg-type]
    sizes = [(int(np.shape(src)[1]), int(np.shape(src)[0])) for src in images]
    return camera_priors([(name, None, size) for name, size in zip(names, sizes)], mode)


def check_K_for_size(K: np.ndarray, size: tuple[int, int], prior: FocalPrior | None) -> None:
    """Raise ``ValueError`` unless ``K`` (given, or the prior's) suits the native ``size``.

    Parameters
    ----------
    K : (3, 3) ndarray
        Intrinsics of the native images.
    size : (int, int)
        The images' native (width, height).
    prior : FocalPrior or None
        The prior ``K`` is from (None: ``K`` was given).

    Raises
    ------
    ValueError
        A prior for another size, or a ``K`` that cannot be of ``size``.
    """
    if prior is not None and tuple(prior.image_size) != tuple(size):
        raise ValueError(f"`focal_prior` is for {prior.image_size[0]}x{prior.image_size[1]} "
                         f"images, not {size[0]}x{size[1]} px, the images' native size, "
                         "which it must be for")
    check_intrinsics_for_native_size(K, size, "`K`" if prior is None else "`focal_prior.K`")


def too_few_keypoints(found: Sequence[tuple], labels: Sequence[str], needed: int,
                       working_size: tuple[int, int]) -> str | None:
    """Why no pair could start when fewer than two views have the ``needed`` keypoints a
    verified pair needs (blank, tiny or too far downscaled images), naming the images by
    their ``labels`` (:func:`~scene3D.io.images.source_label`); else None.

    Parameters
    ----------
    found : sequence of tuple
        Each view's :func:`scene3D.multiview.features.view_features` result (its
        :class:`~scene3D.multiview.view_data.ViewFeatures` first).
    labels : sequence of str
        The images' names in messages.
    needed : int
        Keypoints a verified pair needs.
    working_size : (int, int)
        The working (width, height), named in the message.

    Returns
    -------
    str or None
    """
    counts = [len(f[0].keypoints) for f in found]
    if sum(n >= needed for n in counts) >= 2:
        return None
    shown = ", ".join(f"{n} in '{label}'" for label, n in list(zip(labels, counts))[:4])
    more = f", ... ({len(counts)} images)" if len(counts) > 4 else ""
    return (f"too few keypoints to match: {shown}{more}, where a pair needs {needed}; are "
            f"the images blank, blurred or tiny? (working size {working_size[0]}x"
            f"{working_size[1]} px)")


def check_distinct_photos(keys: Sequence[bytes], keypoints: Sequence[int],
                           labels: Sequence[str]) -> None:
    """Raise ``ValueError`` when two views are one photo (the same keypoints and
    descriptors: a copy under another name), naming the images by their ``labels``
    (:func:`~scene3D.io.images.source_label`); views without keypoints are left to the
    reconstruction, which says they have too few.

    Parameters
    ----------
    keys : sequence of bytes
        Each view's content digest (:func:`scene3D.multiview.features.content_key`).
    keypoints : sequence of int
        Each view's number of keypoints.
    labels : sequence of str
        The images' names in messages.

    Raises
    ------
    ValueError
        Two views with keypoints and one digest.
    """
    first: dict[bytes, int] = {}
    for v, key in enumerate(keys):
        if keypoints[v] and first.setdefault(key, v) != v:
            raise ValueError(f"'{labels[v]}' and '{labels[first[key]]}' are the same photo (the "
                             "same keypoints): a view cannot pair with itself")


def check_distinct_names(images: Sequence[ImageSource], names: Sequence[str]) -> None:
    """Raise ``ValueError`` when two views share a name (files of one name in two
    folders): the result (``unregistered_reasons``) and its files name views by it.

    Parameters
    ----------
    images : sequence of path or ndarray
        The images (paths are named in the message).
    names : sequence of str
        Their names, one per image.

    Raises
    ------
    ValueError
        Two views of one name.
    """
    first: dict[str, int] = {}
    for v, name in enumerate(names):
        u = first.setdefault(name, v)
        if u != v:
            where = (f" ('{images[u]}', '{images[v]}')" if all(
                isinstance(images[w], (str, os.PathLike)) for w in (u, v)) else "")
            raise ValueError(f"two images are named '{name}'{where}: views are named by "
                             "file name; rename one or pass distinct `names`")
