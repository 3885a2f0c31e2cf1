"""Helpers for the tests: synthetic correspondences with known geometry, board detections,
real Strecha pairs with their true pose."""

from __future__ import annotations

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D import SceneReconstruction3D
from scene3D.calibration import detect_board
from scene3D.evaluation.synthetic import random_points
from scene3D.geometry import project, rotation_about_axis
from scene3D.io.datasets import read_strecha_camera, relative_pose


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


def strecha_pair(folder, a, b, max_width):
    """The book's class with views ``a`` and ``b`` of a Strecha scene loaded at
    ``max_width``, and their true relative pose ``(R, t)``."""
    cam_a, cam_b = (read_strecha_camera(folder / "gt_dense_cameras" / f"{i:04d}.jpg.camera")
                    for i in (a, b))
    scene = SceneReconstruction3D(cam_a.K, cam_a.dist)
    scene.load_image_pair(folder / "images" / f"{a:04d}.jpg", folder / "images" / f"{b:04d}.jpg",
                          max_width=max_width)
    return scene, relative_pose(cam_a, cam_b)


def scipy_bundle_adjust(R, t, points3d, obs, K, fixed_view, loss, scale_px, max_evaluations):
    """Reference bundle adjustment with scipy's ``least_squares`` (sparse Jacobian, trust
    region): what scene3D used before its own solver. Same residuals, loss and camera
    update (rotation vector applied on the left, translation added); the scale is left free.
    """
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    from scene3D.geometry import rotations_from_vectors
    from scene3D.optim.bundle import reprojection_residuals

    num_views, num_points = len(R), len(points3d)
    free = np.array([v for v in np.unique(obs.view) if v != fixed_view], dtype=int)
    slot = np.full(num_views, -1, dtype=int)
    slot[free] = np.arange(len(free))
    n_cam = 6 * len(free)

    def unpack(x):
        R_x, t_x = R.copy(), t.copy()
        if len(free):
            params = x[:n_cam].reshape(-1, 6)
            R_x[free] = rotations_from_vectors(params[:, :3]) @ R[free]
            t_x[free] = t[free] + params[:, 3:]
        return R_x, t_x, x[n_cam:].reshape(num_points, 3)

    def residuals(x):
        R_x, t_x, X = unpack(x)
        return reprojection_residuals(R_x, t_x, X, obs, K).ravel()

    # Sparsity: rows 2k, 2k+1 depend on the observing camera (6) and the point (3).
    num_obs = len(obs.view)
    rows, cols = [], []
    obs_rows = np.repeat(np.arange(num_obs) * 2, 2) + np.tile([0, 1], num_obs)
    cam_slot = np.repeat(slot[obs.view], 2)
    has_cam = cam_slot >= 0
    for k in range(6):
        rows.append(obs_rows[has_cam])
        cols.append(6 * cam_slot[has_cam] + k)
    point_col = n_cam + 3 * np.repeat(obs.point, 2)
    for k in range(3):
        rows.append(obs_rows)
        cols.append(point_col + k)
    rows_all, cols_all = np.concatenate(rows), np.concatenate(cols)
    sparsity = csr_matrix((np.ones(len(rows_all), dtype=np.int8), (rows_all, cols_all)),
                          shape=(2 * num_obs, n_cam + 3 * num_points))
    x0 = np.concatenate([np.zeros(n_cam), points3d.ravel()])
    result = least_squares(residuals, x0, jac_sparsity=sparsity, loss=loss, f_scale=scale_px,
                           max_nfev=max_evaluations, x_scale="jac", method="trf",
                           tr_solver="lsmr")
    return unpack(result.x)


def detect_folder(folder, board):
    """The board's detections in every ``*.jpg`` of ``folder`` (sorted; misses left out)."""
    dets = []
    for path in sorted(folder.glob("*.jpg")):
        d = detect_board(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE), board, path.name)
        if d is not None:
            dets.append(d)
    return dets


def same_up_to_sign(A, B, atol):
    """True when two matrices agree up to scale and sign (both scaled to unit norm)."""
    A = A / np.linalg.norm(A)
    B = B / np.linalg.norm(B)
    return min(np.abs(A - B).max(), np.abs(A + B).max()) < atol


def perturbed_pose(R, t, angle_deg=1.0):
    """A start near ``(R, t)``: turned by ``angle_deg``, the direction tilted, ``|t| = 1``."""
    R0 = rotation_about_axis([0.3, -0.2, 1.0], angle_deg) @ R
    t0 = t / np.linalg.norm(t) + np.array([0.02, -0.03, 0.01])
    return R0, t0 / np.linalg.norm(t0)


#: Tests that count page faults to see whether malloc reused memory (glibc's malloc; each
#: test turns transparent huge pages off for its process, so that a fault is one page).
counts_page_faults = pytest.mark.skipif(sys.platform != "linux",
                                        reason="counts page faults of glibc's malloc")


#: Python that prints the pages faulted in by three rounds of allocating ``blocks``
#: blocks of ``mib`` MiB and freeing them (transparent huge pages off for the process,
#: so that a fault is one 4 KiB page).
ROUNDS = ("import ctypes, resource\n"
          "ctypes.CDLL(None).prctl(41, 1, 0, 0, 0)  # PR_SET_THP_DISABLE\n"
          "def rounds(blocks, mib):\n"
          "    def faults(): return resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
          "    for _ in range(3):\n"
          "        before = faults(); held = [bytearray(mib << 20) for _ in range(blocks)]\n"
          "        del held; print(faults() - before)\n")


def run_python(code: str, *args: str, **extra_env: str) -> list[str]:
    """What ``code`` prints with ``args``, run in a fresh interpreter without the caller's
    malloc settings (plus ``extra_env``)."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    return subprocess.run([sys.executable, "-c", code, *args], env={**env, **extra_env},
                          capture_output=True, text=True, check=True).stdout.split()
