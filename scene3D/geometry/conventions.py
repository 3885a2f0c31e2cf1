"""Shared conventions and small geometric helpers.

Conventions (used by every module of scene3D)
---------------------------------------------
- Pixels follow OpenCV: x to the right, y down, integer coordinates at pixel
  centres. Images are indexed ``img[y, x]`` and are BGR ``uint8`` as cv2 loads them.
- Poses are world-to-camera: ``x_cam = R @ X + t`` and ``P = K @ [R | t]``.
  In a two-view reconstruction camera 1 is ``[I | 0]`` and ``(R, t)`` maps
  camera-1 coordinates to camera-2 coordinates: ``x_cam2 = R @ x_cam1 + t``
  (``R_cam2_from_cam1``).
- Epipolar constraint ``x2^T F x1 = 0`` in pixels, ``E = [t]x R`` and
  ``F = K2^-T E K1^-1`` (Hartley & Zisserman, sections 9.2 and 9.6).
- A translation estimated from two views has unit norm: the scale of the scene
  is unknown, and so are the units of ``points3d``.
- Arrays: 2D points ``(N, 2) float64``, 3D points ``(N, 3) float64``,
  ``K``/``F``/``E``/``R`` ``(3, 3)``, ``t`` ``(3,)``, ``P`` ``(3, 4)``.
"""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def image_size(img: np.ndarray) -> tuple[int, int]:
    """The ``(width, height)`` of an image indexed ``img[y, x]``.

    Parameters
    ----------
    img : (H, W) or (H, W, C) array

    Returns
    -------
    (int, int)
        ``(W, H)``, the order OpenCV's sizes take.
    """
    return int(img.shape[1]), int(img.shape[0])


