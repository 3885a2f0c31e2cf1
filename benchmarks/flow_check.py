"""The dense flow check on every pair of the shared scenes: does it flag the wrong poses,
and only those?

    python benchmarks/flow_check.py [--data DIR] [--scenes ...] [--gaps 1 2 3 4 5]
                                    [--sizes 768 1536]

Each pair (i, i + gap) is reconstructed from its SIFT matches with the Strecha camera's
``K`` (``scene3D.twoview.reconstruct_from_matches``, the sparse checks only), then checked
against the dense optical flow between its images (``scene3D.twoview.flow_check``), on every
pair, including those the sparse checks already flag (the pipeline checks only trusted
poses). Printed per scene and size: the pairs; the right poses (both errors under 1
degree) and the largest flow gain among them; the poses more than 2 degrees off and their
gains; the verdicts the check changes (trusted -> flagged, with the errors of the pose and
of the flow's pose); the seconds the check takes a pair (median). Then every pair whose
gain exceeds half of ``TwoViewSettings.max_flow_gain``. The flow is taken at 768 px at
most (``scene3D.twoview.flow_check.MAX_FLOW_WIDTH_PX``). One thread; about 12 minutes for the
three scenes at both sizes.
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np
from bench_cli import add_data_arguments, data_folder

from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.features import find_matches, to_gray
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.datasets import read_strecha_camera, relative_pose, strecha_views
from scene3D.io.images import load_working_image
from scene3D.twoview import TwoViewSettings, check_against_flow, reconstruct_from_matches
from scene3D.twoview.flow_check import check_pose_against_images
from scene3D.twoview.trust import flow_warning


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser, gaps=(1, 2, 3, 4, 5), scenes=True)
    parser.add_argument("--sizes", type=int, nargs="+", default=[768, 1536],
                        help="working widths in px")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    data = data_folder(parser, args)
    settings = TwoViewSettings()
    print("| scene | width | pairs | right (< 1 deg) | their largest gain | > 2 deg off: gains "
          "| newly flagged: pose / flow's pose error (deg) | s a pair |")
    print("|---|---|---|---|---|---|---|---|")
    notable = []
    for scene in args.scenes:
        views = strecha_views(data / scene)
        cameras = [read_strecha_camera(camera) for _, camera in views]
        for width in args.sizes:
            images, K = [], None
            for (path, _), camera in zip(views, cameras):
                img, _, levels = load_working_image(path, camera.K, camera.dist, width)
                images.append(img)
                K = scale_intrinsics_halved(camera.K, levels)
            pairs = [(i, i + gap) for gap in args.gaps for i in range(len(views) - gap)]
            right_gains, wrong, newly, seconds = [], [], [], []
            for i, j in pairs:
                matches = find_matches(images[i], images[j])
                try:
                    geometry = reconstruct_from_matches(matches.pts1, matches.pts2, K, settings)
                except ReconstructionError:
                    continue
                truth = relative_pose(cameras[i], cameras[j])
                error = relative_pose_error(geometry.R, geometry.t, *truth).max_deg
                t0 = time.perf_counter()
                flow = check_pose_against_images(geometry.R, geometry.t, K, to_gray(images[i]),
                                                 to_gray(images[j]), geometry.inlier_pts1,
                                                 geometry.inlier_pts2)
                seconds.append(time.perf_counter() - t0)
                if flow is None:
                    continue
                flow_error = relative_pose_error(flow.R, flow.t, *truth).max_deg
                if error < 1:
                    right_gains.append(flow.gain)
                elif error > 2:
                    wrong.append(f"{i}-{j} {flow.gain:.2f}")
                checked = check_against_flow(geometry, images[i], images[j], settings)
                if geometry.trusted and not checked.trusted:
                    newly.append(f"{i}-{j} {error:.1f} / {flow_error:.1f}")
                if flow.gain > settings.max_flow_gain / 2:
                    doubt = flow_warning(geometry.R, geometry.t, flow, settings)
                    notable.append(f"{scene} {width} {i}-{j}: {error:.2f} deg off, "
                                   f"{'trusted' if geometry.trusted else 'flagged'} before, "
                                   f"gain {flow.gain:.3f}, {flow.points} flow points, flow's "
                                   f"pose {flow_error:.2f} deg off"
                                   + ("" if doubt else ", no doubt (gain or distance)"))
            print(f"| {scene} | {width} | {len(pairs)} | {len(right_gains)} | "
                  f"{max(right_gains, default=float('nan')):.3f} | {', '.join(wrong) or '-'} | "
                  f"{', '.join(newly) or '-'} | {np.median(seconds):.2f} |", flush=True)
    print()
    print("Gains above half the limit:")
    for line in notable:
        print(f"- {line}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
