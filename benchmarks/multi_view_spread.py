"""Many views: how far the camera-error figures move with another draw of the same scene's points.

    python benchmarks/multi_view_spread.py [--scenes Herz-Jesus-P8 fountain-P11 castle-P19]
                                           [--draws 30] [--width 1536]

For each shared Strecha scene (``$SCENE3D_DATA``), ``reconstruct_views`` with default
options, then a bootstrap over its points of three views or more, those that hold the
cameras in the mapper's adjustments (two-view points follow them): the points are drawn
with replacement (each with all its observations) and the final bundle adjustment is run
again from the model's cameras (:func:`scene3D.optim.bundle.bundle_adjust`, the mapper's loss,
its first camera held).
Each draw's cameras are compared with the true ones as ``benchmarks/multi_view.py``
compares them (max / median centre errors in % of the extent of the true centres, aligned
by the orientations and by the centres). Prints the model's own figures and the draws'
mean and standard deviation: the spread that a benchmark figure has from the points
alone, against which a difference between two programs' figures can be weighed. One
BLAS and one OpenCV thread.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from scene3D.evaluation import camera_set_error  # noqa: E402
from scene3D.geometry import camera_centers  # noqa: E402
from scene3D.io.datasets import default_data_root, read_strecha_scene  # noqa: E402
from scene3D.multiview import reconstruct_views  # noqa: E402
from scene3D.optim.bundle import Observations, bundle_adjust  # noqa: E402


def figures(R, centers, R_true, C_true) -> list[float]:
    """Centre errors in % of the extent, max and median: aligned by the orientations, then by
    the centres."""
    out = []
    for align in ("orientations", "centres"):
        e = camera_set_error(R, centers, R_true, C_true, align=align)
        out += [100 * e.center_errors.max(), 100 * np.median(e.center_errors)]
    return out


def resampled(obs: Observations, num_points: int, rng: np.random.Generator
              ) -> tuple[np.ndarray, Observations]:
    """A bootstrap draw among the points of three views or more: the drawn points
    ``(P,)`` (indices into the model's) and their observations, each drawn point a
    point of its own."""
    order = np.argsort(obs.point, kind="stable")
    starts = np.searchsorted(obs.point[order], np.arange(num_points + 1))
    multi = np.flatnonzero(np.diff(starts) >= 3)
    pick = multi[rng.integers(0, len(multi), len(multi))]
    rows = np.concatenate([order[starts[p]:starts[p + 1]] for p in pick])
    point = np.repeat(np.arange(len(pick)), starts[pick + 1] - starts[pick])
    sigma = None if obs.sigma is None else obs.sigma[rows]
    return pick, Observations(obs.view[rows], point, obs.xy[rows], sigma)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="*",
                        default=["Herz-Jesus-P8", "fountain-P11", "castle-P19"])
    parser.add_argument("--draws", type=int, default=30)
    parser.add_argument("--width", type=int, default=1536, choices=(768, 1536, 3072))
    args = parser.parse_args()
    cv2.setNumThreads(1)
    print("| scene | points / observations | | orientations: centre max | median "
          "| centres: centre max | median |")
    print("|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        root = default_data_root() / scene
        truth = read_strecha_scene(root)
        r = reconstruct_views(truth.paths, truth.cameras[0].K, np.zeros(5),
                              max_width=args.width, progress=lambda message: None)
        model = r.models[0]
        reg = np.flatnonzero(model.registered)
        R_true, C_true = truth.R[reg], truth.centers[reg]
        own = figures(model.R[reg], model.centers[reg], R_true, C_true)
        rng = np.random.default_rng(0)
        draws = []
        for _ in range(args.draws):
            pick, obs = resampled(model.observations, len(model.points3d), rng)
            R, t, _ = bundle_adjust(model.R.copy(), model.t.copy(), model.points3d[pick].copy(),
                                    obs, r.K, int(reg[0]), max_iterations=30, tolerance=1e-8)
            draws.append(figures(R[reg], camera_centers(R[reg], t[reg]), R_true, C_true))
        draws = np.array(draws)
        size = f"{len(model.points3d)} / {len(model.observations.view)}"
        print(f"| {scene} | {size} | the model | "
              + " | ".join(f"{v:.3f}" for v in own) + " |")
        print(f"| {scene} | {size} | {args.draws} draws: mean +- std | "
              + " | ".join(f"{m:.3f} +- {s:.3f}" for m, s in zip(draws.mean(0), draws.std(0)))
              + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
