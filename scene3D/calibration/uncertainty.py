"""How far to trust a calibration across the image: covariance of the intrinsics and the
projection-uncertainty map (pure functions).

A calibration estimates the intrinsics ``theta`` (``fx, fy, cx, cy`` and the distortion
coefficients) together with one board pose per view by least squares on the corner
reprojection residuals. With corner noise of standard deviation ``sigma`` (estimated from the
residuals), the first-order covariance of all parameters is ``sigma^2 (J^T J)^-1``
(Hartley & Zisserman, section 5.2.3). :func:`intrinsics_covariance` forms the Jacobian
``J`` of every residual with respect to the intrinsics and every view's pose (the blocks
``cv2.projectPoints`` returns) and marginalises the poses out with the Schur complement::

    S = A - sum_i B_i D_i^-1 B_i^T,    Sigma_theta = sigma^2 S^-1

where ``A = J_theta^T J_theta``, ``B_i = J_theta,i^T J_pose,i`` and
``D_i = J_pose,i^T J_pose,i``. Its diagonal equals the standard deviations OpenCV's
``calibrateCameraExtended`` reports; the off-diagonal terms (fx with fy, the principal
point with the tangential coefficients, k1 with k2 and k3) are what the map needs.

What the map shows
------------------
For an image position ``q``, take the ray ``d(q)`` through it under the estimated intrinsics
(a point at any distance on it, in the **camera frame**) and project that point with
intrinsics drawn from ``N(theta, Sigma_theta)``. To first order the projection moves by
``G dtheta`` with ``G = d project(d; theta) / d theta`` (2 x P), so its covariance is
``G Sigma_theta G^T`` (2 x 2). The map is the square root of the larger eigenvalue of that
matrix: the 1 sigma projection error in the worst direction, in pixels (mrcal's
``worstdirection-stdev``). Pure intrinsics do not depend on the distance along the ray, so
neither does the map.

What it does not show (mrcal's method, for comparison): a fixed point *in the camera
frame* is itself uncertain, because the camera frame is only known through the same
calibration. A change of the principal point, say, can be nearly undone by turning every
board pose the other way, so the data constrain "where a world point projects" better than
"where a camera-frame point projects". mrcal (``mrcal.projection_uncertainty``) therefore maps
the query point into the boards' frames with the nominal poses and back with the perturbed
ones (mean-frames; cross-reprojection from mrcal 3.0), which removes that part and makes its
result depend on the distance. This map keeps it: it is the uncertainty of using the
intrinsics alone, as every other scene3D step does (undistortion, ``K`` in two-view
geometry), and it is an upper bound on mrcal's figure for the same data, most so near the
centre. Model errors (a lens the 5-coefficient model does not fit, a bent board) are not
in it either: it is the effect of the corner noise alone.

Pixels follow :mod:`scene3D.geometry`; sizes are (width, height).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike

from ..geometry.camera import DISTORTION_NAMES
from ..geometry.conventions import FloatArray

logger = logging.getLogger(__name__)

__all__ = [
    "IntrinsicsCovariance", "UncertaintyMap", "intrinsics_covariance",
    "format_px", "projection_covariance", "projection_sigma_px", "reached_by_rays",
    "uncertainty_map",
]

INTRINSIC_NAMES = ("fx", "fy", "cx", "cy")
#: Default limit (px) above which the corners of the map earn a warning.
CORNER_LIMIT_PX = 1.0
#: A pixel whose ray projects back farther than this is not reached by any ray
#: (:func:`reached_by_rays`): the inversion converges to 1e-6 px where a ray exists.
ROUND_TRIP_TOLERANCE_PX = 0.1

_FIXED_BY_FLAG = (
    (cv2.CALIB_FIX_PRINCIPAL_POINT, ("cx", "cy")),
    (cv2.CALIB_FIX_FOCAL_LENGTH, ("fx", "fy")),
    (cv2.CALIB_ZERO_TANGENT_DIST, ("p1", "p2")),
    (cv2.CALIB_FIX_K1, ("k1",)), (cv2.CALIB_FIX_K2, ("k2",)), (cv2.CALIB_FIX_K3, ("k3",)),
    (cv2.CALIB_FIX_K4, ("k4",)), (cv2.CALIB_FIX_K5, ("k5",)), (cv2.CALIB_FIX_K6, ("k6",)),
    (cv2.CALIB_FIX_S1_S2_S3_S4, ("s1", "s2", "s3", "s4")),
    (cv2.CALIB_FIX_TAUX_TAUY, ("tx", "ty")),
)


@dataclass(frozen=True)
class IntrinsicsCovariance:
    """First-order covariance of the intrinsics, the board poses marginalised out.

    Attributes
    ----------
    names : tuple[str, ...]
        The parameters in OpenCV's order: ``fx, fy, cx, cy`` then the distortion
        coefficients (``k1, k2, p1, p2, k3``, ...), as many as the calibration has.
    covariance : (P, P) float64
        Covariance in that order. Parameters held fixed by the calibration flags have
        zero rows and columns.
    residual_sigma_px : float
        Corner noise estimated from the residuals, ``sqrt(|r|^2 / dof)``, per coordinate.
    dof : int
        Degrees of freedom: residual coordinates minus free parameters (intrinsics and
        six per view).
    """

    names: tuple[str, ...]
    covariance: FloatArray
    residual_sigma_px: float
    dof: int

    def std(self) -> dict[str, float]:
        """Standard deviation of each parameter."""
        return {n: float(np.sqrt(max(v, 0.0))) for n, v in zip(self.names,
                                                             np.diag(self.covariance))}


def _parameterisation(names: Sequence[str], K: FloatArray, flags: int) -> FloatArray:
    """``T`` with ``dtheta = T dphi``: the free parameters ``phi`` of a calibration with
    ``flags`` (fixed ones dropped; with ``CALIB_FIX_ASPECT_RATIO`` one focal parameter
    moving ``fx`` and ``fy`` together)."""
    supported = cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_USE_INTRINSIC_GUESS | \
        cv2.CALIB_RATIONAL_MODEL | cv2.CALIB_THIN_PRISM_MODEL | cv2.CALIB_TILTED_MODEL
    for flag, _ in _FIXED_BY_FLAG:
        supported |= flag
    if flags & ~supported:
        raise ValueError(f"`flags` {flags} include calibration flags the covariance does "
                         "not model")
    fixed = {n for flag, fixed_names in _FIXED_BY_FLAG if flags & flag for n in fixed_names}
    columns = []
    index = {n: i for i, n in enumerate(names)}
    if flags & cv2.CALIB_FIX_ASPECT_RATIO and not flags & cv2.CALIB_FIX_FOCAL_LENGTH:
        col = np.zeros(len(names))
        col[index["fx"]], col[index["fy"]] = 1.0, K[1, 1] / K[0, 0]
        columns.append(col)
        fixed |= {"fx", "fy"}
    for name in names:
        if name not in fixed:
            col = np.zeros(len(names))
            col[index[name]] = 1.0
            columns.append(col)
    return np.column_stack(columns)


def intrinsics_covariance(
    object_points: Sequence[ArrayLike],
    image_points: Sequence[ArrayLike],
    K: ArrayLike,
    dist: ArrayLike,
    rvecs: Sequence[ArrayLike],
    tvecs: Sequence[ArrayLike],
    flags: int = 0,
) -> IntrinsicsCovariance:
    """Covariance of the intrinsics of a calibration, its board poses marginalised out.

    Parameters
    ----------
    object_points : sequence of (N_i, 3) array_like
        Board corners of each view (board frame).
    image_points : sequence of (N_i, 2) array_like
        Their detected pixels.
    K : (3, 3) array_like
    dist : (n,) array_like
        The calibrated intrinsics and distortion (the optimum).
    rvecs, tvecs : sequence of (3,) array_like
        The calibrated board-to-camera pose of each view.
    flags : int
        The ``cv2.CALIB_*`` flags of the calibration: parameters they fix are not free.

    Returns
    -------
    IntrinsicsCovariance

    Raises
    ------
    ValueError
        Mismatched inputs, too few residuals for the parameters, or flags not modelled.

    Notes
    -----
    ``J^T J`` is assembled from ``cv2.projectPoints``'s Jacobian blocks; each view's pose is
    eliminated by its 6 x 6 block (Schur complement), and the noise variance is
    ``|r|^2 / (2 M - P - 6 V)`` for ``M`` corners, ``P`` free intrinsics and ``V`` views
    (the unbiased estimate; H&Z section 5.1.3).
    """
    K = np.asarray(K, dtype=np.float64)
    dist = np.asarray(dist, dtype=np.float64).ravel()
    if not (len(object_points) == len(image_points) == len(rvecs) == len(tvecs)):
        raise ValueError("`object_points`, `image_points`, `rvecs` and `tvecs` must have one "
                         f"entry per view, got {len(object_points)}, {len(image_points)}, "
                         f"{len(rvecs)} and {len(tvecs)}")
    if len(dist) not in (4, 5, 8, 12, 14):
        raise ValueError(f"`dist` must have 4, 5, 8, 12 or 14 coefficients, got {len(dist)}")
    names = INTRINSIC_NAMES + DISTORTION_NAMES[: len(dist)]
    T = _parameterisation(names, K, flags)
    num_free = T.shape[1]
    S = np.zeros((num_free, num_free))
    sum_sq, num_residuals = 0.0, 0
    for obj, img, rvec, tvec in zip(object_points, image_points, rvecs, tvecs):
        obj = np.asarray(obj, dtype=np.float64).reshape(-1, 3)
        img = np.asarray(img, dtype=np.float64).reshape(-1, 2)
        if len(obj) != len(img):
            raise ValueError(f"a view has {len(obj)} board points but {len(img)} pixels")
        projected, jac = cv2.projectPoints(obj, np.asarray(rvec, np.float64).reshape(3),
                                           np.asarray(tvec, np.float64).reshape(3), K, dist)
        residuals = projected.reshape(-1, 2) - img
        sum_sq += float(np.sum(residuals ** 2))
        num_residuals += residuals.size
        J_pose = jac[:, :6]
        J_theta = jac[:, 6:6 + len(names)] @ T
        B = J_theta.T @ J_pose
        D = J_pose.T @ J_pose
        S += J_theta.T @ J_theta - B @ np.linalg.solve(D, B.T)
    dof = num_residuals - num_free - 6 * len(rvecs)
    if dof <= 0:
        raise ValueError(f"{num_residuals} residuals cannot determine {num_free} intrinsics "
                         f"and {len(rvecs)} poses")
    sigma2 = sum_sq / dof
    # Scaled to a unit diagonal before the inversion: fx (hundreds of pixels) and k3 (a
    # coefficient of r^6) differ by orders of magnitude, and unscaled, the pseudo-inverse
    # took a barely determined k3 (a telephoto lens, r < 0.1) for an undetermined
    # direction and gave it a variance of 0 (k3 -17066 +- 0.10 where the truth is 0).
    S = 0.5 * (S + S.T)
    scale = np.sqrt(np.maximum(np.diag(S), np.finfo(float).tiny))
    cov_free = sigma2 * np.linalg.pinv(S / np.outer(scale, scale)) / np.outer(scale, scale)
    covariance = T @ cov_free @ T.T
    return IntrinsicsCovariance(names, covariance, float(np.sqrt(sigma2)), int(dof))


def _rays(pixels: FloatArray, K: FloatArray, dist: FloatArray) -> FloatArray:
    """Camera-frame directions ``(N, 3)`` (z = 1) of the rays through ``pixels``."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    normalised = cv2.undistortPoints(pixels.reshape(-1, 1, 2), K, dist, None, np.eye(3), np.eye(3),
                                     criteria).reshape(-1, 2)
    return np.column_stack([normalised, np.ones(len(normalised))])


