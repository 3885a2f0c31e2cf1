"""Helpers for the tests: synthetic correspondences with known geometry."""

from __future__ import annotations

import numpy as np

from scene3D.geometry import project
from scene3D.synthetic import random_points


def correspondences(K, R, t, n=200, noise_px=0.0, seed=0):
    """Points in the camera-1 frame and their pixels in both views, optionally noisy."""
    points = random_points(n, seed)
    pts1 = project(points, K, np.eye(3), np.zeros(3))
    pts2 = project(points, K, R, t)
    if noise_px:
        rng = np.random.default_rng(seed + 1)
        pts1 = pts1 + rng.normal(0, noise_px, pts1.shape)
        pts2 = pts2 + rng.normal(0, noise_px, pts2.shape)
    return points, pts1, pts2
