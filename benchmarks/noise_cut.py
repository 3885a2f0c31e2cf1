"""Noise the inlier threshold cuts off: are the pose's sigmas still calibrated?

    python benchmarks/noise_cut.py [--noise 0.25 0.5 0.75 1 1.5 2] [--draws 150]

A synthetic pair with an exact truth: 500 points 6-14 baselines deep in front of a
768x512 camera (focal length 700 px), the second camera turned by about 8 degrees and
moved sideways. Each draw adds Gaussian noise of the given standard deviation to every
coordinate of both images (no outliers) and runs ``reconstruct_from_matches`` with the
default settings (a 1 px inlier threshold, raised to three noise sigmas, at most 2 px).
For each noise level it prints the share of the draws whose rotation error (3 dof) and
translation-direction error (2 dof) lie within the predicted 90 % bound, with the
covariance's allowance for the cut noise (``scene3D.optim.uncertainty.truncated_noise``) and
without it (the same draws, the allowance's factor set to 1), the mean chi-squares
(3 and 2 when calibrated), the median share of the matches the threshold cut off, and
the share of the draws flagged for it (``TwoViewSettings.max_noise_cut_share``). One
thread.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402

import numpy as np  # noqa: E402

import scene3D.twoview.core as core  # noqa: E402
from scene3D.geometry import project, rotations_from_vectors  # noqa: E402
from scene3D.optim.uncertainty import CHI2_90, pose_error_chi2  # noqa: E402
from scene3D.twoview import TwoViewSettings, reconstruct_from_matches  # noqa: E402


def scene(seed: int = 0):
    """``(K, R, t, x1, x2)``: the camera, the exact pose (unit ``t``) and the exact pixels."""
    rng = np.random.default_rng(seed)
    K = np.array([[700.0, 0.0, 384.0], [0.0, 700.0, 256.0], [0.0, 0.0, 1.0]])
    points = np.column_stack([rng.uniform(-4, 4, 500), rng.uniform(-3, 3, 500),
                              rng.uniform(6, 14, 500)])
    R = rotations_from_vectors(np.radians([[2.0, -8.0, 1.0]]))[0]
    t = -R @ np.array([1.5, 0.1, 0.2])
    t /= np.linalg.norm(t)
    return K, R, t, project(points, K, np.eye(3), np.zeros(3)), project(points, K, R, t)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--noise", type=float, nargs="+", default=[0.25, 0.5, 0.75, 1, 1.5, 2],
                        help="noise standard deviations in pixels (default: 0.25-2)")
    parser.add_argument("--draws", type=int, default=150, help="draws per noise (default: 150)")
    args = parser.parse_args(argv)
    if args.draws < 1 or min(args.noise) <= 0:
        parser.error("--draws must be >= 1 and every --noise > 0")
    K, R, t, x1, x2 = scene()
    with_allowance = core.pose_covariance

    def without_allowance(*pose_args):  # the same covariance, the cut not allowed for
        return with_allowance(*pose_args[:7], 1.0)

    limit = TwoViewSettings().max_noise_cut_share
    print(f"Synthetic pair, {args.draws} draws per noise, no outliers; within the 90 % bound "
          "(rotation / translation direction), calibrated: about 90 %.\n")
    print("| noise (px) | without the allowance | with it | mean chi-square with it "
          f"(3 / 2) | cut share (median) | flagged (cut > {limit:.0%}) |")
    print("|---|---|---|---|---|---|")
    for sigma in args.noise:
        chi2 = {"without": [], "with": []}
        cut, flagged = [], []
        for draw in range(args.draws):
            rng = np.random.default_rng([draw, round(sigma * 1000)])
            q1 = x1 + sigma * rng.standard_normal(x1.shape)
            q2 = x2 + sigma * rng.standard_normal(x2.shape)
            for name, covariance in (("without", without_allowance), ("with", with_allowance)):
                core.pose_covariance = covariance
                try:
                    r = reconstruct_from_matches(q1, q2, K)
                finally:
                    core.pose_covariance = with_allowance
                chi2[name].append(pose_error_chi2(r.R, r.t, R, t, r.pose_covariance))
            cut.append(r.noise_cut_share)
            flagged.append(r.noise_cut_share > limit)
        share = {name: np.array(v) for name, v in chi2.items()}
        within = {name: f"{np.mean(v[:, 0] <= CHI2_90[3]):.0%} / "
                        f"{np.mean(v[:, 1] <= CHI2_90[2]):.0%}" for name, v in share.items()}
        mean = share["with"].mean(axis=0)
        print(f"| {sigma:g} | {within['without']} | {within['with']} | {mean[0]:.2f} / "
              f"{mean[1]:.2f} | {np.median(cut):.1%} | {np.mean(flagged):.0%} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