def projection_covariance(pixels: ArrayLike, K: ArrayLike, dist: ArrayLike,
                          covariance: IntrinsicsCovariance) -> FloatArray:
    """Covariance ``(N, 2, 2)`` of the projection of the camera-frame point seen at each pixel.

    Parameters
    ----------
    pixels : (N, 2) array_like
        Image positions (pixels of the calibrated size).
    K, dist : the calibration's intrinsics and distortion
    covariance : IntrinsicsCovariance
        Of the same calibration (:func:`intrinsics_covariance`).

    Notes
    -----
    See the module docstring: the point on the ray of each pixel, fixed in the camera
    frame, projected under intrinsics with this covariance, to first order.
    """
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    K = np.asarray(K, dtype=np.float64)
    dist = np.asarray(dist, dtype=np.float64).ravel()
    if len(covariance.names) != 4 + len(dist):
        raise ValueError(f"the covariance is for {len(covariance.names) - 4} distortion "
                         f"coefficients, `dist` has {len(dist)}")
    rays = _rays(pixels, K, dist)
    _, jac = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, dist)
    G = jac[:, 6:6 + len(covariance.names)].reshape(len(pixels), 2, -1)
    return G @ covariance.covariance @ G.transpose(0, 2, 1)


def projection_sigma_px(pixels: ArrayLike, K: ArrayLike, dist: ArrayLike,
                        covariance: IntrinsicsCovariance) -> FloatArray:
    """1 sigma projection error in the worst direction ``(N,)``, pixels: the square root of
    the larger eigenvalue of :func:`projection_covariance`.

    Parameters
    ----------
    pixels : (N, 2) array_like
        Image positions (pixels of the calibrated size).
    K : (3, 3) array_like
        The calibration's intrinsics.
    dist : (n,) array_like
        Its OpenCV distortion coefficients.
    covariance : IntrinsicsCovariance
        Of the same calibration.

    Returns
    -------
    (N,) float64 ndarray
    """
    return worst_direction_sigma(projection_covariance(pixels, K, dist, covariance))


