"""Many-view bundle adjustment: scene3D's own solver against Ceres (pyceres), same problem.

    python benchmarks/multi_view_bundle.py [--cases castle-P19 orbit200] [--iterations 30]

For each case ``reconstruct_views`` runs with default options (castle-P19 at 1536 px from
``$SCENE3D_DATA``; ``orbitN``: N views of the rendered orbit of
``benchmarks/multi_view.py``), and the inputs of its first global adjustment once every
view is registered (cameras, points and observations, the reference view fixed) are kept:
the largest of its adjustments, and the one that moves the cameras most. That problem is
then solved, each solver from the same start, one thread (``OPENBLAS_NUM_THREADS=1``,
Ceres ``num_threads=1``), by

- scene3D: :func:`scene3D.optim.bundle.bundle_adjust` (Levenberg-Marquardt, points eliminated by
  the Schur complement, :mod:`scene3D.optim.schur`);
- Ceres 2 through pyceres: the problem as COLMAP builds it (pycolmap's bundle adjuster:
  C++ auto-differentiated reprojection errors, quaternion manifolds), solved by
  ``pyceres.solve`` with a Schur solver (dense up to 50 cameras, sparse beyond; the
  iterative Schur solver as a third row for large cases).

Twice: without a robust loss, where both minimise exactly the same sum of squares, and with
the soft-L1 loss at 1 px (scene3D applies it to each pixel coordinate, COLMAP and Ceres to
each observation's 2-vector). Prints, per solver: CPU and wall seconds, iterations, the final
sum of squared reprojection errors (px^2) and the camera errors against the truth after a
similarity alignment (max / median).

Needs the bench extra (pycolmap) and pyceres.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.multi_view import ORBIT_VIEWS, render_orbit  # noqa: E402
from scene3D.evaluation import camera_set_error  # noqa: E402
from scene3D.geometry import camera_centers  # noqa: E402
from scene3D.io.colmap import colmap_model_from_views, colmap_text  # noqa: E402
from scene3D.io.datasets import default_data_root, read_strecha_scene  # noqa: E402
from scene3D.multiview import reconstruct_views, state  # noqa: E402
from scene3D.optim import bundle  # noqa: E402
from scene3D.optim.bundle import reprojection_residuals  # noqa: E402


def capture_final_adjustment(case: str, folder: Path) -> dict:
    """Run the reconstruction and keep the inputs of its last global bundle adjustment."""
    calls = []
    original = state.bundle_adjust

    def keep(R, t, X, obs, K, fixed, **kwargs):
        out = original(R, t, X, obs, K, fixed, **kwargs)
        calls.append((R.copy(), t.copy(), X.copy(), obs, K, np.atleast_1d(fixed), kwargs,
                      out[0]))
        return out

    state.bundle_adjust = keep
    try:
        if case.startswith("orbit"):
            from scene3D.evaluation.synthetic import asymmetric_camera, orbit_poses

            n = int(case[5:])
            step = ORBIT_VIEWS // n
            paths = [folder / f"{k:03d}.png" for k in range(0, ORBIT_VIEWS, step)]
            K = asymmetric_camera(640, 480)
            Rs, ts = orbit_poses(ORBIT_VIEWS)
            R_true, t_true = Rs[::step], ts[::step]
            C_true = camera_centers(R_true, t_true)
            r = reconstruct_views(paths, K, np.zeros(5), max_width=None)
        else:
            root = default_data_root() / case
            truth = read_strecha_scene(root)
            paths, R_true, C_true = truth.paths, truth.R, truth.centers
            r = reconstruct_views(paths, np.loadtxt(root / "images" / "K.txt"), np.zeros(5))
    finally:
        state.bundle_adjust = original
    # The first global adjustment once every view is registered (tolerance 1e-6, see
    # mapper.grow_model): the one that moves the cameras most of the final ones.
    R, t, X, obs, K, fixed, kwargs, R_out = [c for c in calls
                                             if c[6].get("tolerance") == 1e-6][-1]
    # The mapper numbers views in its own order (by content); the result, in the input
    # order, holds the last adjustment's rotations: match them.
    truth = np.full(len(R), -1)
    for v in np.unique(obs.view):
        truth[v] = int(np.argmin(np.linalg.norm(np.nan_to_num(r.R - R_out[v], nan=9.0),
                                                axis=(1, 2))))
    return {"R": R, "t": t, "X": X, "obs": obs, "K": K, "fixed": fixed,
            "R_true": R_true[truth], "C_true": C_true[truth], "size": r.image_size}


def sum_of_squares(R, t, X, obs, K) -> float:
    return float(np.sum(reprojection_residuals(R, t, X, obs, K) ** 2))


def errors(p: dict, R: np.ndarray, t: np.ndarray) -> str:
    seen = np.unique(p["obs"].view)
    err = camera_set_error(R[seen], camera_centers(R, t)[seen], p["R_true"][seen],
                           p["C_true"][seen])
    return (f"{100 * err.center_errors.max():.3f} / {100 * np.median(err.center_errors):.3f} | "
            f"{err.rotation_errors_deg.max():.3f} / {np.median(err.rotation_errors_deg):.3f}")


def solve_scene3d(p: dict, loss: str, iterations: int) -> tuple:
    c0, w0 = time.process_time(), time.perf_counter()
    counted = []
    original = bundle.levenberg_marquardt

    def counting(state, cost, linearize, max_iterations, min_decrease):
        def counted_linearize(s):
            counted.append(1)
            return linearize(s)
        return original(state, cost, counted_linearize, max_iterations, min_decrease)

    bundle.levenberg_marquardt = counting
    try:
        R, t, X = bundle.bundle_adjust(p["R"], p["t"], p["X"], p["obs"], p["K"], p["fixed"],
                                       loss=loss, scale_px=1.0, max_iterations=iterations,
                                       tolerance=1e-10)
    finally:
        bundle.levenberg_marquardt = original
    return R, t, X, time.process_time() - c0, time.perf_counter() - w0, len(counted)


def solve_ceres(p: dict, loss: str, iterations: int, solver: str) -> tuple:
    import pyceres
    import pycolmap

    seen = np.unique(p["obs"].view)
    registered = np.zeros(len(p["R"]), dtype=bool)
    registered[seen] = True
    names = [f"{v}.png" for v in range(len(p["R"]))]
    files = colmap_text(colmap_model_from_views(
        names, p["K"], p["size"], registered, p["R"], p["t"], p["X"],
        np.zeros((len(p["X"]), 3), np.uint8), p["obs"].view, p["obs"].point, p["obs"].xy))
    with tempfile.TemporaryDirectory() as tmp:
        for name, text in files.items():
            (Path(tmp) / name).write_text(text)
        rec = pycolmap.Reconstruction(tmp)
    c0, w0 = time.process_time(), time.perf_counter()
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = False
    options.refine_principal_point = False
    options.refine_extra_params = False
    options.ceres.loss_function_type = (pycolmap.LossFunctionType.SOFT_L1 if loss == "soft_l1"
                                        else pycolmap.LossFunctionType.TRIVIAL)
    options.ceres.loss_function_scale = 1.0
    config = pycolmap.BundleAdjustmentConfig()
    for image_id in rec.reg_image_ids():
        config.add_image(image_id)
    fixed_ids = {int(v) + 1 for v in p["fixed"]} & set(rec.reg_image_ids())
    for image_id in fixed_ids:
        config.set_constant_rig_from_world_pose(rec.image(image_id).frame_id)
    adjuster = pycolmap.create_default_ceres_bundle_adjuster(options, config, rec)
    solver_options = pyceres.SolverOptions()
    solver_options.linear_solver_type = getattr(pyceres.LinearSolverType, solver)
    if solver == "ITERATIVE_SCHUR":
        solver_options.preconditioner_type = pyceres.PreconditionerType.SCHUR_JACOBI
    solver_options.num_threads = 1
    solver_options.max_num_iterations = iterations
    solver_options.function_tolerance = 1e-10
    solver_options.minimizer_progress_to_stdout = False
    summary = pyceres.SolverSummary()
    pyceres.solve(solver_options, adjuster.problem, summary)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    R, t, X = p["R"].copy(), p["t"].copy(), p["X"].copy()
    for image_id in rec.reg_image_ids():
        pose = rec.image(image_id).cam_from_world()
        R[image_id - 1] = pose.rotation.matrix()
        t[image_id - 1] = pose.translation
    for point_id, point in rec.points3D.items():
        X[point_id - 1] = point.xyz
    return R, t, X, cpu, wall, summary.num_successful_steps + summary.num_unsuccessful_steps


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", nargs="+", default=["castle-P19", "orbit200"])
    parser.add_argument("--iterations", type=int, default=30,
                        help="iterations at most for every solver (the mapper's final count)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    print("| case | cameras / points / observations | loss | solver | CPU s | wall s | "
          "iterations | sum of squares px^2 | centre max / median (% extent) | "
          "rotation max / median (deg) |")
    print("|---" * 10 + "|")
    with tempfile.TemporaryDirectory() as tmp:
        if any(c.startswith("orbit") for c in args.cases):
            render_orbit(Path(tmp))
        for case in args.cases:
            p = capture_final_adjustment(case, Path(tmp))
            size = (f"{len(np.unique(p['obs'].view))} / {len(p['X'])} / "
                    f"{len(p['obs'].view)}")
            many = len(np.unique(p["obs"].view)) > 50
            solvers = (["SPARSE_SCHUR", "ITERATIVE_SCHUR"] if many else ["DENSE_SCHUR"])
            for loss in ("linear", "soft_l1"):
                rows = [("scene3D", solve_scene3d(p, loss, args.iterations))]
                rows += [(f"Ceres {s.lower()}", solve_ceres(p, loss, args.iterations, s))
                         for s in solvers]
                for label, (R, t, X, cpu, wall, its) in rows:
                    print(f"| {case} | {size} | {loss} | {label} | {cpu:.2f} | {wall:.2f} | "
                          f"{its} | {sum_of_squares(R, t, X, p['obs'], p['K']):.2f} | "
                          f"{errors(p, R, t)} |", flush=True)
    print(f"({time.strftime('%Y-%m-%d')}, load average {os.getloadavg()[0]:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