def as_points2d(points: ArrayLike, name: str = "points") -> FloatArray:
    """Return ``points`` as a ``(N, 2) float64`` array, accepting ``(N, 1, 2)`` too.

    Parameters
    ----------
    points : (N, 2) or (N, 1, 2) array_like
        Pixels or normalised coordinates.
    name : str, default "points"
        The argument's name in error messages.

    Returns
    -------
    (N, 2) float64 ndarray


    Raises
    ------
    ValueError
        If the shape is not ``(N, 2)`` / ``(N, 1, 2)`` or values are not finite.
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 3 and arr.shape[1:] == (1, 2):
        arr = arr.reshape(-1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"`{name}` must have shape (N, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"`{name}` contains non-finite values")
    return arr


def is_real_number(value: object) -> bool:
    """A real number that is not a bool (to Python, ``True`` is the integer 1).

    Parameters
    ----------
    value : object

    Returns
    -------
    bool
    """
    return isinstance(value, Real) and not isinstance(value, bool)


def is_whole_number(value: object) -> bool:
    """An integer (Python's or numpy's) that is not a bool.

    Parameters
    ----------
    value : object

    Returns
    -------
    bool
    """
    return isinstance(value, Integral) and not isinstance(value, bool)


def require_whole_number(value: object, name: str, minimum: int = 1) -> int:
    """``value`` as an ``int``, or ``ValueError`` naming ``name`` unless it is a whole
    number of at least ``minimum``.

    Parameters
    ----------
    value : object
        The value to check.
    name : str
        The argument's name in the message.
    minimum : int, default 1
        Smallest allowed value.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        When ``value`` is not such a number.
    """
    if not is_whole_number(value) or value < minimum:
        raise ValueError(f"`{name}` must be a whole number of at least {minimum}, got {value!r}")
    return int(value)


def require_real_number(value: object, name: str, low: float, high: float) -> float:
    """``value`` as a ``float``, or ``ValueError`` naming ``name`` unless it is a real
    number with ``low < value <= high``.

    Parameters
    ----------
    value : object
        The value to check.
    name : str
        The argument's name in the message.
    low, high : float
        Bounds, ``low`` excluded and ``high`` included.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        When ``value`` is not such a number.
    """
    if not is_real_number(value) or not low < value <= high:
        raise ValueError(f"`{name}` must be a number above {low:g} and at most {high:g}, "
                         f"got {value!r}")
    return float(value)


def as_matrix(value: ArrayLike, shape: tuple[int, ...], name: str) -> FloatArray:
    """Return ``value`` as a finite float64 array of exactly ``shape``.

    Parameters
    ----------
    value : array_like
        The array to check.
    shape : tuple of int
        Required shape.
    name : str
        The argument's name in error messages.

    Returns
    -------
    float64 ndarray of ``shape``

    Raises
    ------
    ValueError
        If ``value`` is complex, of another shape or not finite.
    """
    if np.iscomplexobj(value):
        raise ValueError(f"`{name}` must be real, got complex values")
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"`{name}` must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"`{name}` contains non-finite values")
    return arr


def check_same_length(pts1: FloatArray, pts2: FloatArray) -> None:
    """Raise ``ValueError`` unless two point arrays have the same number of rows.

    Parameters
    ----------
    pts1, pts2 : (N, 2) ndarray
        Point arrays.

    Raises
    ------
    ValueError
        If their lengths differ.
    """
    if len(pts1) != len(pts2):
        raise ValueError(
            f"`pts1` and `pts2` must have the same length, got {len(pts1)} and {len(pts2)}"
        )


def distinct_correspondences(pts1: FloatArray, pts2: FloatArray) -> np.ndarray:
    """Indices ``(M,)``, ascending, of the first of each run of identical correspondences.

    ``pts1, pts2`` ``(N, 2)``: row ``i`` of each is one correspondence. A detector
    that gives a keypoint one descriptor per dominant orientation (SIFT) lists the
    same correspondence twice when both copies match (about one match in ten). It
    is one observation of the keypoints' noise, and one point: counted twice, it
    shrinks a covariance as a second observation would and adds to the inlier count
    (on a chessboard on a wall 15 listed inliers were 6 points, which a pose of five
    degrees of freedom nearly interpolates).

    Parameters
    ----------
    pts1, pts2 : (N, 2) ndarray
        Corresponding pixels in images 1 and 2.

    Returns
    -------
    (M,) intp ndarray
    """
    rows = np.hstack([pts1, pts2])
    order = np.lexsort(rows.T[::-1])  # stable: equal rows keep their order
    ordered = rows[order]
    starts = np.ones(len(rows), dtype=bool)
    starts[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    return np.sort(order[starts])  # np.unique(axis=0) gives the same, 5 times slower


def skew(v: ArrayLike) -> FloatArray:
    """Return the ``(3, 3)`` cross-product matrix ``[v]x`` with ``[v]x @ w == v x w``.

    Parameters
    ----------
    v : (3,) array_like

    Returns
    -------
    (3, 3) float64 ndarray
    """
    x, y, z = np.asarray(v, dtype=np.float64).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def to_homogeneous(points: FloatArray) -> FloatArray:
    """Append a column of ones: ``(N, D) -> (N, D + 1)``.

    Parameters
    ----------
    points : (N, D) ndarray

    Returns
    -------
    (N, D + 1) float64 ndarray
    """
    return np.hstack([points, np.ones((len(points), 1))])


def normalize_points(points: FloatArray, K: FloatArray) -> FloatArray:
    """Pixel coordinates ``(N, 2)`` to normalised image coordinates ``K^-1 x`` ``(N, 2)``.

    Parameters
    ----------
    points : (N, 2) ndarray
        Pixels (OpenCV convention).
    K : (3, 3) array_like
        Intrinsics (pixels, OpenCV convention).

    Returns
    -------
    (N, 2) float64 ndarray
    """
    rays = to_homogeneous(points) @ np.linalg.inv(K).T
    return rays[:, :2] / rays[:, 2:3]


def projection_matrix(K: FloatArray, R: FloatArray, t: FloatArray) -> FloatArray:
    """Return ``P = K @ [R | t]`` with shape ``(3, 4)``.

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics (pixels, OpenCV convention).
    R, t : (3, 3), (3,) array_like
        World-to-camera pose, ``x_cam = R X + t``.

    Returns
    -------
    (3, 4) float64 ndarray
    """
    return K @ np.hstack([R, np.reshape(t, (3, 1))])


def project(points3d: FloatArray, K: FloatArray, R: FloatArray, t: FloatArray) -> FloatArray:
    """Project world points ``(N, 3)`` to pixels ``(N, 2)`` with ``x = K (R X + t)``.

    Parameters
    ----------
    points3d : (N, 3) ndarray
        World points.
    K : (3, 3) array_like
        Intrinsics (pixels, OpenCV convention).
    R, t : (3, 3), (3,) array_like
        World-to-camera pose, ``x_cam = R X + t``.

    Returns
    -------
    (N, 2) float64 ndarray
        Pixels (OpenCV convention).
    """
    cam = points3d @ R.T + np.reshape(t, (1, 3))
    pix = cam @ K.T
    return pix[:, :2] / pix[:, 2:3]


def project_with_jacobian(points_cam: FloatArray, K: FloatArray
                          ) -> tuple[FloatArray, FloatArray]:
    """Pixels ``(N, 2)`` of camera-frame points ``(N, 3)`` and their derivatives ``(N, 2, 3)``.

    With ``q = K X``, pixel ``= q[:2] / q[2]`` and its derivative by ``X`` is
    ``(K[:2] - pixel K[2]) / q[2]``.

    Parameters
    ----------
    points_cam : (N, 3) ndarray
        Points in the camera frame.
    K : (3, 3) array_like
        Intrinsics (pixels, OpenCV convention).

    Returns
    -------
    pixels : (N, 2) float64 ndarray
    jacobian : (N, 2, 3) float64 ndarray
        Derivative of each pixel by its camera-frame point.
    """
    q = points_cam @ K.T
    pix = q[:, :2] / q[:, 2:3]
    return pix, (K[None, :2, :] - pix[:, :, None] * K[None, 2:3, :]) / q[:, 2, None, None]


def camera_centers(R: ArrayLike, t: ArrayLike) -> FloatArray:
    """Centres ``C = -R^T t`` ``(V, 3)`` of world-to-camera poses ``R (V, 3, 3)``, ``t (V, 3)``.

    Parameters
    ----------
    R : (V, 3, 3) array_like
        World-to-camera rotations (``x_cam = R X + t``).
    t : (V, 3) array_like
        World-to-camera translations.

    Returns
    -------
    (V, 3) float64 ndarray
        Camera centres in the world frame.
    """
    return -np.einsum("vji,vj->vi", np.asarray(R, np.float64), np.asarray(t, np.float64))


def relative_pose(R1: ArrayLike, t1: ArrayLike, R2: ArrayLike, t2: ArrayLike
                  ) -> tuple[FloatArray, FloatArray]:
    """``(R, t)`` with ``x_cam2 = R x_cam1 + t`` from two poses ``x_cam = R_i x + t_i``.

    ``R1, R2`` (3, 3) and ``t1, t2`` (3,) map one frame (the world, a calibration board)
    into each camera; ``t`` keeps their metric scale (not unit norm).

    Parameters
    ----------
    R1, t1 : (3, 3), (3,) array_like
        Pose of camera 1, ``x_cam1 = R1 X + t1``.
    R2, t2 : (3, 3), (3,) array_like
        Pose of camera 2, ``x_cam2 = R2 X + t2``.

    Returns
    -------
    R : (3, 3) float64 ndarray
        ``R_cam2_from_cam1``.
    t : (3,) float64 ndarray
    """
    R1, R2 = np.asarray(R1, np.float64), np.asarray(R2, np.float64)
    R = R2 @ R1.T
    return R, np.asarray(t2, np.float64).reshape(3) - R @ np.asarray(t1, np.float64).reshape(3)


def rotation_angle_deg(R: ArrayLike) -> float:
    """Angle of the rotation ``R`` in degrees (0 for the identity).

    Parameters
    ----------
    R : (3, 3) array_like
        Rotation matrix.

    Returns
    -------
    float
    """
    R = np.asarray(R, dtype=np.float64)
    # ||R - I||_F = 2 sqrt(2) sin(angle / 2): accurate for small angles, unlike arccos.
    half_chord = np.linalg.norm(R - np.eye(3)) / (2.0 * np.sqrt(2.0))
    return float(np.degrees(2.0 * np.arcsin(np.clip(half_chord, 0.0, 1.0))))


def rotation_error_deg(R_est: ArrayLike, R_true: ArrayLike) -> float:
    """Angle in degrees of ``R_est @ R_true^T``: how far apart two rotations are.

    Parameters
    ----------
    R_est, R_true : (3, 3) array_like
        Rotation matrices.

    Returns
    -------
    float
    """
    return rotation_angle_deg(np.asarray(R_est) @ np.asarray(R_true).T)


def angle_between_deg(a: ArrayLike, b: ArrayLike) -> float:
    """Angle in degrees between two 3-vectors (direction only, sign matters).

    Parameters
    ----------
    a, b : (3,) array_like
        Non-zero vectors.

    Returns
    -------
    float
        In ``[0, 180]``.
    """
    a = np.asarray(a, dtype=np.float64).reshape(3)
    b = np.asarray(b, dtype=np.float64).reshape(3)
    cos = np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def pose_angle_deg(R_a: ArrayLike, t_a: ArrayLike, R_b: ArrayLike, t_b: ArrayLike) -> float:
    """How far apart two relative poses ``(R (3, 3), t (3,))`` are, in degrees: the larger of
    the angle between their rotations (:func:`rotation_error_deg`) and the angle between
    their translation directions (:func:`angle_between_deg`, sign matters).

    Parameters
    ----------
    R_a, t_a : (3, 3), (3,) array_like
        First relative pose, e.g. camera 2 from camera 1 (``x_cam2 = R x_cam1 + t``).
    R_b, t_b : (3, 3), (3,) array_like
        Second relative pose, between the same frames in the same direction.

    Returns
    -------
    float
    """
    return max(rotation_error_deg(R_a, R_b), angle_between_deg(t_a, t_b))


def rotation_about_axis(axis: ArrayLike, angle_deg: float) -> FloatArray:
    """Rotation matrix ``(3, 3)`` turning by ``angle_deg`` about ``axis`` (right hand).

    Parameters
    ----------
    axis : (3,) array_like
        Non-zero axis (any length).
    angle_deg : float
        Angle in degrees.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    axis = np.asarray(axis, dtype=np.float64).reshape(3)
    return rotations_from_vectors((np.radians(angle_deg) / np.linalg.norm(axis) * axis)[None])[0]