def worst_direction_sigma(cov2: ArrayLike) -> FloatArray:
    """Square root of the larger eigenvalue of each ``(..., 2, 2)`` covariance.

    Parameters
    ----------
    cov2 : (..., 2, 2) array_like
        Covariances (px^2).

    Returns
    -------
    (...) float64 ndarray
    """
    cov2 = np.asarray(cov2, dtype=np.float64)
    a, b, c = cov2[..., 0, 0], 0.5 * (cov2[..., 0, 1] + cov2[..., 1, 0]), cov2[..., 1, 1]
    largest = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b ** 2)
    return np.sqrt(np.maximum(largest, 0.0))


@dataclass(frozen=True)
class UncertaintyMap:
    """The projection uncertainty sampled over the image.

    Attributes
    ----------
    xs : (W',) float64
    ys : (H',) float64
        Pixel coordinates of the grid's columns and rows (from 0 to ``width - 1`` and
        ``height - 1``: the grid includes the image corners).
    sigma_px : (H', W') float64
        1 sigma worst-direction projection error at each grid position, pixels; NaN
        where no ray reaches the position (:attr:`unreachable_share`).
    image_size : tuple[int, int]
        (width, height).
    limit_px : float
        The limit the warnings use.
    """

    xs: FloatArray
    ys: FloatArray
    sigma_px: FloatArray
    image_size: tuple[int, int]
    limit_px: float = CORNER_LIMIT_PX

    @property
    def unreachable_share(self) -> float:
        """The share of the grid that no ray reaches: the fitted distortion folds back
        inside the image (it grows, then shrinks, with the distance from the centre), so
        its pixels beyond the fold have no ray, and the calibration does not hold there."""
        return float(np.mean(np.isnan(self.sigma_px)))

    @property
    def median_px(self) -> float:
        """Median over the image (where rays reach)."""
        return float(np.nanmedian(self.sigma_px)) if self.unreachable_share < 1 else np.nan

    @property
    def worst_px(self) -> float:
        """Largest value over the image (where rays reach)."""
        return float(np.nanmax(self.sigma_px)) if self.unreachable_share < 1 else np.nan

    @property
    def centre_px(self) -> float:
        """At the grid position nearest the image centre."""
        w, h = self.image_size
        return float(self.sigma_px[np.argmin(np.abs(self.ys - (h - 1) / 2)),
                                   np.argmin(np.abs(self.xs - (w - 1) / 2))])

    @property
    def corners_px(self) -> dict[str, float]:
        """At the four image corners (top-left, top-right, bottom-right, bottom-left)."""
        s = self.sigma_px
        return {"top-left": float(s[0, 0]), "top-right": float(s[0, -1]),
                "bottom-right": float(s[-1, -1]), "bottom-left": float(s[-1, 0])}

    @property
    def warnings(self) -> list[str]:
        """Warnings: the distortion folds inside the image; the uncertainty exceeds
        ``limit_px`` at the centre too (the intrinsics themselves are poorly determined),
        or only at image corners (the corners lack views)."""
        warnings = []
        if self.unreachable_share > 0:
            lost = [k for k, v in self.corners_px.items() if np.isnan(v)]
            warnings.append(
                f"the fitted distortion folds back inside the image: no ray reaches "
                f"{self.unreachable_share:.1%} of it"
                + (f" (the {', '.join(lost)} corner{'s' if len(lost) > 1 else ''})"
                   if lost else "")
                + ", where the calibration does not hold; add views with the board there")
        listing = ", ".join(f"{k} {v:.2f} px" for k, v in self.corners_px.items()
                            if v > self.limit_px)
        if self.centre_px > self.limit_px:
            warnings.append(
                f"the projection uncertainty exceeds {self.limit_px:g} px even at the image "
                f"centre ({self.centre_px:.2f} px" + (f"; {listing}" if listing else "")
                + "): the focal length and principal point themselves are poorly "
                "determined; add views with the board tilted (by 20-45 degrees) and "
                "filling more of the image")
        elif listing:
            warnings.append(f"the projection uncertainty at the image corners exceeds "
                            f"{self.limit_px:g} px ({listing}): add views with the board in "
                            "the corners")
        return warnings


