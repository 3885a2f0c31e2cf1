"""Several cameras in one reconstruction: photos of different cameras, sizes or zooms.

Each photo belongs to a camera (:func:`scene3D.geometry.intrinsics_prior.camera_groups`):
its own focal length, radial coefficients and image size, the principal point at the
centre of its images. The incremental mapper works with one intrinsic matrix, so the
views of every camera are brought into the pixels of one *reference camera* (the camera
of most views): a keypoint ``u`` of camera ``c`` (focal length ``f_c``, principal point
``c_c``, undistorted with its lens) becomes ``c_r + (u - c_c) f_r / f_c``, the pixel a
camera with the reference intrinsics ``(f_r, c_r)`` would have seen along the same ray
(:func:`reference_features`). The keypoint sizes scale alike, so the adjustments weigh
each camera's keypoints by their noise in those pixels.

A camera's focal length is a guess until the model has seen it: its first view is
registered with a focal search (:func:`pnp_focal_search`), and its views' keypoints are
rescaled with the focal length found (``GrowingModel.camera_scale``). Once the views
are reconstructed, every camera's focal length and coefficients are adjusted on the
photographed keypoints (:func:`refine_cameras`,
:func:`scene3D.optim.bundle_radial.bundle_adjust_cameras`) and the views reconstructed
again with those, as for one camera's lens (:mod:`scene3D.multiview.lens`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import cv2
import numpy as np

from ..geometry.conventions import FloatArray
from ..geometry.lens import distort_pixels, rescaled_coefficients, undistort_pixels
from ..optim.bundle import Observations
from ..optim.bundle_radial import CamerasAdjustment, bundle_adjust_cameras
from .models import reference_camera  # noqa: F401 - public here
from .sfm_model import SfMModel
from .view_data import ViewFeatures

#: Focal-length factors a camera's first view is tried with (:func:`pnp_focal_search`):
#: a guess from EXIF is within a few percent, the default ``1.2 x`` the longer side
#: within a factor of two for most photos.
SEARCH_SCALES = np.geomspace(0.4, 2.5, 25)

#: The coefficients' prior standard deviation, as for one camera
#: (:data:`scene3D.multiview.lens.K_PRIOR_SIGMA`).
K_PRIOR_SIGMA = 0.5


def to_reference_pixels(xy: FloatArray, K_camera: FloatArray, K_reference: FloatArray
                        ) -> FloatArray:
    """Pixels ``(N, 2)`` of a pinhole camera ``K_camera`` as the pinhole camera
    ``K_reference`` sees the same rays: ``c_r + (xy - c_c) f_r / f_c``.

    Parameters
    ----------
    xy : (N, 2) array_like
        Undistorted pixels of ``K_camera`` (OpenCV convention).
    K_camera, K_reference : (3, 3) array_like
        Square pixels, no skew.

    Returns
    -------
    (N, 2) float64 ndarray
    """
    K_camera, K_reference = np.asarray(K_camera, float), np.asarray(K_reference, float)
    scale = K_reference[0, 0] / K_camera[0, 0]
    return K_reference[:2, 2] + (np.asarray(xy, float) - K_camera[:2, 2]) * scale


def reference_features(features: Sequence[ViewFeatures], raw_keypoints: Sequence[FloatArray],
                       raw_sizes: Sequence[FloatArray | None], view_camera: np.ndarray,
                       K_cameras: FloatArray, k_cameras: FloatArray, K_reference: FloatArray
                       ) -> list[ViewFeatures]:
    """The views' features with their photographed keypoints undistorted by their
    camera's lens and put in the reference camera's pixels (:func:`to_reference_pixels`),
    their sizes scaled alike.

    Parameters
    ----------
    features : sequence of ViewFeatures
        The views' features.
    raw_keypoints : sequence of (N_v, 2) ndarray
        Each view's keypoints as photographed (its working pixels).
    raw_sizes : sequence of (N_v,) ndarray or None
        Each view's keypoint sizes as detected.
    view_camera : (V,) int ndarray
        The camera of each view.
    K_cameras : (C, 3, 3) array_like
        Each camera's intrinsics at its working size.
    k_cameras : (C, m) array_like
        Each camera's radial coefficients about its ``K`` (m may be 0).
    K_reference : (3, 3) array_like
        The pixels to map into.

    Returns
    -------
    list of ViewFeatures
    """
    out = []
    for f, raw, sizes, c in zip(features, raw_keypoints, raw_sizes, view_camera):
        K_c = K_cameras[c]
        undistorted = undistort_pixels(raw, K_c, k_cameras[c]) if np.any(k_cameras[c]) else raw
        scale = float(K_reference[0, 0] / K_c[0, 0])
        out.append(dataclasses.replace(
            f, keypoints=to_reference_pixels(undistorted, K_c, K_reference),
            sizes=None if sizes is None else sizes * scale))
    return out


def pnp_focal_search(points3d: FloatArray, xy: FloatArray, K: FloatArray,
                     threshold_px: float, scales: FloatArray = SEARCH_SCALES,
                     iterations: int = 100) -> tuple[float, int]:
    """The factor of ``K``'s focal length that best explains 2D-3D matches of a view
    whose focal length is not known: the most PnP inliers over ``scales``, then the
    least reprojection error near it.

    The pixels are scaled about the principal point by ``1 / s`` for each factor ``s``
    (the pixels a camera of ``s`` times the focal length would see, in ``K``'s), and a
    pose found by RANSAC; around the best factor, the pose is refined on its inliers at
    finer factors and the minimum of a parabola through the errors taken.

    Parameters
    ----------
    points3d : (M, 3) ndarray
        World points.
    xy : (M, 2) ndarray
        Their pixels in the view (OpenCV convention).
    K : (3, 3) ndarray
        The intrinsics the pixels are in (the guess).
    threshold_px : float
        RANSAC's inlier threshold.
    scales : (S,) ndarray
        Factors tried.
    iterations : int, default 100
        RANSAC iterations for each factor: the matches come from verified tracks, mostly
        inliers (with 30 % outliers, 100 find the factor as well as 500, five times
        faster).

    Returns
    -------
    scale : float
        The factor (1 when no factor gives a pose).
    inliers : int
        Inliers at the best coarse factor.
    """
    c = K[:2, 2]
    best = (0, 1.0, None)
    points3d = np.ascontiguousarray(points3d, np.float64)
    for s in scales:
        img = np.ascontiguousarray(c + (xy - c) / s)
        ok, rvec, tvec, inliers = cv2.solvePnPRansac(
            points3d, img, K, None, iterationsCount=iterations,
            reprojectionError=threshold_px, confidence=0.999, flags=cv2.SOLVEPNP_SQPNP)
        if ok and inliers is not None and len(inliers) > best[0]:
            best = (len(inliers), float(s), (rvec, tvec, inliers.ravel()))
    count, scale, found = best
    if found is None or count < 6:
        return 1.0, count
    rvec, tvec, inl = found
    step = float(scales[1] / scales[0]) if len(scales) > 1 else 1.1
    fine = scale * np.geomspace(1 / step, step, 9)
    errors = []
    for s in fine:
        img = np.ascontiguousarray(c + (xy[inl] - c) / s)
        r, t = cv2.solvePnPRefineLM(points3d[inl], img, K, None, rvec.copy(), tvec.copy())
        projected = cv2.projectPoints(points3d[inl], r, t, K, None)[0].reshape(-1, 2)
        # In the view's own pixels (times s), so that factors compare alike.
        errors.append(float(np.median(np.linalg.norm(projected - img, axis=1))) * s)
    errors = np.asarray(errors)
    i = int(np.argmin(errors))
    if 0 < i < len(fine) - 1:  # the parabola's vertex in log s
        x = np.log(fine[i - 1:i + 2])
        a, b, _ = np.polyfit(x, errors[i - 1:i + 2], 2)
        if a > 0:
            return float(np.exp(np.clip(-b / (2 * a), x[0], x[2]))), count
    return float(fine[i]), count


@dataclasses.dataclass(frozen=True)
class CameraPass:
    """The cameras one pass of the mapper used, per camera ``(C,)``.

    Attributes
    ----------
    K : (C, 3, 3)
        Intrinsics at each camera's working size the keypoints were mapped with.
    k : (C, m)
        Radial coefficients they were undistorted with.
    known : (C,) bool
        Cameras whose focal length a previous pass estimated (no focal search).
    """

    K: FloatArray
    k: FloatArray
    known: np.ndarray


def model_cameras(model: SfMModel, used: CameraPass, K_reference: FloatArray
                  ) -> FloatArray:
    """The intrinsics ``(C, 3, 3)`` a model's views imply for each camera: its focal
    length from the model's and the rescaling its views had (``model.camera_scale``).

    Parameters
    ----------
    model : SfMModel
        A model made with the cameras ``used``.
    used : CameraPass
        The cameras its keypoints were mapped with.
    K_reference : (3, 3) ndarray
        The reference pixels the keypoints were mapped into.

    Returns
    -------
    (C, 3, 3) float64 ndarray
    """
    K_model = model.K if model.K is not None else K_reference
    scale = np.ones(len(used.K)) if model.camera_scale is None else model.camera_scale
    out = used.K.copy()
    out[:, 0, 0] = out[:, 1, 1] = (K_model[0, 0] * used.K[:, 0, 0]
                                   / (K_reference[0, 0] * scale))
    return out


def implied_coefficients(used: CameraPass, K_cameras: FloatArray) -> FloatArray:
    """The radial coefficients ``(C, m)`` of the cameras ``used`` about the focal lengths
    of ``K_cameras``: the same lens (:func:`scene3D.geometry.lens.rescaled_coefficients`).

    Parameters
    ----------
    used : CameraPass
        The cameras the keypoints were undistorted with.
    K_cameras : (C, 3, 3) ndarray
        The focal lengths to express them about (:func:`model_cameras`).

    Returns
    -------
    (C, m) float64 ndarray
    """
    if not used.k.shape[1]:
        return used.k.copy()
    return np.stack([rescaled_coefficients(used.k[c], float(used.K[c, 0, 0]),
                                           float(K_cameras[c, 0, 0]))
                     for c in range(len(used.K))])


def camera_pixels(model: SfMModel, view_camera: np.ndarray, K_model: FloatArray,
                  K_cameras: FloatArray) -> Observations:
    """A model's observations in each view's own (undistorted) working pixels, from the
    reference pixels ``K_model`` describes.

    Parameters
    ----------
    model : SfMModel
        Observations in the reference pixels, with its own ``K_model``.
    view_camera : (V,) int ndarray
        The camera of each view.
    K_model : (3, 3) ndarray
        The model's intrinsics (in the reference pixels).
    K_cameras : (C, 3, 3) ndarray
        Each camera's intrinsics the model implies (:func:`model_cameras`).

    Returns
    -------
    Observations
    """
    obs = model.observations
    K_obs = K_cameras[view_camera[obs.view]]
    scale = (K_obs[:, 0, 0] / K_model[0, 0])[:, None]
    xy = K_obs[:, :2, 2] + (obs.xy - K_model[:2, 2]) * scale
    sigma = None if obs.sigma is None else obs.sigma * scale[:, 0]
    return Observations(obs.view, obs.point, xy, sigma)


def refine_cameras(model: SfMModel, view_camera: np.ndarray, used: CameraPass,
                   K_reference: FloatArray, prior_focal_px: FloatArray,
                   prior_sigma_log: FloatArray) -> CamerasAdjustment:
    """Every camera's focal length and radial coefficients a model calls for, on the
    photographed keypoints (:func:`scene3D.optim.bundle_radial.bundle_adjust_cameras`),
    starting from the cameras the model implies (:func:`model_cameras`).

    Parameters
    ----------
    model : SfMModel
        Made with the cameras ``used``.
    view_camera : (V,) int ndarray
        The camera of each view.
    used : CameraPass
        The cameras the keypoints were mapped with.
    K_reference : (3, 3) ndarray
        The reference pixels.
    prior_focal_px, prior_sigma_log : (C,) ndarray
        Each camera's focal-length prior at its working size.

    Returns
    -------
    CamerasAdjustment
        ``K`` and ``k`` about each camera's image centre; a camera the model does not see
        keeps its start.
    """
    K_model = model.K if model.K is not None else K_reference
    K_start = model_cameras(model, used, K_reference)
    obs = camera_pixels(model, view_camera, K_model, K_start)
    k_start = implied_coefficients(used, K_start)
    raw_xy = obs.xy.copy()
    for c in range(len(used.K)):
        rows = view_camera[obs.view] == c
        if rows.any() and used.k.shape[1]:
            raw_xy[rows] = distort_pixels(obs.xy[rows], K_start[c], k_start[c])
    raw = Observations(obs.view, obs.point, raw_xy, obs.sigma)
    views = np.flatnonzero(model.registered)
    reference = int(views[np.argmin(np.linalg.norm(model.t[views], axis=1))])
    return bundle_adjust_cameras(model.R, model.t, model.points3d, raw, K_start, k_start,
                                 view_camera, reference, prior_focal_px, prior_sigma_log,
                                 K_PRIOR_SIGMA)


def corner_change_px(K_a: FloatArray, k_a: FloatArray, K_b: FloatArray, k_b: FloatArray,
                     image_size: tuple[int, int]) -> float:
    """How far the rays of the image corners move from camera ``(K_a, k_a)`` to camera
    ``(K_b, k_b)``, in pixels of ``K_b`` at the farthest corner: a change of focal length
    and of lens alike.

    Parameters
    ----------
    K_a, K_b : (3, 3) array_like
        Square pixels, no skew.
    k_a, k_b : (m,) array_like
        Radial coefficients (:mod:`scene3D.geometry.lens`), m may be 0.
    image_size : (int, int)
        ``(width, height)`` in px.

    Returns
    -------
    float
    """
    w, h = image_size
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]])

    def rays(K: FloatArray, k: FloatArray) -> FloatArray:
        K = np.asarray(K, np.float64)
        return (undistort_pixels(corners, K, k) - K[:2, 2]) / K[0, 0]

    return float(np.max(np.linalg.norm(rays(K_a, k_a) - rays(K_b, k_b), axis=1))
                 * float(np.asarray(K_b)[0, 0]))