def rotations_from_vectors(w: FloatArray) -> FloatArray:
    """Rodrigues' formula for ``(M, 3)`` rotation vectors: ``(M, 3, 3)`` rotations.

    Parameters
    ----------
    w : (M, 3) ndarray
        Rotation vectors (axis times angle in radians).

    Returns
    -------
    (M, 3, 3) float64 ndarray
    """
    theta = np.linalg.norm(w, axis=1)
    safe = np.where(theta < 1e-12, 1.0, theta)
    K = skews(w / safe[:, None])
    s = np.sin(theta)[:, None, None]
    c = (1.0 - np.cos(theta))[:, None, None]
    R = np.eye(3)[None] + s * K + c * (K @ K)
    small = theta < 1e-12
    if small.any():  # first order for tiny angles
        R[small] = np.eye(3)[None] + skews(w[small])
    return R


def skews(v: FloatArray) -> FloatArray:
    """:func:`skew` of each row of ``v (M, 3)``: ``(M, 3, 3)``.

    Parameters
    ----------
    v : (M, 3) ndarray

    Returns
    -------
    (M, 3, 3) float64 ndarray
    """
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2] = -v[:, 2], v[:, 1]
    S[:, 1, 0], S[:, 1, 2] = v[:, 2], -v[:, 0]
    S[:, 2, 0], S[:, 2, 1] = -v[:, 1], v[:, 0]
    return S


def quaternion_from_rotation(R: ArrayLike) -> FloatArray:
    """Unit quaternion ``(w, x, y, z)`` (Hamilton, ``w >= 0``) of a rotation matrix.

    Parameters
    ----------
    R : (3, 3) array_like
        Rotation matrix.

    Returns
    -------
    (4,) float64 ndarray
        ``(w, x, y, z)``.
    """
    R = np.asarray(R, dtype=np.float64)
    trace = np.trace(R)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def rotation_from_quaternion(q: ArrayLike) -> FloatArray:
    """Rotation matrix of a quaternion ``(w, x, y, z)``.

    Parameters
    ----------
    q : (4,) array_like
        Quaternion ``(w, x, y, z)``, normalised here.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def median(values: FloatArray) -> float:
    """``np.median`` of a non-empty ``(N,)`` array without NaNs.

    ``np.median`` imports ``numpy.ma`` on its first call, 8-18 ms of a 0.4-0.6 s run.

    Parameters
    ----------
    values : (N,) ndarray
        N >= 1, no NaN.

    Returns
    -------
    float
    """
    n = len(values)
    part = np.partition(values, [(n - 1) // 2, n // 2])
    return float(0.5 * (part[(n - 1) // 2] + part[n // 2]))