def uncertainty_map(K: ArrayLike, dist: ArrayLike, covariance: IntrinsicsCovariance,
                    image_size: tuple[int, int], step_px: float | None = None,
                    limit_px: float = CORNER_LIMIT_PX) -> UncertaintyMap:
    """:func:`projection_sigma_px` on a grid over the whole image, corners included.

    Parameters
    ----------
    K, dist, covariance : the calibration and :func:`intrinsics_covariance`
    image_size : tuple[int, int]
        (width, height) of the calibration.
    step_px : float, optional
        Grid spacing (default: a 65-column grid, ``(width - 1) / 64``).
    limit_px : float
        Limit for the corner warning (default 1 px).
    """
    w, h = int(image_size[0]), int(image_size[1])
    if w < 2 or h < 2:
        raise ValueError(f"`image_size` must be at least 2x2, got {image_size}")
    step = (w - 1) / 64 if step_px is None else float(step_px)
    if not step > 0:
        raise ValueError(f"`step_px` must be positive, got {step_px}")
    xs = np.linspace(0.0, w - 1.0, max(2, int(np.ceil((w - 1) / step)) + 1))
    ys = np.linspace(0.0, h - 1.0, max(2, int(np.ceil((h - 1) / step)) + 1))
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    sigma = projection_sigma_px(grid, K, dist, covariance)
    sigma[~reached_by_rays(grid, K, dist)] = np.nan
    return UncertaintyMap(xs, ys, sigma.reshape(len(ys), len(xs)), (w, h), float(limit_px))


