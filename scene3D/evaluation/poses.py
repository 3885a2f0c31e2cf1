"""Comparing estimated poses with ground truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, angle_between_deg, as_matrix, rotation_error_deg
from ..optim.uncertainty import CHI2_90


@dataclass(frozen=True)
class PoseError:
    """Angular errors of a relative pose, in degrees.

    ``rotation_deg``: angle of ``R_est R_true^T``. ``translation_deg``: angle
    between the translation directions (the scale of ``t`` is unknown).
    """

    rotation_deg: float
    translation_deg: float

    @property
    def max_deg(self) -> float:
        return max(self.rotation_deg, self.translation_deg)


def relative_pose_error(
    R_est: ArrayLike, t_est: ArrayLike, R_true: ArrayLike, t_true: ArrayLike
) -> PoseError:
    """Angular errors of an estimated relative pose against the true one.

    Parameters
    ----------
    R_est, R_true : (3, 3) array_like
        Rotations ``R_cam2_from_cam1``: ``x_cam2 = R @ x_cam1 + t``.
    t_est, t_true : (3,) array_like
        Translations in the camera-2 frame, same convention; ``(3, 1)`` is taken too.
        Only their directions count (a two-view ``t`` has unit norm, scale unknown),
        so neither may be zero.

    Returns
    -------
    PoseError
        ``rotation_deg``: angle of ``R_est @ R_true.T``; ``translation_deg``: angle
        between ``t_est`` and ``t_true`` (0 to 180 deg: a negated ``t`` is 180 deg off).

    Raises
    ------
    ValueError
        If a shape is wrong (naming the argument), a value is not finite, or a
        translation is zero.
    """
    rotations = [as_matrix(R, (3, 3), name) for R, name in ((R_est, "R_est"), (R_true, "R_true"))]
    directions = [_direction(t, name) for t, name in ((t_est, "t_est"), (t_true, "t_true"))]
    return PoseError(rotation_error_deg(*rotations), angle_between_deg(*directions))


def _direction(t: ArrayLike, name: str) -> FloatArray:
    """``t`` as a finite, non-zero ``(3,) float64`` vector (``(3, 1)`` accepted)."""
    arr = np.asarray(t, dtype=np.float64)
    if arr.shape not in ((3,), (3, 1)):
        raise ValueError(f"`{name}` must have shape (3,), got {arr.shape}")
    arr = as_matrix(arr.reshape(3), (3,), name)
    if not np.any(arr):
        raise ValueError(f"`{name}` must be non-zero: its direction is compared")
    return arr


def pose_auc(max_errors_deg: ArrayLike, threshold_deg: float = 5.0) -> float:
    """Area under the recall curve of ``max_errors_deg`` from 0 to ``threshold_deg``, in percent.

    Failed pairs should be passed as ``inf``.

    Parameters
    ----------
    max_errors_deg : (N,) array_like
        Per-pair error (deg), the larger of rotation and translation direction.
    threshold_deg : float, default 5.0
        Upper end of the curve (deg).

    Returns
    -------
    float
        Percent; NaN for no pairs.
    """
    errors = np.sort(np.asarray(max_errors_deg, dtype=np.float64))
    n = len(errors)
    if n == 0:
        return float("nan")
    recall = np.arange(1, n + 1) / n
    mask = errors < threshold_deg
    e = np.concatenate([[0.0], errors[mask], [threshold_deg]])
    r = np.concatenate([[0.0], recall[mask]])
    r = np.concatenate([r, [r[-1]]])
    area = np.sum(np.diff(e) * r[:-1])
    return float(100.0 * area / threshold_deg)


def paired_auc_difference(
    max_errors_a: ArrayLike,
    max_errors_b: ArrayLike,
    threshold_deg: float = 5.0,
    confidence: float = 0.95,
    samples: int = 10000,
    seed: int = 0,
) -> tuple[float, float, float]:
    """AUC of method a minus AUC of method b on the same pairs, with a bootstrap interval.

    :func:`pose_auc` is the mean over pairs of ``max(0, 1 - e / threshold)`` (in
    percent), so the difference is a mean of per-pair differences. Resampling the
    pairs with replacement, the same pairs for both methods, gives a percentile
    interval: when it contains 0, these pairs do not tell the two methods apart.

    Parameters
    ----------
    max_errors_a, max_errors_b : (N,) or (N, D) array_like
        Per-pair ``max(rotation, translation)`` errors in degrees, pair ``i`` the same
        in both; failed pairs as ``inf``. With ``D`` columns, row ``i`` holds ``D``
        draws of one pair (e.g. noise draws): the pairs are resampled, each with all
        its draws, since draws of one pair are not independent.

    Returns
    -------
    difference, low, high : float
        Percentage points; ``low, high`` bound the ``confidence`` interval.
    """
    a = np.asarray(max_errors_a, dtype=np.float64)
    b = np.asarray(max_errors_b, dtype=np.float64)
    if a.shape != b.shape or a.ndim not in (1, 2) or a.size == 0:
        raise ValueError(f"need two equally shaped, non-empty (N,) or (N, D) error arrays, "
                         f"got {a.shape} and {b.shape}")
    per_draw = 100.0 * (np.clip(1.0 - a / threshold_deg, 0.0, None)
                        - np.clip(1.0 - b / threshold_deg, 0.0, None))
    per_pair = per_draw.reshape(len(a), -1).mean(axis=1)
    resampled = np.random.default_rng(seed).integers(0, len(a), (samples, len(a)))
    means = per_pair[resampled].mean(axis=1)
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = np.percentile(means, [tail, 100.0 - tail])
    return float(per_pair.mean()), float(low), float(high)


def summarize_pose_errors(
    rotation_deg: ArrayLike, translation_deg: ArrayLike, flagged: ArrayLike | None = None
) -> dict[str, float]:
    """Benchmark statistics of per-pair errors (failed pairs as ``inf``, counted as 180 deg).

    Returns medians and 90th percentiles of both errors, the fractions of pairs
    with both errors below 2 and 5 degrees, AUC@5deg (percent), and, when
    ``flagged`` says which pairs the method refused or marked untrusted, how well
    the flag follows the error: ``flagged`` (count), ``right_flagged`` (poses within
    1 deg flagged), ``wrong_unflagged`` (poses more than 5 deg off, failures
    included, not flagged), ``off2`` and ``off2_flagged`` (pairs more than 2 deg
    off or failed, and how many of them were flagged).

    Parameters
    ----------
    rotation_deg, translation_deg : (N,) array_like
        Per-pair rotation and translation-direction errors (deg), inf for failures.
    flagged : (N,) bool array_like or None, default None
        Pairs refused or marked untrusted.

    Returns
    -------
    dict[str, float]
    """
    # A failed pair (inf) is as wrong as an angle can be: 180 deg, so percentiles stay finite.
    rot = np.minimum(np.asarray(rotation_deg, dtype=np.float64), 180.0)
    tdir = np.minimum(np.asarray(translation_deg, dtype=np.float64), 180.0)
    worst = np.maximum(rot, tdir)
    flags = np.zeros(len(rot), bool) if flagged is None else np.asarray(flagged, bool)
    return {
        "pairs": float(len(rot)),
        "median_rotation_deg": float(np.median(rot)),
        "p90_rotation_deg": float(np.percentile(rot, 90)),
        "median_translation_deg": float(np.median(tdir)),
        "p90_translation_deg": float(np.percentile(tdir, 90)),
        "within_2deg": float(np.mean(worst < 2.0)),
        "within_5deg": float(np.mean(worst < 5.0)),
        "auc_5deg": pose_auc(worst, 5.0),
        "flagged": float(flags.sum()),
        "right_flagged": float(np.sum((worst < 1.0) & flags)),
        "wrong_unflagged": float(np.sum((worst > 5.0) & ~flags)),
        "off2": float(np.sum(worst > 2.0)),
        "off2_flagged": float(np.sum((worst > 2.0) & flags)),
    }


def sigma_calibration(rotation_chi2: ArrayLike, translation_chi2: ArrayLike) -> dict[str, float]:
    """How often errors lie within their predicted 90 % bounds.

    ``rotation_chi2`` and ``translation_chi2`` ``(N,)`` are the Mahalanobis
    distances (squared) of each pose's rotation and translation-direction errors
    under its predicted covariance (:func:`scene3D.optim.uncertainty.pose_error_chi2`;
    NaN where no pose came back, and those pairs are left out). Returns ``pairs``
    (counted) and ``rotation_within90`` / ``translation_within90``, the shares within
    the chi-square 90 % quantiles of 3 and 2 degrees of freedom: about 0.9 when the
    covariances are calibrated, less when they are optimistic.

    Parameters
    ----------
    rotation_chi2, translation_chi2 : (N,) array_like
        Squared Mahalanobis distances of the errors, NaN where no pose came back.

    Returns
    -------
    dict[str, float]
    """
    rot = np.asarray(rotation_chi2, dtype=np.float64)
    tdir = np.asarray(translation_chi2, dtype=np.float64)
    known = ~(np.isnan(rot) | np.isnan(tdir))
    if not known.any():
        return {"pairs": 0.0, "rotation_within90": float("nan"),
                "translation_within90": float("nan")}
    return {"pairs": float(known.sum()),
            "rotation_within90": float(np.mean(rot[known] <= CHI2_90[3])),
            "translation_within90": float(np.mean(tdir[known] <= CHI2_90[2]))}


def similarity_transform(src: ArrayLike, dst: ArrayLike) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity ``dst ~ s R src + t`` (Umeyama, 1991).

    Parameters
    ----------
    src, dst : (N, 3) array_like
        Corresponding points, N >= 3 and not collinear.

    Returns
    -------
    s : float
    R : (3, 3) float64
        Proper rotation.
    t : (3,) float64
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1.0
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / np.mean(np.sum(a**2, axis=1)))
    return s, R, mu_d - s * R @ mu_s


@dataclass(frozen=True)
class CameraSetError:
    """Errors of registered cameras after a similarity alignment to ground truth.

    Attributes
    ----------
    center_errors : (V,) float64
        Distance of each aligned camera centre to the true one, as a fraction of
        the scene extent (the largest distance between two true centres).
    rotation_errors_deg : (V,) float64
        Angle between each aligned camera orientation and the true one.
    """

    center_errors: np.ndarray
    rotation_errors_deg: np.ndarray


def camera_set_error(
    R_est: ArrayLike, centers_est: ArrayLike, R_true: ArrayLike, centers_true: ArrayLike,
    align: str = "orientations",
) -> CameraSetError:
    """Compare world-to-camera rotations ``(V, 3, 3)`` and centres ``(V, 3)`` up to similarity.

    With ``align="orientations"`` (the default) the alignment ``X_true = s A X_est + b``
    takes its rotation ``A`` from the camera orientations (``R_est = R_true A`` for
    every view; their chordal mean), which stays well determined when the centres lie
    near a line or an arc, and its scale and offset from the centres (least squares).
    With ``align="centres"`` the whole similarity comes from the centres
    (:func:`similarity_transform`), as COLMAP's model aligner and most published SfM
    evaluations do: it gives the smallest centre errors, but when the centres lie near
    a line the roll about it is hardly constrained, and the rotation errors then carry
    that ill-determined roll
    (docs/benchmarks.md#the-reference-colmap-incremental-measured-the-same-way).

    Parameters
    ----------
    R_est, R_true : (V, 3, 3) array_like
        Estimated and true world-to-camera rotations (``x_cam = R X + t``).
    centers_est, centers_true : (V, 3) array_like
        Estimated and true camera centres, each in its own world frame.
    align : {"orientations", "centres"}, default "orientations"
        What the similarity's rotation comes from.

    Returns
    -------
    CameraSetError

    Raises
    ------
    ValueError
        For another ``align``.
    """
    R_est, R_true = np.asarray(R_est, np.float64), np.asarray(R_true, np.float64)
    c_est, c_true = np.asarray(centers_est, np.float64), np.asarray(centers_true, np.float64)
    if align == "orientations":
        U, _, Vt = np.linalg.svd(np.einsum("vji,vjk->ik", R_true, R_est))  # sum R_true^T R_est
        A = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
        a = (c_est - c_est.mean(axis=0)) @ A.T
        d = c_true - c_true.mean(axis=0)
        s = float(np.sum(a * d) / np.sum(a * a))
        b = c_true.mean(axis=0) - s * A @ c_est.mean(axis=0)
    elif align == "centres":
        s, A, b = similarity_transform(c_est, c_true)
    else:
        raise ValueError(f"`align` must be 'orientations' or 'centres', got {align!r}")
    aligned = (s * (A @ c_est.T)).T + b
    extent = max(np.linalg.norm(p - q) for p in c_true for q in c_true)
    center_errors = np.linalg.norm(aligned - c_true, axis=1) / extent
    # World points map as X_true = s A X_est + b, so R_est A^T is the aligned orientation.
    rot = np.array([rotation_error_deg(Re @ A.T, Rt) for Re, Rt in zip(R_est, R_true)])
    return CameraSetError(center_errors, rot)
