"""The distortion check on the shared scenes photographed through a lens the calibration
leaves out: does it flag the wrong poses, and only those?

    python benchmarks/distortion_check.py [--data DIR] [--scenes ...] [--gaps 1 2]
                                          [--k1 0 -0.05 -0.1 -0.2 0.05] [--sizes 768]

Both photos of every pair (i, i + gap) are warped as a lens with radial distortion ``k1``
would have taken them (``r_d = r_u (1 + k1 r_u^2)`` in normalised coordinates about the
Strecha principal point; ``k1 = 0``: the photos as they are, decoded whole and then
halved), and reconstructed with the true, distortion-free ``K`` by every check that
``chapter4.py`` runs (``scene3D.twoview.reconstruct_two_view`` with both images, the
flow's too). Printed per scene, size and ``k1``: the pairs answered; the right poses (within 1
degree; the larger of the rotation and translation-direction errors) and those the
distortion check flags; the largest pose shift among right poses it checked
(``distortion_pose_shift_deg``: how far the pose refined with a radial distortion
lies); the poses more than 5 and more than 2 degrees off that every other check
trusted, and how many of them the distortion check flags. The check runs only on poses
that passed every other check, so a pose it flags would be trusted without it. One
thread; about 15 minutes for the defaults.
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np
from bench_cli import add_data_arguments, quiet_run

from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.evaluation.synthetic import lens_photo
from scene3D.features import image_features, match_features
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.datasets import read_strecha_camera, relative_pose, strecha_views
from scene3D.io.images import load_working_image
from scene3D.twoview import reconstruct_two_view

#: Words of the check's warning that name its cause (scene3D.twoview.trust.distortion_warning).
DISTORTION_WORDS = "lens distortion"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser, gaps=(1, 2), scenes=True)
    parser.add_argument("--k1", type=float, nargs="+", default=[0.0, -0.05, -0.1, -0.2, 0.05],
                        help="radial distortions of the lens (0: the photos as they are)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[768],
                        help="working widths in px")
    args = parser.parse_args(argv)
    data = quiet_run(parser, args)
    print("| scene | width | k1 | pairs | right (< 1 deg): flagged by the check | largest "
          "shift of a right pose (deg) | > 5 deg off, trusted by the rest: flagged by it "
          "| > 2 deg off, the same |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        views = strecha_views(data / scene)
        cameras = [read_strecha_camera(camera) for _, camera in views]
        for width in args.sizes:
            for k1 in args.k1:
                features, images, K = [], [], None
                for (path, _), camera in zip(views, cameras):
                    native = lens_photo(cv2.imread(str(path), cv2.IMREAD_COLOR), camera.K, k1)
                    img, _, levels = load_working_image(native, camera.K, camera.dist, width)
                    images.append(img)
                    features.append(image_features(img))
                    K = scale_intrinsics_halved(camera.K, levels)
                pairs = [(i, i + gap) for gap in args.gaps for i in range(len(views) - gap)]
                answered, right, right_flagged, shifts = 0, 0, 0, [0.0]
                off5, off5_flagged, off2, off2_flagged = 0, 0, 0, 0
                for i, j in pairs:
                    try:
                        result = reconstruct_two_view(images[i], match_features(
                            features[i], features[j]), K, img2=images[j])
                    except ReconstructionError:
                        continue
                    answered += 1
                    error = relative_pose_error(result.R, result.t,
                                                *relative_pose(cameras[i], cameras[j])).max_deg
                    by_check = any(DISTORTION_WORDS in w for w in result.warnings)
                    if error < 1:
                        right += 1
                        right_flagged += by_check
                        if np.isfinite(result.distortion_pose_shift_deg):
                            shifts.append(result.distortion_pose_shift_deg)
                    if result.trusted or by_check:  # trusted by every other check
                        off5 += error > 5
                        off5_flagged += error > 5 and by_check
                        off2 += error > 2
                        off2_flagged += error > 2 and by_check
                print(f"| {scene} | {width} | {k1:g} | {answered} | {right}: {right_flagged} "
                      f"| {max(shifts):.2f} | {off5}: {off5_flagged} | {off2}: {off2_flagged} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
