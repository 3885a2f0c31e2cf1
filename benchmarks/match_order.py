"""How much scene3D's two-view figures depend on the order of the same matches.

    python benchmarks/match_order.py [--data DIR] [--scenes fountain-P11 ...]
                                     [--sizes 768 1536] [--gaps 1 2 3 4 5] [--orders 5]

The robust restarts of ``fit_essential`` draw their samples from the matches in the
order given, so the same set of matches in another order is another draw of the
estimator: on an ambiguous pair (castle-P19's repeated windows) the pose, and whether the
restarts meet twice, can change with it. The figures of ``two_view.py`` are one such draw
(the order in which the matcher lists them). This runs every pair (i, i + gap) of each
scene through ``reconstruct_from_matches`` on the same matches in ``--orders`` orders (the
matcher's, then random permutations, seeds 1, 2, ...) and prints, per scene, size and group
of gaps (1-2, 3-5): AUC@5deg over the orders (mean, least and most), the share within
2 deg, and summed over the orders the right poses (< 1 deg) flagged, the poses more than
2 deg off that are flagged, the trusted poses more than 5 and 2 deg off, the share within
the predicted 90 % bounds, and the pairs whose verdict (refused, flagged, trusted) is not
the same in every order. One thread; about 2 minutes an order for the three scenes.

Run it on another checkout (``PYTHONPATH=path/to/checkout``) to compare versions on equal
terms: its only imports are scene3D's public functions.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from bench_cli import add_data_arguments, quiet_run

import scene3D
from scene3D.errors import ReconstructionError
from scene3D.evaluation import pose_auc, relative_pose_error
from scene3D.features import image_features, match_features, to_gray
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.datasets import read_strecha_camera, relative_pose, strecha_views
from scene3D.io.images import load_working_image
from scene3D.optim.uncertainty import CHI2_90, pose_error_chi2
from scene3D.twoview import reconstruct_from_matches

GAP_GROUPS = (((1, 2), "1-2"), ((3, 4, 5), "3-5"))


@dataclass
class Outcome:
    """One pair in one order."""

    status: str  # "refused", "flagged" or "trusted"
    error_deg: float = float("inf")  # the larger of the rotation and t-dir errors
    within_90: tuple[bool, bool] = (False, False)


def pair_matches(folder: Path, width: int, gaps: list[int]):
    """``{(a, b): (pts1, pts2, K, (R, t))}`` for every pair (a, a + gap) of a Strecha scene."""
    views = strecha_views(folder)
    cameras = [read_strecha_camera(camera) for _, camera in views]
    features, Ks = [], []
    for (path, _), camera in zip(views, cameras):
        img, _, levels = load_working_image(path, camera.K, camera.dist, width)
        features.append(image_features(to_gray(img), "SIFT"))
        Ks.append(scale_intrinsics_halved(camera.K, levels))
    pairs = {}
    for gap in gaps:
        for a in range(len(views) - gap):
            m = match_features(features[a], features[a + gap])
            pairs[(a, a + gap)] = (m.pts1, m.pts2, Ks[a],
                                   relative_pose(cameras[a], cameras[a + gap]))
    return pairs


def run_pair(pts1, pts2, K, truth, order: int) -> Outcome:
    """The pair reconstructed from its matches in order ``order`` (0: as given)."""
    if order:
        permutation = np.random.default_rng(order).permutation(len(pts1))
        pts1, pts2 = pts1[permutation], pts2[permutation]
    try:
        result = reconstruct_from_matches(pts1, pts2, K)
    except ReconstructionError:
        return Outcome("refused")
    chi2 = pose_error_chi2(result.R, result.t, *truth, result.pose_covariance)
    return Outcome("trusted" if result.trusted else "flagged",
                   relative_pose_error(result.R, result.t, *truth).max_deg,
                   (bool(chi2[0] <= CHI2_90[3]), bool(chi2[1] <= CHI2_90[2])))


def _row(scene: str, width: int, gaps: str, runs: list[list[Outcome]]) -> str:
    """One table row from ``runs[order][pair]``."""
    errors = np.array([[o.error_deg for o in run] for run in runs])
    flagged = np.array([[o.status != "trusted" for o in run] for run in runs])
    aucs = [pose_auc(e) for e in errors]
    within = np.array([o.within_90 for run in runs for o in run if o.status != "refused"])
    unsteady = sum(len({run[i].status for run in runs}) > 1 for i in range(len(runs[0])))
    wrong2 = errors > 2
    return (f"| {scene} | {width} | {gaps} | {np.mean(aucs):.2f} [{min(aucs):.2f}, "
            f"{max(aucs):.2f}] | {np.mean(errors < 2):.1%} | "
            f"{int(((errors < 1) & flagged).sum())} of {errors.size} | "
            f"{int((wrong2 & flagged).sum())} of {int(wrong2.sum())} | "
            f"{int(((errors > 5) & ~flagged).sum())} | {int((wrong2 & ~flagged).sum())} | "
            f"{within[:, 0].mean():.0%} / {within[:, 1].mean():.0%} | "
            f"{unsteady} of {len(runs[0])} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser, gaps=(1, 2, 3, 4, 5), scenes=True)
    parser.add_argument("--sizes", type=int, nargs="+", default=[768, 1536],
                        help="working widths in pixels (default: 768 1536)")
    parser.add_argument("--orders", type=int, default=5,
                        help="orders of the matches: the matcher's and random ones (default: 5)")
    args = parser.parse_args(argv)
    data = quiet_run(parser, args)
    print(f"scene3D from {Path(scene3D.__file__).parent}")
    print(f"{args.orders} orders of the same matches; sums over the orders; 'unsteady': "
          "pairs whose verdict is not the same in every order\n")
    print("| scene | width | gaps | AUC@5deg mean [least, most] | both < 2 deg | right flagged "
          "| > 2 deg flagged | > 5 deg trusted | > 2 deg trusted | within 90 %: rotation / "
          "t-dir | unsteady verdicts |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        for width in args.sizes:
            pairs = pair_matches(data / scene, width, args.gaps)
            outcomes = {key: [run_pair(*value, order) for order in range(args.orders)]
                        for key, value in pairs.items()}
            for gaps, name in GAP_GROUPS:
                keys = [k for k in outcomes if k[1] - k[0] in gaps]
                if keys:
                    runs = [[outcomes[k][order] for k in keys] for order in range(args.orders)]
                    print(_row(scene, width, name, runs), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
