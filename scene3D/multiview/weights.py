"""How precisely each keypoint is located: the weights of bundle adjustment.

A SIFT keypoint is the extremum of a difference of Gaussians at its scale; it is
located to a fraction of that scale, so its error grows with the keypoint's size
(``cv2.KeyPoint.size``, the diameter of the region described), as a model's reprojection
residuals show (docs/benchmarks.md). Dividing each residual by a standard
deviation proportional to the size is the maximum-likelihood weighting for that noise
(H&Z section 4.2.2: the Mahalanobis distance under the measurements' covariance).
"""

from __future__ import annotations

import numpy as np

from ..geometry.conventions import FloatArray


def keypoint_sigma(sizes: FloatArray) -> FloatArray:
    """Relative standard deviation of each keypoint's position ``(N,)``.

    Parameters
    ----------
    sizes : (N,) array_like
        Keypoint sizes in pixels (all views' keypoints).

    Returns
    -------
    (N,) float64
        ``sizes / median(sizes)``: proportional to the size, 1 for the median
        keypoint, so that thresholds and the robust loss's scale, given in pixels,
        keep their meaning for a typical keypoint. All ones when the sizes are not
        positive and finite (e.g. corners without a scale).
    """
    sizes = np.asarray(sizes, np.float64).ravel()
    if len(sizes) == 0 or not np.all(np.isfinite(sizes)) or np.any(sizes <= 0):
        return np.ones(len(sizes))
    return sizes / np.median(sizes)
