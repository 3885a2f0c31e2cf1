"""Two-view bundle adjustment: scene3D's sparse Levenberg-Marquardt against scipy.

    python benchmarks/bundle_adjustment.py [--width 768] [--evaluations 100 1000]

On the fountain-P11 pairs (i, i+1) and (i, i+2), each pair's default
reconstruction (pose, points, inlier pixels) is adjusted by
:func:`scene3D.optim.bundle_two_view.bundle_adjust_two_view` and by scipy's
``least_squares`` (sparse Jacobian, trust region; the reference the tests use,
needs the dev extra) with the same residuals and Cauchy loss, at the scale the
pipeline gives the pair (:func:`scene3D.twoview.essential_fit.loss_scale_px` of its points'
Sampson distances), stopped after each number of evaluations. Prints per solver
the median and largest time, the smallest and the median robust cost above the
cost scene3D reaches (negative: scipy found a lower cost), and the largest pose
difference from scene3D's result. Single-threaded (OpenBLAS and OpenCV), one process.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scene3D import SceneReconstruction3D  # noqa: E402
from scene3D.evaluation import relative_pose_error  # noqa: E402
from scene3D.geometry.epipolar import essential_distances  # noqa: E402
from scene3D.io.datasets import fetch_fountain_p11, read_strecha_camera  # noqa: E402
from scene3D.optim.bundle import Observations  # noqa: E402
from scene3D.optim.bundle_two_view import bundle_adjust_two_view, two_view_residuals  # noqa: E402
from scene3D.optim.least_squares import robust_cost  # noqa: E402
from scene3D.twoview import TwoViewSettings  # noqa: E402
from scene3D.twoview.essential_fit import loss_scale_px  # noqa: E402
from tests.helpers import scipy_bundle_adjust  # noqa: E402


def cost(R, t, X, pts1, pts2, K, scale):
    return robust_cost(two_view_residuals(R, t, X, pts1, pts2, K), "cauchy", scale)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=int, default=768, help="working width (768 or 1536)")
    parser.add_argument("--evaluations", type=int, nargs="+", default=[100, 1000],
                        help="scipy's max_nfev values to compare")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    folder = fetch_fountain_p11()
    solvers = ["scene3D"] + [f"scipy, {n} evaluations" for n in args.evaluations]
    times = {s: [] for s in solvers}
    excess = {s: [] for s in solvers}
    pose_diff = {s: [] for s in solvers}
    scales = []
    pairs = [(i, i + g) for g in (1, 2) for i in range(11 - g)]
    for a, b in pairs:
        cam = read_strecha_camera(folder / "gt_dense_cameras" / f"{a:04d}.jpg.camera")
        scene = SceneReconstruction3D(cam.K)
        scene.load_image_pair(folder / "images" / f"{a:04d}.jpg",
                              folder / "images" / f"{b:04d}.jpg", max_width=args.width)
        g = scene.reconstruct()
        K, n = scene.K, len(g.points3d)
        scale = loss_scale_px(essential_distances(g.E, g.pts1, g.pts2, K),
                              TwoViewSettings().threshold_px)
        scales.append(scale)
        t0 = time.perf_counter()
        R1, t1, X1 = bundle_adjust_two_view(g.R, g.t, g.points3d, g.pts1, g.pts2, K,
                                            loss="cauchy", scale_px=scale)
        times["scene3D"].append(time.perf_counter() - t0)
        best = cost(R1, t1, X1, g.pts1, g.pts2, K, scale)
        excess["scene3D"].append(0.0)
        pose_diff["scene3D"].append(0.0)
        obs = Observations(np.repeat([0, 1], n), np.tile(np.arange(n), 2),
                           np.vstack([g.pts1, g.pts2]))
        for evaluations, name in zip(args.evaluations, solvers[1:]):
            t0 = time.perf_counter()
            Rs, ts, Xs = scipy_bundle_adjust(np.stack([np.eye(3), g.R]),
                                             np.stack([np.zeros(3), g.t]), g.points3d, obs, K,
                                             0, "cauchy", scale, evaluations)
            times[name].append(time.perf_counter() - t0)
            norm = np.linalg.norm(ts[1])
            excess[name].append(cost(Rs[1], ts[1] / norm, Xs / norm, g.pts1, g.pts2, K, scale)
                                - best)
            pose_diff[name].append(relative_pose_error(Rs[1], ts[1], R1, t1).max_deg)
        print(f"pair {a}-{b}: {n} points", file=sys.stderr, flush=True)
    print(f"fountain-P11, {len(pairs)} pairs at {args.width} px, Cauchy loss at each pair's "
          f"scale ({min(scales):.3f} to {max(scales):.3f} px)\n")
    print("| solver | median ms | max ms | cost above scene3D's: min | median | "
          "max pose difference from scene3D (deg) |")
    print("|---|---|---|---|---|---|")
    for s in solvers:
        print(f"| {s} | {1000 * np.median(times[s]):.0f} | {1000 * max(times[s]):.0f} | "
              f"{min(excess[s]):.4f} | {np.median(excess[s]):.4f} | {max(pose_diff[s]):.4f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
