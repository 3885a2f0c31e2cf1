"""Two-view accuracy and speed: scene3D against the book, plain OpenCV, PoseLib and pycolmap.

    python benchmarks/two_view.py [--scene DIR] [--sizes 1536 768] [--methods ...] [--gaps 1 2]
                                  [--quick] [--no-process]

Runs fountain-P11 pairs (i, i+1) and (i, i+2) (``--gaps 3 4 5``: wider baselines; ``--scene``:
any other Strecha-format scene, images/ + gt_dense_cameras/) at each working width, compares
every
estimated relative pose with the Strecha ground truth and prints markdown tables (rows per
method and size): accuracy and stage times; trust (how the flag follows the error, and
how often scene3D's errors fall within its predicted 90 % bounds); then the whole-process
time of ``chapter4.py --no-plots`` against a hand-written plain-OpenCV script (not with
``--no-process``). Per-pair rows go to a CSV.

Every method gets the same working images (scene3D's loading: halved by area
averaging). Thread settings, the same for every method: one thread each, i.e. OpenCV
with ``cv2.setNumThreads(1)``, numpy's BLAS with ``OPENBLAS_NUM_THREADS=1``, pycolmap
with ``num_threads=1``, PoseLib single-threaded. The book, plain-OpenCV and PoseLib rows
share one set of SIFT matches (ratio 0.8); scene3D and pycolmap compute their own.
The whole-process comparison runs both scripts as users run them (default threads).
"""

from __future__ import annotations

import os

# One BLAS thread for the in-process table; set before numpy loads. The subprocesses
# of the whole-process comparison get the user's environment instead.
_USER_ENV = dict(os.environ)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import csv
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from bench_cli import REPO, interleaved_times, plain_command

from scene3D.errors import ReconstructionError
from scene3D.evaluation import (
    paired_auc_difference,
    relative_pose_error,
    sigma_calibration,
    summarize_pose_errors,
)
from scene3D.features import find_matches
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.geometry.pose import choose_pose
from scene3D.io.datasets import (
    BOOK_PAIR,
    FOUNTAIN_P11,
    default_data_root,
    read_strecha_camera,
    relative_pose,
    strecha_views,
)
from scene3D.io.images import load_working_image
from scene3D.memory import malloc_environment
from scene3D.optim.uncertainty import pose_error_chi2
from scene3D.twoview import reconstruct_two_view

METHODS = ("book", "opencv", "poselib", "pycolmap", "scene3D")


@dataclass
class Outcome:
    method: str
    width: int
    pair: tuple[int, int]
    rotation_deg: float = float("inf")
    translation_deg: float = float("inf")
    inliers: int = 0
    flagged: bool = False  # refused or marked untrusted by the method
    error: str = ""
    rotation_sigma_deg: float = float("nan")  # scene3D's predicted uncertainty (1 sigma)
    translation_sigma_deg: float = float("nan")
    rotation_chi2: float = float("nan")  # the error's Mahalanobis distance under it
    translation_chi2: float = float("nan")
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def max_deg(self) -> float:
        return max(self.rotation_deg, self.translation_deg)


def shared_sift(img1, img2):
    """Plain OpenCV SIFT + ratio 0.8 (no mutual check), sequential."""
    t0 = time.perf_counter()
    sift = cv2.SIFT_create()
    kp1, d1 = sift.detectAndCompute(cv2.cvtColor(img1, cv2.COLOR_BGR2GRAY), None)
    kp2, d2 = sift.detectAndCompute(cv2.cvtColor(img2, cv2.COLOR_BGR2GRAY), None)
    t1 = time.perf_counter()
    good = [m for m, n in cv2.BFMatcher().knnMatch(d1, d2, k=2) if m.distance < 0.8 * n.distance]
    p1 = np.float64([kp1[m.queryIdx].pt for m in good])
    p2 = np.float64([kp2[m.trainIdx].pt for m in good])
    return p1, p2, {"features": t1 - t0, "matching": time.perf_counter() - t1}


