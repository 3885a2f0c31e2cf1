"""The pose parametrisation of scene3D's refinements and pose uncertainties.

A relative pose ``(R, t)`` (``x_cam2 = R x_cam1 + t``, ``|t| = 1``) has five degrees
of freedom. Near an estimate ``(R, t)`` the poses are written with a 5-vector
``x = (w, d)``, the step that scene3D's refinements take
(:func:`scene3D.optim.refinement.refine_relative_pose`; :func:`update_pose` applies it):

- ``R(x) = exp([w]x) R``: ``w`` (3,) is a rotation vector in radians, in the
  camera-2 frame (the rotation is applied after ``R``, on the left);
- ``t(x) = (t + d @ B) / |t + d @ B|``: ``d`` (2,) is a step in the plane tangent
  to the unit sphere at ``t``, along the two rows of ``B = tangent_basis(t)``
  ``(2, 3)`` (orthonormal, orthogonal to ``t``, camera-2 frame). To first order
  ``|d|`` is the angle in radians between ``t(x)`` and ``t``.

A pose covariance ``(5, 5)`` is the covariance of ``x``: rows and columns 0-2 the
rotation, 3-4 the translation direction (with the basis ``B`` it refers to).

A pose error (:func:`pose_error_coordinates`) is written in the same coordinates,
so that :mod:`scene3D.optim.uncertainty` can weigh it with the pose's covariance.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, rotations_from_vectors, skew


def tangent_basis(t: ArrayLike) -> FloatArray:
    """Two unit vectors ``(2, 3)`` orthogonal to the unit vector ``t`` and to each other.

    The basis of the translation-direction step of the pose parametrisation (module
    docstring); a deterministic function of ``t``.

    Parameters
    ----------
    t : (3,) array_like
        Translation direction (normalised here).

    Returns
    -------
    (2, 3) float64 ndarray
    """
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    helper = np.eye(3)[int(np.argmin(np.abs(t)))]
    b1 = skew(t) @ helper
    b1 /= np.linalg.norm(b1)
    return np.vstack([b1, skew(t) @ b1])


def update_pose(
    R: FloatArray, t: FloatArray, dx: FloatArray, basis: FloatArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """Apply a step ``x = (w, d)`` of the pose parametrisation (module docstring) to ``(R, t)``.

    Parameters
    ----------
    R : (3, 3) array
        ``R_cam2_from_cam1``.
    t : (3,) array
        Unit translation, ``x_cam2 = R x_cam1 + t``.
    dx : (5,) array
        Rotation vector ``w`` (3, radians, camera-2 frame), then the tangent step ``d`` (2).
    basis : (2, 3) array, optional
        The tangent basis of ``t`` the step refers to; :func:`tangent_basis` ``(t)`` by default.

    Returns
    -------
    R, t : (3, 3), (3,) float64
        ``exp([w]x) R`` and ``(t + d @ basis) / |t + d @ basis|``.
    """
    basis = tangent_basis(t) if basis is None else basis
    R_new = rotations_from_vectors(dx[None, :3])[0] @ R
    t_new = t + dx[3:] @ basis
    return R_new, t_new / np.linalg.norm(t_new)


def rotation_vector(R: ArrayLike) -> FloatArray:
    """The rotation vector ``w`` (3,) with ``exp([w]x) = R`` (radians, angle below pi).

    Parameters
    ----------
    R : (3, 3) array_like
        Rotation matrix.

    Returns
    -------
    (3,) float64 ndarray
    """
    R = np.asarray(R, dtype=np.float64)
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    sin_angle = 0.5 * np.linalg.norm(axis)
    cos_angle = np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)
    angle = np.arctan2(sin_angle, cos_angle)
    if sin_angle < 1e-12:
        if cos_angle > 0:
            return 0.5 * axis  # first order
        # 180 degrees: the axis is the eigenvector of R + I.
        v = np.linalg.eigh(0.5 * (R + R.T) + np.eye(3))[1][:, -1]
        return np.pi * v
    return angle / (2.0 * sin_angle) * axis


def pose_error_coordinates(R_est: ArrayLike, t_est: ArrayLike, R_true: ArrayLike,
                           t_true: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The estimate's error in its own parametrisation (module docstring).

    Returns ``w`` (3,), the rotation vector of ``R_est R_true^T`` (so that
    ``R_est = exp([w]x) R_true``), and ``d`` (2,), the coordinates of ``t_est``
    seen from ``t_true`` along :func:`tangent_basis` ``(t_est)`` (the gnomonic step
    from the truth to the estimate; ``|d|`` is the tangent of their angle). Both
    poses ``x_cam2 = R x_cam1 + t``.

    Parameters
    ----------
    R_est, t_est : (3, 3), (3,) array_like
        Estimated relative pose.
    R_true, t_true : (3, 3), (3,) array_like
        Reference pose.
    """
    R_est, R_true = np.asarray(R_est, np.float64), np.asarray(R_true, np.float64)
    t_est = np.asarray(t_est, np.float64).reshape(3)
    t_true = np.asarray(t_true, np.float64).reshape(3)
    t_est, t_true = t_est / np.linalg.norm(t_est), t_true / np.linalg.norm(t_true)
    w = rotation_vector(R_est @ R_true.T)
    cos = float(t_est @ t_true)
    d = -(tangent_basis(t_est) @ t_true) / cos if cos > 0 else np.full(2, np.inf)
    return w, d
