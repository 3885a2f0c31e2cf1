"""The focal-length check against calibrations that are off: how many pairs it flags.

    python benchmarks/focal_check.py [--data DIR] [--scenes ...] [--sizes 768 1536]
                                     [--gaps 1 2 3 4 5]
                                     [--factors 1 0.8 0.85 1.18 1.25 1.5]

Each pair (i, i+gap) of each scene is reconstructed with the true K and with K whose
focal lengths are multiplied by each factor (principal point kept), from the same
matches, as ``chapter4.py`` and ``scene3d evaluate`` do: the sparse checks
(``reconstruct_from_matches``), then the dense flow check with both images
(``check_against_flow``). For each scene, factor and size it prints the median
``focal_scale`` the matches call for (expected: 1 / factor), how many pairs are flagged
for it (a warning about the focal length), the poses more than 5 deg off and how many of
them end trusted, and the right poses (both errors under 1 deg) that end flagged. A
refused pair counts as flagged, not as wrong. One thread; about 9 minutes.
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_cli import add_data_arguments, quiet_run

from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.features import image_features, match_features
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.datasets import read_strecha_camera, relative_pose, strecha_views
from scene3D.io.images import load_working_image
from scene3D.twoview import check_against_flow, reconstruct_from_matches


def measure(views, width: int, gaps: list[int], factors: list[float]) -> list[dict]:
    cameras = [read_strecha_camera(cam) for _, cam in views]
    images, features, K = [], [], None
    for (path, _), cam in zip(views, cameras):
        img, _, levels = load_working_image(path, cam.K, cam.dist, width)
        images.append(img)
        features.append(image_features(img))
        K = scale_intrinsics_halved(cam.K, levels)
    pairs = [(a, a + g) for g in gaps for a in range(len(views) - g)]
    matches = {(a, b): match_features(features[a], features[b]) for a, b in pairs}
    rows = []
    for factor in factors:
        K_wrong = K.copy()
        K_wrong[0, 0] *= factor
        K_wrong[1, 1] *= factor
        row = {"factor": factor, "width": width, "pairs": len(pairs), "scales": [],
               "flagged": 0, "wrong": 0, "wrong_trusted": 0, "right": 0,
               "right_flagged": 0}
        for a, b in pairs:
            m = matches[(a, b)]
            try:
                sparse = reconstruct_from_matches(m.pts1, m.pts2, K_wrong,
                                                  image_size=images[a].shape[1::-1])
            except ReconstructionError:
                row["flagged"] += 1
                continue
            result = check_against_flow(sparse, images[a], images[b])
            row["scales"].append(result.focal_scale)
            row["flagged"] += any("focal length" in w for w in result.warnings)
            err = relative_pose_error(result.R, result.t,
                                      *relative_pose(cameras[a], cameras[b])).max_deg
            row["wrong"] += err > 5.0
            row["wrong_trusted"] += err > 5.0 and result.trusted
            row["right"] += err < 1.0
            row["right_flagged"] += err < 1.0 and not result.trusted
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_data_arguments(parser, gaps=(1, 2, 3, 4, 5), scenes=True)
    parser.add_argument("--sizes", type=int, nargs="+", default=[768, 1536],
                        help="working widths (default: 768 1536)")
    parser.add_argument("--factors", type=float, nargs="+",
                        default=[1.0, 0.8, 0.85, 1.18, 1.25, 1.5],
                        help="calibration focal length / true focal length")
    args = parser.parse_args(argv)
    data = quiet_run(parser, args)
    print("| scene | calibration focal / true | width | median focal_scale (expected) | range "
          "| pairs flagged for it | pairs > 5 deg off | of those trusted | right poses (< 1 "
          "deg) flagged |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        views = strecha_views(data / scene)
        rows = [r for width in args.sizes for r in measure(views, width, args.gaps,
                                                           args.factors)]
        for r in sorted(rows, key=lambda r: (r["factor"], r["width"])):
            scales = r["scales"] or [float("nan")]
            print(f"| {scene} | {r['factor']:g} | {r['width']} | {np.median(scales):.3f} "
                  f"({1 / r['factor']:.2f}) | {min(scales):.3f}-{max(scales):.3f} | "
                  f"{r['flagged']} of {r['pairs']} | {r['wrong']} | {r['wrong_trusted']} | "
                  f"{r['right_flagged']} of {r['right']} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
