"""The focal-length check against calibrations that are off: how many pairs it flags.

    python benchmarks/focal_check.py [--data DIR] [--sizes 768 1536] [--gaps 1 2 3 4 5]
                                     [--factors 1 0.8 0.85 1.18 1.25 1.5]

Each fountain-P11 pair (i, i+gap) is reconstructed with the true K and with K whose focal
lengths are multiplied by each factor (principal point kept), from the same matches. For
each factor and size it prints the median ``focal_scale`` the matches call for (expected:
1 / factor), how many pairs the check flags for it (a warning about the focal length),
and how many pairs end more than 5 deg off without any flag. A refused pair counts as
flagged, not as wrong.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from scene3D.camera import scale_intrinsics_halved
from scene3D.datasets import (
    FOUNTAIN_P11,
    default_data_root,
    read_strecha_camera,
    relative_pose,
    strecha_views,
)
from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.features import image_features, match_features
from scene3D.imageio import load_working_image
from scene3D.twoview import reconstruct_from_matches


def measure(views, width: int, gaps: list[int], factors: list[float]) -> list[dict]:
    cameras = [read_strecha_camera(cam) for _, cam in views]
    features, K = [], None
    for (path, _), cam in zip(views, cameras):
        img, _, levels = load_working_image(path, cam.K, cam.dist, width)
        features.append(image_features(img))
        K = scale_intrinsics_halved(cam.K, levels)
    pairs = [(a, a + g) for g in gaps for a in range(len(views) - g)]
    matches = {(a, b): match_features(features[a], features[b]) for a, b in pairs}
    rows = []
    for factor in factors:
        K_wrong = K.copy()
        K_wrong[0, 0] *= factor
        K_wrong[1, 1] *= factor
        scales, flagged, wrong, wrong_unflagged = [], 0, 0, 0
        for a, b in pairs:
            m = matches[(a, b)]
            try:
                result = reconstruct_from_matches(m.pts1, m.pts2, K_wrong)
            except ReconstructionError:
                flagged += 1
                continue
            scales.append(result.focal_scale)
            flagged += any("focal length" in w for w in result.warnings)
            err = relative_pose_error(result.R, result.t,
                                      *relative_pose(cameras[a], cameras[b]))
            if max(err.rotation_deg, err.translation_deg) > 5.0:
                wrong += 1
                wrong_unflagged += result.trusted
        rows.append({"factor": factor, "width": width, "pairs": len(pairs),
                     "median_scale": float(np.median(scales)), "min_scale": min(scales),
                     "max_scale": max(scales), "flagged": flagged, "wrong": wrong,
                     "wrong_unflagged": wrong_unflagged})
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None,
                        help="folder holding fountain-P11/ (default: $SCENE3D_DATA)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[768, 1536],
                        help="working widths (default: 768 1536)")
    parser.add_argument("--gaps", type=int, nargs="+", default=[1, 2, 3, 4, 5],
                        help="pairs (i, i+gap) (default: 1 2 3 4 5, 40 pairs)")
    parser.add_argument("--factors", type=float, nargs="+",
                        default=[1.0, 0.8, 0.85, 1.18, 1.25, 1.5],
                        help="calibration focal length / true focal length")
    args = parser.parse_args(argv)
    root = args.data or default_data_root()
    if root is None or not (root / FOUNTAIN_P11).is_dir():
        print("error: fountain-P11 not found; set SCENE3D_DATA or pass --data", file=sys.stderr)
        return 2
    views = strecha_views(root / FOUNTAIN_P11)
    rows = [r for width in args.sizes for r in measure(views, width, args.gaps, args.factors)]
    print("| calibration focal / true | width | median focal_scale (expected) | range | "
          "pairs flagged for it | pairs > 5 deg off | of those not flagged at all |")
    print("|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["factor"], r["width"])):
        print(f"| {r['factor']:g} | {r['width']} | {r['median_scale']:.3f} "
              f"({1 / r['factor']:.2f}) | {r['min_scale']:.3f}-{r['max_scale']:.3f} | "
              f"{r['flagged']} of {r['pairs']} | {r['wrong']} | {r['wrong_unflagged']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