def run_book(p1, p2, K):
    """The book's algorithm: F by RANSAC at 0.1 px, E = K^T F K, cheirality fixed (counted)."""
    F, mask = cv2.findFundamentalMat(p1, p2, cv2.FM_RANSAC, 0.1, 0.99)
    inl = mask.ravel() > 0
    E = K.T @ F @ K
    R, t, _, _ = choose_pose(E, p1[inl], p2[inl], K)
    return R, t, int(inl.sum())


def run_opencv(p1, p2, K):
    E, mask = cv2.findEssentialMat(p1, p2, K, cv2.USAC_MAGSAC, 0.999, 1.0)
    n, R, t, mask = cv2.recoverPose(E, p1, p2, K, mask=mask)
    return R, t.ravel(), int(n)


def run_poselib(p1, p2, K, size):
    import poselib

    cam = {"model": "PINHOLE", "width": size[0], "height": size[1],
           "params": [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]}
    pose, info = poselib.estimate_relative_pose(p1, p2, cam, cam, {"max_epipolar_error": 1.0}, {})
    return pose.R, pose.t, int(info["num_inliers"])


def run_pycolmap(img1, img2, K):
    import pycolmap

    t0 = time.perf_counter()
    ext_opts = pycolmap.FeatureExtractionOptions()
    ext_opts.num_threads = 1
    extractor = pycolmap.FeatureExtractor.create(ext_opts, device=pycolmap.Device.cpu)
    gray1 = cv2.cvtColor(img1, cv2.COLOR_BGR2GRAY)
    gray2 = cv2.cvtColor(img2, cv2.COLOR_BGR2GRAY)
    k1, d1 = extractor.extract_from_uint8_array(gray1)
    k2, d2 = extractor.extract_from_uint8_array(gray2)
    t1 = time.perf_counter()
    match_opts = pycolmap.FeatureMatchingOptions()
    match_opts.num_threads = 1
    match_opts.use_gpu = False
    matches = pycolmap.FeatureMatcher.create(match_opts, device=pycolmap.Device.cpu).match(
        k1, d1, k2, d2)
    t2 = time.perf_counter()
    h, w = gray1.shape
    # COLMAP puts pixel centres at +0.5: shift the principal point accordingly.
    cam = pycolmap.Camera(model="PINHOLE", width=w, height=h,
                          params=[K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5])
    p1 = np.array([[k.x, k.y] for k in k1])
    p2 = np.array([[k.x, k.y] for k in k2])
    geom = pycolmap.estimate_calibrated_two_view_geometry(cam, p1, cam, p2, matches)
    if not pycolmap.estimate_two_view_geometry_pose(cam, p1, cam, p2, geom):
        raise RuntimeError("pycolmap found no pose")
    t3 = time.perf_counter()
    pose = geom.cam2_from_cam1
    timings = {"features": t1 - t0, "matching": t2 - t1, "geometry": t3 - t2}
    return pose.rotation.matrix(), np.asarray(pose.translation), len(geom.inlier_matches), timings


def load_pair(views: list[tuple[Path, Path]], a: int, b: int, width: int):
    """Views ``a`` and ``b`` of a scene (:func:`scene3D.io.datasets.strecha_views`) as scene3D
    loads them (halved by area averaging); every method gets these same pixels."""
    (path1, camera1), (path2, camera2) = views[a], views[b]
    cam1, cam2 = read_strecha_camera(camera1), read_strecha_camera(camera2)
    img1, _, levels = load_working_image(path1, cam1.K, cam1.dist, width)
    img2, _, _ = load_working_image(path2, cam2.K, cam2.dist, width)
    return img1, img2, scale_intrinsics_halved(cam1.K, levels), relative_pose(cam1, cam2)


