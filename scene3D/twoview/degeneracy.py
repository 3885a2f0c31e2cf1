"""Two-view configurations that deceive a pose estimate, and how to recognise them.

- A camera that only turned: every match then fits a homography ``K R K^-1``,
  and an essential matrix fits them too, for any translation. Model selection
  (:func:`motion_model_choice`, Torr's GRIC) tells a pure rotation from a small
  real baseline; :func:`is_rotation_homography` checks a fitted homography. When
  the rotation explains most matches but not all, the translation rests on the
  few that show parallax: a camera that moved past a distant scene, or a camera
  that stood still while something in view moved (``rotation_share``).
- A planar scene: two poses fit the plane's matches (:func:`plane_poses`); only
  matches off the plane can choose (:func:`off_plane_evidence`), and
  :func:`lower_cost_plane_pose` lets them vote when random samples drew from the
  plane alone.

Frames as in :mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np

from ..geometry.conventions import (
    FloatArray,
    angle_between_deg,
    project_with_jacobian,
    rotation_error_deg,
    rotations_from_vectors,
    skews,
    to_homogeneous,
)
from ..geometry.epipolar import essential_distances, essential_from_pose
from ..geometry.triangulation import in_front_mask, triangulate_points
from .essential_fit import essential_cost, polish_essential


def is_rotation_homography(H: FloatArray, K: FloatArray, tolerance: float = 0.02) -> bool:
    """True when ``H`` is (close to) ``K R K^-1``, the homography of a camera that only turned.

    ``K^-1 H K`` is then a rotation up to scale: its singular values are equal
    (within ``tolerance``, relative). A plane seen from two centres gives
    ``R + t n^T / d`` instead, whose singular values differ by about ``|t| / d``.

    Parameters
    ----------
    H : (3, 3) array_like
        Homography ``x2 ~ H x1`` in pixels.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    tolerance : float, default 0.02
        Relative tolerance on the singular values' ratio.

    Returns
    -------
    bool
    """
    if not np.all(np.isfinite(H)):
        return False
    singular = np.linalg.svd(np.linalg.inv(K) @ H @ K, compute_uv=False)
    return bool(singular[0] / singular[2] - 1.0 < tolerance)


def plane_poses(H: FloatArray, K: FloatArray, pts1: FloatArray,
                pts2: FloatArray) -> list[tuple[FloatArray, FloatArray]]:
    """The physically valid poses ``(R, t)`` (``|t| = 1``) of a plane's homography.

    ``cv2.decomposeHomographyMat`` gives up to four; those that put the plane's
    points ``pts1, pts2`` ``(N, 2)`` in front of both cameras remain (two for a
    plane seen with a baseline, Faugeras & Lustman 1988).

    Parameters
    ----------
    H : (3, 3) array_like
        The plane's homography ``x2 ~ H x1`` in pixels.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    pts1, pts2 : (N, 2) array_like
        Pixels of the plane's matches.

    Returns
    -------
    list of ((3, 3), (3,)) float64 ndarray
        Poses ``x_cam2 = R x_cam1 + t``, ``|t| = 1``.
    """
    _, rotations, translations, _ = cv2.decomposeHomographyMat(H, K)
    poses = []
    for R, t in zip(rotations, translations):
        t = t.ravel()
        if np.linalg.norm(t) < 1e-12:
            continue
        t = t / np.linalg.norm(t)
        if in_front_mask(triangulate_points(pts1, pts2, K, R, t), R, t).mean() >= 0.5:
            poses.append((R, t))
    return poses


#: Matches that fit a homography (or an essential matrix) better than this (median,
#: pixels) fit better than any camera locates its keypoints (real planes, chessboards
#: photographed at 640x480, fit to 0.032 px and more): one image is the other warped
#: (shifted, scaled, rendered), not a second view.
COPY_RESIDUAL_PX = 0.01


def warped_copy_residual(H: FloatArray, pts1: FloatArray, pts2: FloatArray,
                         on_plane: np.ndarray, sampson_px: FloatArray) -> float | None:
    """How well matches that a homography mostly explains fit, when it is better than
    :data:`COPY_RESIDUAL_PX`: image 2 is then a warped copy of image 1, and a pose
    found on them, with sigmas near zero, describes no camera. Else None.

    The fit is the smaller of the median error under ``H`` of the matches ``pts1, pts2``
    ``(N, 2)`` it explains (``on_plane``) and the median of their Sampson distances
    ``sampson_px`` ``(N,)`` to the essential matrix, in pixels: ORB's whole-pixel
    keypoints of an image shifted along its rows miss the homography by their rounding,
    yet fit a sideways translation to 1e-8 px. Exact synthetic matches of a scene with
    depth fit an essential matrix as well, but no homography explains most of them.

    Parameters
    ----------
    H : (3, 3) array_like
        Homography ``x2 ~ H x1`` fitted to the matches.
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.
    on_plane : (N,) bool ndarray
        The matches ``H`` explains.
    sampson_px : (N,) array_like
        Sampson distances (px) to the essential matrix.

    Returns
    -------
    float or None
        The fit in px, or None.
    """
    errors = [float(np.median(np.abs(sampson_px)))]
    if np.all(np.isfinite(H)) and on_plane.any():
        errors.append(float(np.median(homography_errors(H, pts1[on_plane], pts2[on_plane]))))
    fit = min(errors)
    return fit if fit < COPY_RESIDUAL_PX else None


def off_plane_evidence(H: FloatArray, K: FloatArray, R: FloatArray, t: FloatArray,
                       pts1: FloatArray, pts2: FloatArray, on_plane: np.ndarray,
                       threshold_px: float) -> int:
    """How many matches off the plane rule out every other pose the plane allows.

    Two views of a plane admit two physically valid poses (:func:`plane_poses`):
    the plane's points cannot choose between them. Matches off the plane can: this
    counts those among ``pts1, pts2`` (inliers of the chosen pose ``(R, t)``) that
    are not ``on_plane`` and whose Sampson distance to the other valid pose
    exceeds ``threshold_px``; with several other poses, the smallest count. A
    large count means the pose is not ambiguous.

    Parameters
    ----------
    H : (3, 3)
        Homography of the plane, ``x2 ~ H x1``.
    R, t : (3, 3), (3,)
        The chosen pose, camera 2 from camera 1: ``x_cam2 = R x_cam1 + t``.
    pts1, pts2 : (N, 2)
        Inlier pixels of the chosen pose.
    on_plane : (N,) bool
        The matches ``H`` explains.
    """
    poses = plane_poses(H, K, pts1[on_plane], pts2[on_plane])
    # The plane's pose nearest to the chosen one is that pose; the others are the doubt.
    poses.sort(key=lambda pose: rotation_error_deg(pose[0], R) + angle_between_deg(pose[1], t))
    off = ~on_plane
    evidence = len(pts1)
    for R_other, t_other in poses[1:]:
        distances = essential_distances(essential_from_pose(R_other, t_other), pts1[off],
                                        pts2[off], K)
        evidence = min(evidence, int(np.sum(distances > threshold_px)))
    return evidence


def lower_cost_plane_pose(E: FloatArray, inliers: np.ndarray, on_plane: np.ndarray,
                           H: FloatArray, p1: FloatArray, p2: FloatArray, K: FloatArray,
                           threshold_px: float) -> tuple[FloatArray, np.ndarray] | None:
    """A pose of the plane, polished on all matches, that costs less than ``E``; else None.

    When one plane holds most matches, USAC's random samples come from the plane
    and its models may fit the plane alone, dropping the matches off it as
    outliers; starting the local optimisation from the plane's own poses lets those
    matches count (:func:`scene3D.twoview.essential_fit.polish_essential` gives the costs).
    ``inliers`` are those of ``E`` among ``p1, p2``; ``on_plane`` those of ``H``
    among them.

    Parameters
    ----------
    E : (3, 3) array_like
        The essential matrix found.
    inliers : (N,) bool ndarray
        Inliers of ``E`` among ``p1, p2``.
    on_plane : (n_inliers,) bool ndarray
        Inliers of ``H`` among ``E``'s inliers.
    H : (3, 3) array_like
        The plane's homography ``x2 ~ H x1``.
    p1, p2 : (N, 2) array_like
        All the correspondences (pixels, OpenCV convention).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).

    Returns
    -------
    (E, inliers) or None
        The better essential matrix ``(3, 3)`` and its ``(N,) bool`` inliers.
    """
    best_cost, better = essential_cost(E, p1, p2, K, threshold_px), None
    in1, in2 = p1[inliers], p2[inliers]
    for R, t in plane_poses(H, K, in1[on_plane], in2[on_plane]):
        cost, E_plane, plane_inliers = polish_essential(essential_from_pose(R, t), p1, p2, K,
                                                        threshold_px)
        if cost < best_cost:
            best_cost, better = cost, (E_plane, plane_inliers)
    return better


def _transfer(R: FloatArray, rays1: FloatArray, pts2: FloatArray,
              K: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Transfer residuals ``(2N,)`` of ``K R rays1`` against ``pts2`` and their Jacobian
    ``(2N, 3)`` by the rotation vector of ``R <- exp([w]x) R``, which moves ``y = R ray``
    by ``-[y]x w``."""
    y = rays1 @ R.T
    pixels, J = project_with_jacobian(y, K)
    return (pixels - pts2).ravel(), (J @ -skews(y)).reshape(-1, 3)


