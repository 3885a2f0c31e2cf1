"""Many views: observations weighed by keypoint size, against equal weights.

    python benchmarks/multi_view_weights.py [--scenes castle-P19 fountain-P11 Herz-Jesus-P8]
                                            [--width 1536]

For each shared Strecha scene (``$SCENE3D_DATA``), ``reconstruct_views`` with default
options, once with ``SfMSettings(weight_by_size=False)`` (every observation weighs the
same) and once with the default (each residual divided by a sigma proportional to its
keypoint's size, :mod:`scene3D.multiview.weights`). Prints, per run, the model's points
and observations and the camera errors after a similarity alignment to the true cameras
(max / median; centres in % of the extent of the true centres, rotations in degrees),
aligned by the orientations and by the centres as ``benchmarks/multi_view.py`` does; then,
for the equal-weight model, the robust standard deviation (1.4826 MAD) of its
reprojection residuals per eighth of its observations ordered by keypoint size: the noise
model the weights assume. One BLAS and one OpenCV thread.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

import scene3D.multiview.pipeline as pipeline  # noqa: E402
from scene3D.evaluation import camera_set_error  # noqa: E402
from scene3D.io.datasets import default_data_root, read_strecha_scene  # noqa: E402
from scene3D.multiview import SfMSettings, reconstruct_views  # noqa: E402
from scene3D.optim.bundle import reprojection_residuals  # noqa: E402


def residuals_by_size(features, model, K) -> str:
    """Robust sigma of the residuals per eighth of the observations by keypoint size
    (``features`` and ``model`` in the mapper's order of views, ``K`` at the working size)."""
    obs = model.observations
    r = reprojection_residuals(model.R, model.t, model.points3d, obs, K)
    sizes = np.empty(len(obs.view))
    for v in np.unique(obs.view):
        on = obs.view == v
        index = {tuple(p): k for k, p in enumerate(features[v].keypoints)}
        sizes[on] = features[v].sizes[[index[tuple(p)] for p in obs.xy[on]]]
    edges = np.quantile(sizes, np.linspace(0, 1, 9))
    band = np.clip(np.searchsorted(edges, sizes, side="right") - 1, 0, 7)
    return ", ".join(f"{edges[k]:.1f}-{edges[k + 1]:.1f} px: "
                     f"{1.4826 * np.median(np.abs(r[band == k])):.3f}" for k in range(8))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="*",
                        default=["castle-P19", "fountain-P11", "Herz-Jesus-P8"])
    parser.add_argument("--width", type=int, default=1536, choices=(768, 1536, 3072))
    args = parser.parse_args()
    cv2.setNumThreads(1)
    original = pipeline.reconstruct_models
    seen: dict = {}

    def recording(features, verified, K, *rest):
        models, reasons, timings = original(features, verified, K, *rest)
        seen.update(features=features, model=models[0], K=K)
        return models, reasons, timings

    pipeline.reconstruct_models = recording
    print("| scene | weights | points | observations | centre max / median (% extent) | "
          "rotation max / median (deg) | aligned by centres |")
    print("|---|---|---|---|---|---|---|")
    notes = []
    for scene in args.scenes:
        root = default_data_root() / scene
        truth = read_strecha_scene(root)
        paths, R_true, C_true = truth.paths, truth.R, truth.centers
        K = np.loadtxt(root / "images" / "K.txt")
        for weigh in (False, True):
            r = reconstruct_views(paths, K, np.zeros(5), max_width=args.width,
                                  settings=SfMSettings(weight_by_size=weigh),
                                  progress=lambda message: None)
            reg = np.flatnonzero(r.registered)
            e = camera_set_error(r.R[reg], r.centers[reg], R_true[reg], C_true[reg])
            c = camera_set_error(r.R[reg], r.centers[reg], R_true[reg], C_true[reg],
                                 align="centres")
            print(f"| {scene} | {'by size' if weigh else 'equal'} | {len(r.points3d)} | "
                  f"{len(r.models[0].observations.view)} | "
                  f"{100 * e.center_errors.max():.3f} / {100 * np.median(e.center_errors):.3f} | "
                  f"{e.rotation_errors_deg.max():.3f} / "
                  f"{np.median(e.rotation_errors_deg):.3f} | "
                  f"{100 * c.center_errors.max():.3f} / {100 * np.median(c.center_errors):.3f} "
                  f"%, {c.rotation_errors_deg.max():.3f} / "
                  f"{np.median(c.rotation_errors_deg):.3f} deg |", flush=True)
            if not weigh:
                notes.append(f"{scene}, equal weights, residual sigma (px) by keypoint size: "
                             + residuals_by_size(seen["features"], seen["model"], seen["K"]))
    print()
    for note in notes:
        print(note)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