def evaluate_pair(views, a, b, width, methods) -> list[Outcome]:
    img1, img2, K, (R_true, t_true) = load_pair(views, a, b, width)
    size = (img1.shape[1], img1.shape[0])
    outcomes = []
    shared = shared_sift(img1, img2) if {"book", "opencv", "poselib"} & set(methods) else None
    for method in methods:
        out = Outcome(method, size[0], (a, b))
        t0 = time.perf_counter()
        try:
            if method == "scene3D":
                matches = find_matches(img1, img2, "SIFT")
                result = reconstruct_two_view(img1, matches, K, img2=img2)
                R, t, out.inliers = result.R, result.t, result.num_inliers
                out.flagged = not result.trusted
                out.rotation_sigma_deg = result.rotation_sigma_deg
                out.translation_sigma_deg = result.translation_sigma_deg
                out.rotation_chi2, out.translation_chi2 = pose_error_chi2(
                    R, t, R_true, t_true, result.pose_covariance)
                out.timings_s = {k: v for k, v in result.timings_s.items() if k != "total"}
            elif method == "pycolmap":
                R, t, out.inliers, out.timings_s = run_pycolmap(img1, img2, K)
            else:
                p1, p2, match_times = shared
                t_geom = time.perf_counter()
                R, t, out.inliers = {"book": run_book, "opencv": run_opencv}.get(
                    method, lambda p, q, k: run_poselib(p, q, k, size))(p1, p2, K)
                out.timings_s = dict(match_times, geometry=time.perf_counter() - t_geom)
            err = relative_pose_error(R, t, R_true, t_true)
            out.rotation_deg, out.translation_deg = err.rotation_deg, err.translation_deg
        except ReconstructionError as exc:
            out.flagged, out.error = True, exc.reason
        except Exception as exc:  # a peer failing on a pair counts as a failure
            out.error = f"{type(exc).__name__}: {exc}"
        if method == "scene3D" or method == "pycolmap":
            out.timings_s["total"] = time.perf_counter() - t0
        else:
            out.timings_s["total"] = sum(out.timings_s.values())
        outcomes.append(out)
    return outcomes


def summarize(outcomes: list[Outcome]) -> dict:
    stats = summarize_pose_errors([o.rotation_deg for o in outcomes],
                                  [o.translation_deg for o in outcomes],
                                  [o.flagged for o in outcomes])
    stats["inliers"] = float(np.mean([o.inliers for o in outcomes]))
    stats.update({f"sigma_{k}": v for k, v in sigma_calibration(
        [o.rotation_chi2 for o in outcomes], [o.translation_chi2 for o in outcomes]).items()})
    for stage in ("features", "matching", "geometry", "refinement", "total"):
        stats[f"t_{stage}"] = float(np.mean([o.timings_s.get(stage, 0.0) for o in outcomes]))
    return stats


PROCESS_RUNS = 21