def _robust_rotation_cost(residuals: FloatArray, scale_px: float) -> float:
    return float(np.sum(np.log1p((residuals[0::2] ** 2 + residuals[1::2] ** 2) / scale_px**2)))


def fit_rotation(pts1: FloatArray, pts2: FloatArray, K: FloatArray, scale_px: float = 1.0,
                 H: FloatArray | None = None, iterations: int = 4) -> FloatArray:
    """The rotation ``R`` ``(3, 3)`` of a camera that only turned, ``x2 ~ K R K^-1 x1``.

    Robust: Gauss-Newton on the transfer errors in image 2 (pixels) reweighted by a
    Cauchy loss of scale ``scale_px``, so that matches the rotation cannot explain
    (a moving object, points near the camera) do not pull it. It starts from the
    better, in that robust cost, of two rotations: the one that best aligns all the
    viewing rays (Kabsch's SVD) and, given a homography ``H`` fitted to the same
    matches, the one nearest to ``K^-1 H K``. ``pts1, pts2`` ``(N, 2)`` (N >= 2) are
    matches, the inliers of the essential matrix.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    scale_px : float, default 1.0
        Scale of the Cauchy loss (px).
    H : (3, 3) array_like or None, default None
        Homography ``x2 ~ H x1`` fitted to the same matches, for a second start.
    iterations : int, default 4
        Gauss-Newton iterations.

    Returns
    -------
    (3, 3) float64 ndarray
        Rotation ``x_cam2 = R x_cam1``.
    """
    K_inv = np.linalg.inv(K)
    rays1 = to_homogeneous(pts1) @ K_inv.T
    rays2 = to_homogeneous(pts2) @ K_inv.T
    starts = [_nearest_rotation(_unit_rows(rays2).T @ _unit_rows(rays1))]
    if H is not None and np.all(np.isfinite(H)):
        starts.append(_nearest_rotation(K_inv @ H @ K))
    fits = [(R, *_transfer(R, rays1, pts2, K)) for R in starts]
    R, residuals, J = min(fits, key=lambda fit: _robust_rotation_cost(fit[1], scale_px))
    for _ in range(iterations):
        step = _cauchy_step(J, residuals, scale_px)
        if step is None:
            break
        R = rotations_from_vectors(step[None])[0] @ R
        residuals, J = _transfer(R, rays1, pts2, K)
    return R


