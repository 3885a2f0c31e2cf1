"""Cameras that only turned: a fountain-P11 photo and its exact rotations, under the
camera's calibration and under calibrations for another zoom.

    python benchmarks/pure_rotation.py [--data DIR] [--features SIFT ORB]

Image 2 is image 1 (0004.jpg) warped by ``K R K^-1``, ``K`` the Strecha camera's: what a
camera that only turned sees, with no baseline and no noise but the resampling's. Each
row reconstructs the pair with the book's class at its default size (768 px), given ``K``
with its focal lengths times ``factor``. A pure rotation has no translation to find: the
right answer is a refusal (no parallax, or a plane, as the rotation's homography is one),
or a flagged pose; a trusted one is wrong. Printed: what came back, the rotation found
(the truth is the angle in the row), the sigmas, the focal check's factor, the warnings.
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np
from bench_cli import add_data_arguments, data_folder, reconstruct_or_refusal, verdict

from scene3D import SceneReconstruction3D
from scene3D.errors import ReconstructionError
from scene3D.geometry import rotations_from_vectors
from scene3D.io.datasets import read_strecha_camera

#: (rotation vector in degrees, focal-length factor of the calibration given).
CASES = [((0, 5, 0), 1.0), ((0, 5, 0), 1.3), ((0, 5, 0), 0.8), ((1, 5, 0), 1.1),
         ((0, 0.5, 0), 1.0), ((0, 10, 0), 1.0), ((5, 3, 2), 1.0)]


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser)
    parser.add_argument("--features", nargs="+", default=["SIFT", "ORB"])
    args = parser.parse_args(argv)
    fountain = data_folder(parser, args) / "fountain-P11"
    camera = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera")
    img = cv2.imread(str(fountain / "images" / "0004.jpg"))
    print("| feature | rotation (deg) | K factor | result | rotation found (deg) | "
          "sigmas rot / t-dir (deg) | focal check | warnings |")
    print("|---|---|---|---|---|---|---|---|")
    for feature in args.features:
        for turn, factor in CASES:
            R = rotations_from_vectors(np.radians([turn]))[0]
            turned = cv2.warpPerspective(img, camera.K @ R @ np.linalg.inv(camera.K),
                                         img.shape[1::-1])
            K = camera.K.copy()
            K[:2, :2] *= factor
            scene = SceneReconstruction3D(K)
            scene.load_image_pair(img, turned)
            r = reconstruct_or_refusal(scene, feature)
            head = f"| {feature} | {_angle_deg(R):.2f} | {factor:g} | {verdict(r)} |"
            if isinstance(r, ReconstructionError):
                print(f"{head} | | | {r.message[:90]} |")
                continue
            print(f"{head} {_angle_deg(r.R):.2f} | "
                  f"{r.rotation_sigma_deg:.2g} / {r.translation_sigma_deg:.2g} | "
                  f"{r.focal_scale:.3f} | {'; '.join(w[:90] for w in r.warnings)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
