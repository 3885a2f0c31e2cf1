"""The reduced camera system of many cameras: dense, sparse and iterative solves side by side.

    python benchmarks/reduced_camera_system.py [--cameras 100 250 500 1000] [--adjust 500]
        [--damping 1e-3 1e-6] [--adjust-iterations 20]

A ring of cameras looking outward (an orbit or a video's banded covisibility: each point is
in front of 3 to 6 consecutive cameras, about 300 points per camera, camera 0 fixed), with
the reprojection Jacobians of :func:`scene3D.optim.bundle.reprojection_jacobians` and random
residuals. For each camera count, each method of :func:`scene3D.optim.schur.solve_damped`
(``dense``, ``sparse``, ``iterative``) takes one step at each damping (Levenberg-Marquardt
starts at 1e-3; later steps take less) in a forked process: its time, the growth of the peak
resident memory during the solve (Linux ``VmHWM`` after resetting it), the conjugate
gradients' iterations and the step's difference from the dense one. Then one
:func:`scene3D.optim.bundle.bundle_adjust` of ``--adjust`` cameras (0.5 px noise, poses
and points perturbed) with each method: time, solves (one per damping tried), final cost.
Single-threaded BLAS, as the other benchmarks.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scene3D.evaluation.synthetic import outward_ring  # noqa: E402
from scene3D.geometry import project, rotations_from_vectors  # noqa: E402
from scene3D.optim import bundle, schur  # noqa: E402
from scene3D.optim.bundle import Observations, reprojection_jacobians  # noqa: E402

K = np.array([[700.0, 0, 333.0], [0, 690.0, 231.0], [0, 0, 1]])
METHODS = ("dense", "sparse", "iterative")


def ring(num_cameras, points_per_camera=270, seed=0, spacing=0.5):
    """:func:`scene3D.evaluation.synthetic.outward_ring`, 270 points per camera by default."""
    return outward_ring(num_cameras, points_per_camera, seed, spacing)


def _status_kib(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise KeyError(field)


class _Iterations(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.iterations: list[int] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.getMessage().startswith("conjugate gradients:"):
            self.iterations.append(int(record.args[0]))


def _solve_once(ne, method, damping, queue) -> None:
    Path("/proc/self/clear_refs").write_text("5")  # the peak resident memory restarts here
    before = _status_kib("VmRSS")
    handler = _Iterations()
    log = logging.getLogger(schur.__name__)
    log.addHandler(handler)
    log.setLevel(logging.DEBUG)
    start = time.perf_counter()
    steps = schur.solve_damped(ne, damping, method=method)
    elapsed = time.perf_counter() - start
    queue.put((elapsed, (_status_kib("VmHWM") - before) / 1024, handler.iterations, steps))


def solve_table(camera_counts: list[int], dampings: list[float]) -> None:
    print("| cameras | observations | damping | method | solve s | peak memory MiB "
          "| PCG iterations | step vs dense |")
    print("|---:|---:|---:|---|---:|---:|---:|---:|")
    context = multiprocessing.get_context("fork")
    for C in camera_counts:
        R, t, X, view, point = ring(C)
        obs = Observations(view, point, np.zeros((len(view), 2)))
        J_camera, J_point, _ = reprojection_jacobians(R, t, X, obs, K)
        r = np.random.default_rng(1).normal(size=(len(view), 2))
        ne = schur.normal_equations(J_camera, view - 1, J_point, point, r, C - 1, len(X))
        del J_camera, J_point, r, obs
        for damping in dampings:
            dense = None
            for method in METHODS:
                queue = context.Queue()
                child = context.Process(target=_solve_once, args=(ne, method, damping, queue))
                child.start()
                elapsed, peak_mib, iterations, steps = queue.get()
                child.join()
                x = np.concatenate([s.ravel() for s in steps])
                dense = x if method == "dense" else dense
                difference = np.linalg.norm(x - dense) / np.linalg.norm(dense)
                print(f"| {C} | {len(view)} | {damping:g} | {method} | {elapsed:.2f} | "
                      f"{peak_mib:.0f} | {iterations[0] if iterations else '-'} | "
                      f"{'-' if method == 'dense' else f'{difference:.1e}'} |", flush=True)


def adjust_table(C: int, max_iterations: int) -> None:
    rng = np.random.default_rng(9)
    R, t, X, view, point = ring(C, seed=9)
    xy = np.empty((len(view), 2))
    for v in range(C):
        on = view == v
        xy[on] = project(X[point[on]], K, R[v], t[v])
    obs = Observations(view, point, xy + rng.normal(0, 0.5, xy.shape))
    R0 = rotations_from_vectors(rng.normal(0, 0.002, (C, 3))) @ R
    t0 = t + rng.normal(0, 0.01, t.shape)
    R0[0], t0[0] = R[0], t[0]
    X0 = X + rng.normal(0, 0.02, X.shape)
    print(f"\nbundle_adjust, {C} cameras, {len(X)} points, {len(view)} observations "
          f"(linear loss, camera 0 fixed, at most {max_iterations} iterations)\n")
    print("| method | time s | solves | final cost px^2 | start cost px^2 |")
    print("|---|---:|---:|---:|---:|")
    solve = bundle.solve_damped_global
    for method in METHODS:
        calls = []

        def counted(ne, damping, method=method, calls=calls):
            calls.append(damping)
            return solve(ne, damping, method=method)

        bundle.solve_damped_global = counted
        start = time.perf_counter()
        R1, t1, X1 = bundle.bundle_adjust(R0, t0, X0, obs, K, fixed_view=0, loss="linear",
                                        max_iterations=max_iterations)
        elapsed = time.perf_counter() - start
        bundle.solve_damped_global = solve
        final = float((bundle.reprojection_residuals(R1, t1, X1, obs, K) ** 2).sum())
        initial = float((bundle.reprojection_residuals(R0, t0, X0, obs, K) ** 2).sum())
        print(f"| {method} | {elapsed:.1f} | {len(calls)} | {final:.6f} | {initial:.0f} |",
              flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cameras", type=int, nargs="+", default=[100, 250, 500, 1000])
    parser.add_argument("--damping", type=float, nargs="+", default=[1e-3, 1e-6],
                        help="Levenberg-Marquardt dampings of the single solves")
    parser.add_argument("--adjust", type=int, default=500,
                        help="cameras of the bundle adjustment (0: none)")
    parser.add_argument("--adjust-iterations", type=int, default=20,
                        help="its Levenberg-Marquardt iterations at most (the library's "
                             "default, 50, takes the run past 8 minutes)")
    args = parser.parse_args(argv)
    solve_table(args.cameras, args.damping)
    if args.adjust:
        adjust_table(args.adjust, args.adjust_iterations)
    return 0


if __name__ == "__main__":
    sys.exit(main())