def process_times(folder: Path, runs: int = PROCESS_RUNS) -> dict[str, list[float]]:
    """Wall times of ``runs`` runs of chapter4.py --no-plots and of the plain-OpenCV script.

    Both run as a user runs them: Python may cache bytecode (PYTHONDONTWRITEBYTECODE is
    removed from their environment) and one untimed warm-up run of each comes first.
    ``"plain_tuned"`` is the plain script given the OpenBLAS and malloc settings that
    scene3D's command-line tools make for themselves (OPENBLAS_THREAD_TIMEOUT=4 and
    :func:`scene3D.memory.malloc_environment`), to show how much of the difference those
    settings alone account for.
    """
    img1, img2 = (folder / name for name in BOOK_PAIR)
    ours = [sys.executable, str(REPO / "chapter4.py"), str(img1), str(img2), "--calib",
            str(REPO / "data" / "fountain_P11_intrinsics.yaml"), "--no-plots", "-q"]
    env = {k: v for k, v in _USER_ENV.items() if k != "PYTHONDONTWRITEBYTECODE"}
    tuned = dict(env, OPENBLAS_THREAD_TIMEOUT="4", **malloc_environment())
    with tempfile.TemporaryDirectory() as tmp:
        return interleaved_times({"plain": (plain_command(folder), env),
                                  "ours": (ours + ["--out", tmp], env),
                                  "plain_tuned": (plain_command(folder), tuned)}, runs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=None,
                        help="folder holding fountain-P11/ (default: $SCENE3D_DATA)")
    parser.add_argument("--scene", type=Path, default=None, metavar="DIR",
                        help="a Strecha-format scene (images/ + gt_dense_cameras/, e.g. "
                             "Herz-Jesus-P8) to run instead of fountain-P11; the "
                             "whole-process comparison still uses fountain-P11's book pair")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1536, 768])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--gaps", type=int, nargs="+", default=[1, 2],
                        help="pair each image i with i + gap (default: 1 2, the consecutive "
                             "and skip-one pairs; larger gaps are wider baselines)")
    parser.add_argument("--quick", action="store_true", help="only pairs (i, i+1), i even")
    parser.add_argument("--csv", type=Path, default=REPO / "out" / "bench" / "two_view.csv")
    parser.add_argument("--process-only", action="store_true",
                        help="only the whole-process comparison with the plain-OpenCV script")
    parser.add_argument("--no-process", action="store_true",
                        help="skip the whole-process comparison (the accuracy, trust and "
                             "stage-time tables only)")
    args = parser.parse_args(argv)
    root = args.data or default_data_root()
    fountain = root / FOUNTAIN_P11 if root is not None else None
    if args.process_only:
        _print_process_ratio(fountain)
        return 0
    scene = args.scene or fountain
    if scene is None:
        parser.error("no data: set SCENE3D_DATA or pass --data or --scene")
    try:
        views = strecha_views(scene)
    except (FileNotFoundError, ValueError) as exc:
        parser.error(str(exc))
    cv2.setNumThreads(1)
    methods = [m for m in args.methods if m in ("book", "opencv", "scene3D") or _has(m)]
    if min(args.gaps) < 1:
        parser.error("--gaps must be whole numbers >= 1")
    n = len(views)
    pairs = [(i, i + gap) for gap in args.gaps for i in range(n - gap)]
    if args.quick:
        pairs = [(i, i + 1) for i in range(0, n - 1, 2)]
    if not pairs:
        parser.error(f"--gaps {' '.join(map(str, args.gaps))} selects no pair of the {n} views")
    outcomes: list[Outcome] = []
    for width in args.sizes:
        for a, b in pairs:
            outcomes += evaluate_pair(views, a, b, width, methods)
            print(f"width {width} pair {a}-{b} done", file=sys.stderr)
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["method", "width", "pair", "rot_deg", "t_deg", "inliers", "flagged",
                         "error", "rot_sigma_deg", "t_sigma_deg", "rot_chi2", "t_chi2",
                         "t_features", "t_matching", "t_geometry", "t_refinement", "t_total"])
        for o in outcomes:
            writer.writerow([o.method, o.width, f"{o.pair[0]}-{o.pair[1]}", o.rotation_deg,
                             o.translation_deg, o.inliers, o.flagged, o.error,
                             o.rotation_sigma_deg, o.translation_sigma_deg, o.rotation_chi2,
                             o.translation_chi2,
                             *(o.timings_s.get(s, 0.0) for s in
                               ("features", "matching", "geometry", "refinement", "total"))])
    print(f"{scene.resolve().name}, {len(pairs)} pairs per size (gaps "
          f"{' '.join(map(str, args.gaps))}); errors in degrees against the Strecha cameras; a "
          "failed pair counts as 180 deg (zero for AUC).\n")
    print("| method | width | median rot | p90 rot | median t-dir | p90 t-dir | both < 2 deg "
          "| both < 5 deg | AUC@5deg | inliers | features s | matching s | geometry s "
          "| refinement s | total s |")
    print("|---" * 15 + "|")
    widths = sorted({o.width for o in outcomes}, reverse=True)
    for width in widths:
        for method in methods:
            s = summarize([o for o in outcomes if o.method == method and o.width == width])
            print(f"| {method} | {width} | {s['median_rotation_deg']:.3f} | "
                  f"{s['p90_rotation_deg']:.3f} | {s['median_translation_deg']:.3f} | "
                  f"{s['p90_translation_deg']:.3f} | {s['within_2deg']:.0%} | "
                  f"{s['within_5deg']:.0%} | {s['auc_5deg']:.1f} | {s['inliers']:.0f} | "
                  f"{s['t_features']:.2f} | {s['t_matching']:.2f} | {s['t_geometry']:.3f} | "
                  f"{s['t_refinement']:.3f} | {s['t_total']:.2f} |")
    _print_trust(outcomes, methods, widths)
    peers = [m for m in methods if m != "scene3D"]
    if "scene3D" in methods and peers:  # scene3D alone has nothing to be compared with
        _print_auc_differences(outcomes, peers)
    if not args.no_process:
        _print_process_ratio(fountain)
    print(f"Per-pair rows: {args.csv}")
    return 0


