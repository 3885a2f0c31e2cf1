"""Comparing estimated poses with ground truth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .geometry import angle_between_deg, rotation_error_deg


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
    """Errors of ``(R_est, t_est)`` against ``(R_true, t_true)``, both ``x_cam2 = R x_cam1 + t``."""
    return PoseError(rotation_error_deg(R_est, R_true), angle_between_deg(t_est, t_true))


def pose_auc(max_errors_deg: ArrayLike, threshold_deg: float = 5.0) -> float:
    """Area under the recall curve of ``max_errors_deg`` from 0 to ``threshold_deg``, in percent.

    Failed pairs should be passed as ``inf``.
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