def _cauchy_step(J: FloatArray, residuals: FloatArray, scale_px: float) -> FloatArray | None:
    """One reweighted Gauss-Newton step ``(k,)`` for transfer residuals ``(2N,)`` with
    Jacobian ``(2N, k)``, each match weighted by the Cauchy loss of scale ``scale_px``
    on its transfer error; None when the normal equations are singular."""
    squared = residuals[0::2] ** 2 + residuals[1::2] ** 2
    weights = np.repeat(1.0 / (1.0 + squared / scale_px**2), 2)
    Jw = J * weights[:, None]
    try:
        return -np.linalg.solve(Jw.T @ J, Jw.T @ residuals)
    except np.linalg.LinAlgError:
        return None


def _with_focal_scale(K: FloatArray, scale: float) -> FloatArray:
    """``K`` with its focal length (and skew) times ``scale``, the principal point kept."""
    Ks = K.copy()
    Ks[:2, :2] *= scale
    return Ks


def fit_rotation_and_focal(pts1: FloatArray, pts2: FloatArray, K: FloatArray,
                           scale_px: float, H: FloatArray | None = None,
                           max_log_scale: float = float(np.log(2.0)),
                           iterations: int = 6) -> tuple[FloatArray, float]:
    """The rotation ``R`` ``(3, 3)`` and focal-length factor ``s`` of a camera that only
    turned, ``x2 ~ K_s R K_s^-1 x1`` with ``K_s`` = ``K`` whose focal length is ``s``
    times ``K``'s (principal point kept): a pure rotation seen through a calibration
    for another zoom or lens, which an essential matrix explains with an invented
    translation.

    Robust as :func:`fit_rotation` (Cauchy loss of scale ``scale_px`` on the transfer
    errors); ``log s`` is kept within ``+-max_log_scale`` (beyond it the family tends to
    an image shift, which a translation past a distant plane explains too). It starts
    from the best of three factors (1, 0.7 and 1.4), each with its :func:`fit_rotation`,
    then Gauss-Newton on the rotation vector and ``log s`` (the ``log s`` column of the
    Jacobian by central differences).

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    scale_px : float
        Scale of the Cauchy loss (px).
    H : (3, 3) array_like or None, default None
        Homography ``x2 ~ H x1`` fitted to the same matches.
    max_log_scale : float, default log(2)
        Bound on ``|log s|``.
    iterations : int, default 6
        Gauss-Newton iterations.

    Returns
    -------
    R : (3, 3) float64 ndarray
        Rotation ``x_cam2 = R x_cam1``.
    s : float
        Focal-length factor.
    """
    def residuals(R: FloatArray, log_s: float) -> tuple[FloatArray, FloatArray]:
        Ks = _with_focal_scale(K, float(np.exp(log_s)))
        rays1 = to_homogeneous(pts1) @ np.linalg.inv(Ks).T
        return _transfer(R, rays1, pts2, Ks)

    starts = []
    for log_s in (0.0, np.log(0.7), np.log(1.4)):
        R = fit_rotation(pts1, pts2, _with_focal_scale(K, float(np.exp(log_s))), scale_px, H,
                         iterations=2)
        starts.append((_robust_rotation_cost(residuals(R, log_s)[0], scale_px), R, log_s))
    _, R, log_s = min(starts, key=lambda start: start[0])
    step_log_s = 1e-6
    for _ in range(iterations):
        r, J_rot = residuals(R, log_s)
        J_log_s = (residuals(R, log_s + step_log_s)[0]
                   - residuals(R, log_s - step_log_s)[0]) / (2 * step_log_s)
        step = _cauchy_step(np.column_stack([J_rot, J_log_s]), r, scale_px)
        if step is None:
            break
        R = rotations_from_vectors(step[None, :3])[0] @ R
        log_s = float(np.clip(log_s + step[3], -max_log_scale, max_log_scale))
    return R, float(np.exp(log_s))