def format_px(value: float) -> str:
    """A map value in pixels for people: ``"0.42 px"``, or ``"no ray"`` where none
    reaches (NaN: :attr:`UncertaintyMap.unreachable_share`).

    Parameters
    ----------
    value : float
        A value in px, or NaN.

    Returns
    -------
    str
    """
    return "no ray" if np.isnan(value) else f"{value:.2f} px"


def reached_by_rays(pixels: ArrayLike, K: ArrayLike, dist: ArrayLike,
                    tolerance_px: float = ROUND_TRIP_TOLERANCE_PX) -> np.ndarray:
    """Which ``pixels`` ``(N, 2)`` some ray projects to under ``K, dist``: ``(N,) bool``.

    The ray through a pixel is found by inverting the distortion
    (``cv2.undistortPoints``) and projected back; a pixel that the distortion folds away
    (beyond where the distorted radius stops growing) comes back elsewhere, by pixels.

    Parameters
    ----------
    pixels : (N, 2) array_like
        Image positions (OpenCV pixels).
    K : (3, 3) array_like
        Intrinsics.
    dist : (n,) array_like
        OpenCV distortion coefficients.
    tolerance_px : float, default ROUND_TRIP_TOLERANCE_PX
        Largest round-trip error (px).

    Returns
    -------
    (N,) bool ndarray
    """
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    K = np.asarray(K, dtype=np.float64)
    dist = np.asarray(dist, dtype=np.float64).ravel()
    back, _ = cv2.projectPoints(_rays(pixels, K, dist), np.zeros(3), np.zeros(3), K, dist)
    return np.linalg.norm(back.reshape(-1, 2) - pixels, axis=1) <= tolerance_px