def _print_trust(outcomes: list[Outcome], methods: list[str], widths: list[int]) -> None:
    """The flag against the error, per method and size, and scene3D's sigma calibration."""
    print("\nTrust: 'flagged' is refused or marked untrusted (peers without a trust flag: "
          "refused or failed). Right: both errors < 1 deg; > 2 deg and > 5 deg include "
          "failures. Within 90 %: share of scene3D's poses whose rotation (3 dof) and "
          "translation-direction (2 dof) errors lie within the predicted 90 % bound "
          "(chi-square on the covariance; the Strecha cameras' own error counts in).\n")
    print("| method | width | pairs | flagged | right flagged (< 1 deg) | > 2 deg flagged "
          "| > 5 deg not flagged | within 90 %: rotation | within 90 %: t-dir |")
    print("|---" * 9 + "|")
    for width in widths:
        for method in methods:
            s = summarize([o for o in outcomes if o.method == method and o.width == width])
            right = f"{s['right_flagged']:.0f} ({s['right_flagged'] / s['pairs']:.0%} of pairs)"
            off2 = (f"{s['off2_flagged']:.0f} of {s['off2']:.0f} "
                    f"({s['off2_flagged'] / s['off2']:.0%})" if s["off2"] else "0 of 0")
            calib = (f"{s['sigma_rotation_within90']:.0%} | {s['sigma_translation_within90']:.0%}"
                     if s["sigma_pairs"] else "- | -")
            print(f"| {method} | {width} | {s['pairs']:.0f} | {s['flagged']:.0f} | {right} | "
                  f"{off2} | {s['wrong_unflagged']:.0f} | {calib} |")


def _print_auc_differences(outcomes: list[Outcome], peers: list[str]) -> None:
    """scene3D's AUC@5deg minus each peer's, with a 95 % paired-bootstrap interval."""
    print("\nAUC@5deg, scene3D minus each peer (percentage points, 95 % paired-bootstrap "
          "interval over the pairs; an interval containing 0 does not separate the two):")
    def worst(method: str, width: int) -> list[float]:  # per pair, in pair order
        return [o.max_deg for o in sorted(outcomes, key=lambda o: o.pair)
                if o.method == method and o.width == width]

    for width in sorted({o.width for o in outcomes}, reverse=True):
        ours = worst("scene3D", width)
        cells = []
        for peer in peers:
            diff, low, high = paired_auc_difference(ours, worst(peer, width))
            cells.append(f"{peer} {diff:+.2f} [{low:+.2f}, {high:+.2f}]")
        print(f"- {width} px: " + "; ".join(cells))


def _print_process_ratio(fountain: Path | None) -> None:
    if fountain is None or not all((fountain / name).is_file() for name in BOOK_PAIR):
        print("\nWhole process: skipped (it runs on fountain-P11's book pair, not found)")
        return
    times = process_times(fountain)
    # Medians, and the fastest runs: on a shared machine the fastest run of each is the
    # one least disturbed by other work, and their ratio the steadier one.
    t = {name: statistics.median(values) for name, values in times.items()}
    fastest = {name: min(values) for name, values in times.items()}
    print(f"\nWhole process, book pair at 768 px (median of {PROCESS_RUNS}): chapter4.py "
          f"--no-plots {t['ours']:.2f} s, plain-OpenCV script {t['plain']:.2f} s, ratio "
          f"{t['ours'] / t['plain']:.2f}; fastest runs {fastest['ours']:.2f} s and "
          f"{fastest['plain']:.2f} s, ratio {fastest['ours'] / fastest['plain']:.2f} (against "
          f"the plain script given the same OpenBLAS and malloc settings: median "
          f"{t['plain_tuned']:.2f} s, "
          f"ratio {t['ours'] / t['plain_tuned']:.2f})")


def _has(module: str) -> bool:
    try:
        __import__(module)
        return True
    except ImportError:
        print(f"{module} is not installed (pip install -e '.[bench]'); skipping it",
              file=sys.stderr)
        return False


if __name__ == "__main__":
    sys.exit(main())