def _unit_rows(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _nearest_rotation(M: FloatArray) -> FloatArray:
    """The rotation nearest to ``M`` ``(3, 3)`` in the Frobenius norm (SVD, det +1)."""
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def homography_errors(H: FloatArray, pts1: FloatArray, pts2: FloatArray) -> FloatArray:
    """Geometric errors ``(N,)`` in pixels of matches under a homography ``x2 ~ H x1``.

    ``|x2 - H x1| / sqrt(2)``: the distance of the match to the homography's
    variety, to first order where ``H`` is nearly an isometry (as a rotation's is
    near the image centre, and a plane's seen from nearby views), the noise shared
    by both images.

    Parameters
    ----------
    H : (3, 3) array_like
        Homography ``x2 ~ H x1`` in pixels.
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.

    Returns
    -------
    (N,) float64 ndarray
        Errors in px; inf where a point maps to infinity.
    """
    mapped = to_homogeneous(pts1) @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        transfer = np.linalg.norm(mapped[:, :2] / mapped[:, 2:3] - pts2, axis=1)
    return np.where(np.isfinite(transfer), transfer / np.sqrt(2.0), np.inf)


def gric(errors: FloatArray, sigma: float, dimension: int, parameters: int) -> float:
    """Torr's Geometric Robust Information Criterion of a two-view relation (lower is better).

    ``sum min(e^2 / sigma^2, 2 (4 - d)) + n d log 4 + k log(4 n)`` for ``n``
    matches (data of dimension 4) with errors ``e`` ``(n,)`` to a relation whose
    variety has dimension ``d`` and which has ``k`` parameters (P. Torr, "Geometric
    motion segmentation and model selection", Phil. Trans. R. Soc. A 356, 1998).
    The capped residual term keeps outliers from deciding.

    Parameters
    ----------
    errors : (n,) array_like
        Errors of the matches (px).
    sigma : float
        Noise standard deviation (px).
    dimension : int
        Dimension ``d`` of the relation's variety (3 for E, 2 for a homography).
    parameters : int
        Number ``k`` of the relation's parameters.

    Returns
    -------
    float
    """
    n = len(errors)
    z = (np.asarray(errors, dtype=np.float64) / sigma) ** 2
    return float(np.sum(np.minimum(z, 2.0 * (4 - dimension)))
                 + n * dimension * np.log(4.0) + parameters * np.log(4.0 * n))


class MotionModelChoice(NamedTuple):
    """What :func:`motion_model_choice` found.

    Attributes
    ----------
    essential_gric, rotation_gric, homography_gric : float
        GRIC of the essential matrix (variety of dimension 3, 5 parameters), of
        the rotation homography ``K R K^-1`` (dimension 2, 3 parameters) and of a
        general homography (dimension 2, 8 parameters).
    pure_rotation : bool
        The rotation explains the matches at least as well as the essential matrix,
        for its fewer parameters: there is no measurable baseline.
    planar : bool
        The general homography explains them at least as well: a plane (or a
        baseline too short to show the depth off it), where two poses can fit.
    rotation_share : float
        Share of the matches the rotation explains within three noise standard
        deviations: those that show no parallax. When they are most, a translation
        rests on the others, which a moving object would explain as well as a camera
        that moved.
    R : (3, 3) float64
        The fitted rotation, ``R_cam2_from_cam1`` (``x_cam2 = R x_cam1``).
    focal_rotation_share, focal_scale : float
        With ``free_focal``, the share of the matches that a rotation under a focal
        length ``focal_scale`` times ``K``'s explains within three noise standard
        deviations (:func:`fit_rotation_and_focal`), when its GRIC is lower than the
        rotation's under ``K``; else 0 and 1. It does not decide ``pure_rotation``: a
        free focal length also absorbs some of a small real baseline's parallax.
    """

    essential_gric: float
    rotation_gric: float
    homography_gric: float
    pure_rotation: bool
    planar: bool
    rotation_share: float
    R: FloatArray
    focal_rotation_share: float = 0.0
    focal_scale: float = 1.0

    @property
    def widest_rotation(self) -> tuple[float, float]:
        """``(share, focal factor)`` of the rotation that explains more of the matches:
        under ``K`` (factor 1) or under another focal length."""
        return max((self.rotation_share, 1.0), (self.focal_rotation_share, self.focal_scale))


def motion_model_choice(pts1: FloatArray, pts2: FloatArray, K: FloatArray,
                        sampson_px: FloatArray, noise_px: float,
                        H: FloatArray, free_focal: bool = False) -> MotionModelChoice:
    """Do a pure rotation or a homography explain the matches as well as an essential matrix?

    An essential matrix fits the matches of a camera that only turned for any
    translation, and those of a plane for two poses, so its fit alone cannot
    tell; a small real baseline and a pure rotation differ in whether the
    rotation homography leaves residuals beyond the noise, a scene with depth and
    a plane in whether the homography ``H`` (``x2 ~ H x1``, fitted to the same
    matches) does. The relations are compared by GRIC (:func:`gric`) on the inliers
    ``pts1, pts2`` ``(N, 2)`` of the essential matrix, with their Sampson distances
    ``sampson_px`` ``(N,)`` and the noise ``noise_px`` (pixels, per coordinate)
    measured on them.

    With ``free_focal``, the rotation is also fitted with a free focal length
    (:func:`fit_rotation_and_focal`, 4 parameters): a camera that only turned, given a
    calibration for another zoom, fits it, while the essential matrix explains its
    matches with an invented translation (the caller asks for it where a homography
    explains the matches, as the rotation's does).

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Inlier pixels of the essential matrix in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    sampson_px : (N,) array_like
        Their Sampson distances (px).
    noise_px : float
        Noise per coordinate (px).
    H : (3, 3) array_like
        Homography ``x2 ~ H x1`` fitted to the same matches.
    free_focal : bool, default False
        Also fit the rotation with a free focal length.

    Returns
    -------
    MotionModelChoice
    """
    sigma = noise_px
    R = fit_rotation(pts1, pts2, K, 3.0 * sigma, H)
    essential = gric(sampson_px, sigma, 3, 5)
    rotation_errors = homography_errors(K @ R @ np.linalg.inv(K), pts1, pts2)
    rotation = gric(rotation_errors, sigma, 2, 3)
    focal_share, focal_scale = 0.0, 1.0
    if free_focal:
        R_s, scale = fit_rotation_and_focal(pts1, pts2, K, 3.0 * sigma, H)
        Ks = _with_focal_scale(K, scale)
        errors_s = homography_errors(Ks @ R_s @ np.linalg.inv(Ks), pts1, pts2)
        if gric(errors_s, sigma, 2, 4) < rotation:
            focal_share, focal_scale = float(np.mean(errors_s <= 3.0 * sigma)), scale
    homography = (gric(homography_errors(H, pts1, pts2), sigma, 2, 8)
                  if np.all(np.isfinite(H)) else np.inf)
    return MotionModelChoice(essential, rotation, homography, rotation <= essential,
                             homography <= essential,
                             float(np.mean(rotation_errors <= 3.0 * sigma)), R, focal_share,
                             focal_scale)
