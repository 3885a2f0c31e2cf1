"""Accuracy levers of the two-view pipeline, each on every Strecha scene at every size.

    python benchmarks/two_view_levers.py [--data DIR] [--scenes fountain-P11 ...]
                                         [--sizes 1536 768] [--gaps 1 2] [--levers ...]

Issue #19 asked for castle-P19 (rows of identical windows) at 97 % of the gap-1 and gap-2
pairs within 2 deg without losing anything on fountain-P11 and Herz-Jesus-P8. This runs
scene3D's two-view core (``reconstruct_from_matches``) with one lever changed at a time,
on the same working images and against the Strecha cameras, and prints one markdown
table: both errors < 2 deg, AUC@5deg and its difference from scene3D's (95 % interval,
pairs resampled: ``scene3D.evaluation.paired_auc_difference``), medians, flagged pairs
(among them the right poses, both errors under 1 deg, and the poses more than 2 deg off),
and the milliseconds per pair of features (two images), matching and geometry. The
levers:

- ``scene3D``: the pipeline as it is;
- ``previous``: restarts compared at the 1 px threshold with MAGSAC++ (no noise probe:
  the essential fit before issue #19, then in ``scene3D.geometry.epipolar``);
- ``previous-0.5px``: the same with a 0.5 px threshold;
- ``ratio-0.7``: Lowe's ratio 0.7 instead of 0.8;
- ``rootsift``: RootSIFT descriptors (L1-normalised, square-rooted);
- ``symmetric``: the ratio test in both directions (OpenSfM's symmetric matching);
- ``self-ratio``: a match must also be 0.8 times closer than the nearest other keypoint
  of either image to its own (a test against repeated structure);
- ``contrast-0.02``: SIFT's contrast threshold 0.02 instead of OpenCV's 0.04 (about
  twice the keypoints);
- ``guided-1px``, ``guided-3px``: guided matching: the pair reconstructed once, then
  matched again among the keypoints within 1 or 3 px (Sampson distance) of that pose's
  epipolar geometry (ratio test and mutual check among those candidates only), and
  reconstructed from the new matches (the geometry time holds both fits and the guided
  matching);
- ``locality-0.3``, ``locality-0.4``: neighbourhood consensus (as in LPM, Ma et al.
  2019): a match is kept when at least 30 or 40 % of its 10 nearest matches in image 1
  are among its 10 nearest in image 2 (a test against repeated structure: a window
  matched to its neighbour's twin keeps few of its neighbours);
- ``aligned``: each match's image-2 point moved to where image 2's patch best fits image
  1's (:func:`align_matches`: an affine warp of a 15 x 15 patch started from the
  keypoints' scale and orientation, fitted on zero-mean, unit-norm intensities, as ECC;
  the time is in the matching column);
- ``poselib``, ``poselib-0.5px``: PoseLib's estimator on scene3D's matches (with the
  ``bench`` extra).

One thread for everything (``cv2.setNumThreads(1)``, ``OPENBLAS_NUM_THREADS=1``). Each
image's features are computed once per detector setting; the times are those of this run
on a shared machine, so compare rows of one run.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads

import argparse
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from bench_cli import add_data_arguments, data_folder

from scene3D.errors import ReconstructionError
from scene3D.evaluation import (
    paired_auc_difference,
    relative_pose_error,
    summarize_pose_errors,
)
from scene3D.features import match_descriptors, to_gray
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.datasets import read_strecha_camera, relative_pose, strecha_views
from scene3D.io.images import load_working_image
from scene3D.twoview import TwoViewSettings, essential_fit, reconstruct_from_matches

LEVERS = ("scene3D", "previous", "previous-0.5px", "ratio-0.7", "rootsift", "symmetric",
          "self-ratio", "contrast-0.02", "guided-1px", "guided-3px", "locality-0.3",
          "locality-0.4", "aligned", "poselib", "poselib-0.5px")
RATIO = 0.8


@dataclass(frozen=True)
class Features:
    pixels: np.ndarray  # (N, 2)
    descriptors: np.ndarray  # (N, 128) float32
    seconds: float
    sizes: np.ndarray  # (N,) cv2.KeyPoint.size, px
    angles: np.ndarray  # (N,) cv2.KeyPoint.angle, degrees
    gray: np.ndarray  # the grey working image


def detect(gray: np.ndarray, contrast: float) -> Features:
    """scene3D's bias-free SIFT with the given contrast threshold."""
    t0 = time.perf_counter()
    sift = cv2.SIFT_create(nfeatures=8000, contrastThreshold=contrast,
                           enable_precise_upscale=True)
    keypoints, descriptors = sift.detectAndCompute(gray, None)
    pixels = cv2.KeyPoint_convert(keypoints).astype(np.float64).reshape(-1, 2)
    return Features(pixels, descriptors, time.perf_counter() - t0,
                    np.array([k.size for k in keypoints]), np.array([k.angle for k in keypoints]),
                    gray)


def root_sift(descriptors: np.ndarray) -> np.ndarray:
    """RootSIFT (Arandjelovic and Zisserman, 2012): Hellinger distances as Euclidean ones."""
    l1 = np.maximum(descriptors.sum(axis=1, keepdims=True), 1e-12)
    return np.sqrt(descriptors / l1).astype(np.float32)


def _sq_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = -2.0 * (a @ b.T)
    d += np.einsum("ij,ij->i", a, a)[:, None]
    d += np.einsum("ij,ij->i", b, b)[None, :]
    return np.maximum(d, 0.0)


def symmetric_filter(d1: np.ndarray, d2: np.ndarray, idx1: np.ndarray,
                     idx2: np.ndarray) -> np.ndarray:
    """Which of scene3D's matches also pass the ratio test from image 2 to image 1."""
    d = _sq_distances(d2[idx2], d1)  # each matched image-2 descriptor against image 1
    best = d[np.arange(len(idx1)), idx1]
    d[np.arange(len(idx1)), idx1] = np.inf
    return best < RATIO ** 2 * d.min(axis=1)


def self_ratio_filter(f1: Features, f2: Features, idx1: np.ndarray, idx2: np.ndarray,
                      block: int = 512) -> np.ndarray:
    """Which matches are 0.8 times closer than either keypoint's nearest other in its image.

    Keypoints within 2 px of each other (SIFT's twins at one place with another
    orientation) are not "others".
    """
    match = np.sum((f1.descriptors[idx1] - f2.descriptors[idx2]) ** 2, axis=1)
    nearest_other = np.full(len(idx1), np.inf)
    for f, idx in ((f1, idx1), (f2, idx2)):
        for start in range(0, len(idx), block):
            rows = idx[start:start + block]
            d = _sq_distances(f.descriptors[rows], f.descriptors)
            d[_sq_distances(f.pixels[rows], f.pixels) < 4.0] = np.inf
            nearest_other[start:start + block] = np.minimum(nearest_other[start:start + block],
                                                            d.min(axis=1))
    return match < RATIO ** 2 * nearest_other


def locality_filter(p1: np.ndarray, p2: np.ndarray, share: float, k: int = 10) -> np.ndarray:
    """``(N,) bool``: the matches ``p1[i] <-> p2[i]`` (pixels, ``(N, 2)``) at least
    ``share`` of whose ``k`` nearest matches in image 1 are among the ``k`` nearest in
    image 2."""
    from scipy.spatial import cKDTree

    k = min(k, len(p1) - 1)
    if k < 2:
        return np.ones(len(p1), bool)
    near1 = cKDTree(p1).query(p1, k + 1)[1][:, 1:]
    near2 = cKDTree(p2).query(p2, k + 1)[1][:, 1:]
    shared = (near1[:, :, None] == near2[:, None, :]).sum(axis=(1, 2))
    return shared >= share * k


def guided_matches(f1: Features, f2: Features, F: np.ndarray, band_px: float,
                   block: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the matches among keypoint pairs within ``band_px`` of ``F``'s geometry.

    A pair is a candidate when its Sampson distance to ``F`` (pixels of image 2 ~ F x1)
    is at most ``band_px``; among each keypoint's candidates the nearest descriptor must
    pass Lowe's ratio against the second nearest, and be the nearest of its own
    candidates in image 1 (mutual check).
    """
    x1 = np.c_[f1.pixels, np.ones(len(f1.pixels))]
    x2 = np.c_[f2.pixels, np.ones(len(f2.pixels))]
    lines2, lines1 = x1 @ F.T, x2 @ F  # epipolar lines in image 2 and image 1
    grad1 = lines1[:, 0] ** 2 + lines1[:, 1] ** 2
    n1, n2 = len(x1), len(x2)
    nearest, passed = np.zeros(n1, dtype=np.intp), np.zeros(n1, dtype=bool)
    col_best, col_arg = np.full(n2, np.inf), np.zeros(n2, dtype=np.intp)
    for start in range(0, n1, block):
        rows = slice(start, start + block)
        d = _sq_distances(f1.descriptors[rows], f2.descriptors)
        lines = lines2[rows]
        algebraic = (lines @ x2.T) ** 2
        d[algebraic > band_px ** 2 * ((lines[:, 0] ** 2 + lines[:, 1] ** 2)[:, None]
                                      + grad1[None, :])] = np.inf
        r = np.arange(len(d))
        j = d.argmin(axis=1)
        best = d[r, j].copy()
        d[r, j] = np.inf
        second = d.min(axis=1)
        d[r, j] = best
        nearest[rows], passed[rows] = j, np.isfinite(best) & (best < RATIO ** 2 * second)
        i = d.argmin(axis=0)
        value = d[i, np.arange(n2)]
        better = value < col_best
        col_best[better], col_arg[better] = value[better], i[better] + start
    idx1 = np.flatnonzero(passed & (col_arg[nearest] == np.arange(n1)))
    return idx1, nearest[idx1]


def align_matches(gray1: np.ndarray, gray2: np.ndarray, p1: np.ndarray, p2: np.ndarray,
                  size1: np.ndarray, size2: np.ndarray, angle1: np.ndarray, angle2: np.ndarray,
                  radius: int = 7, iterations: int = 20, min_correlation: float = 0.8,
                  max_shift_px: float = 2.0, tolerance_px: float = 1e-3
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Each match's image-2 point moved to where image 2's patch best fits image 1's.

    A ``(2 radius + 1)^2`` patch of image 1 around ``p1`` (pixel steps) is the template;
    an affine warp of image 2, started from the keypoints' scale ratio and angle
    difference at ``p2``, is fitted to it by Gauss-Newton on zero-mean, unit-norm
    intensities (invariant to gain and offset, as ECC), all matches at once. A match
    moves when its final correlation is at least ``min_correlation`` and its point moved
    less than ``max_shift_px``. Returns ``p2`` refined ``(N, 2)`` and which moved ``(N,)``.
    """
    g2 = np.ascontiguousarray(gray2, np.float32)
    gx = cv2.Sobel(g2, cv2.CV_32F, 1, 0, ksize=1, scale=0.5)
    gy = cv2.Sobel(g2, cv2.CV_32F, 0, 1, ksize=1, scale=0.5)
    stack = cv2.merge([g2, gx, gy])
    steps = np.arange(-radius, radius + 1, dtype=np.float32)
    ux, uy = (u.ravel() for u in np.meshgrid(steps, steps))

    def sample(img: np.ndarray, A: np.ndarray, t: np.ndarray) -> np.ndarray:
        x = t[:, :1] + A[:, 0, :1] * ux + A[:, 0, 1:] * uy
        y = t[:, 1:] + A[:, 1, :1] * ux + A[:, 1, 1:] * uy
        return cv2.remap(img, x.astype(np.float32), y.astype(np.float32), cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)

    def normalise(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values = values - values.mean(axis=1, keepdims=True)
        norm = np.maximum(np.linalg.norm(values, axis=1, keepdims=True), 1e-6)
        return values / norm, norm

    n = len(p1)
    template, _ = normalise(sample(np.ascontiguousarray(gray1, np.float32),
                                   np.broadcast_to(np.eye(2), (n, 2, 2)), p1))
    turn = np.deg2rad(angle2 - angle1)
    c, s = size2 / size1 * np.cos(turn), size2 / size1 * np.sin(turn)
    A = np.stack([np.stack([c, -s], 1), np.stack([s, c], 1)], 1)
    t = np.array(p2, dtype=np.float64)
    active = np.arange(n)
    for _ in range(iterations):
        if len(active) == 0:
            break
        samples = sample(stack, A[active], t[active])
        values, norm = normalise(samples[..., 0])
        gxs, gys = samples[..., 1] / norm, samples[..., 2] / norm
        J = np.stack([gxs * ux, gxs * uy, gys * ux, gys * uy, gxs, gys], axis=2)
        J -= J.mean(axis=1, keepdims=True)
        Jt = J.transpose(0, 2, 1)
        step = np.linalg.solve((Jt @ J).astype(np.float64) + 1e-9 * np.eye(6),
                               (Jt @ (template[active] - values)[..., None]).astype(np.float64))
        A[active] += step[:, :4, 0].reshape(-1, 2, 2)
        t[active] += step[:, 4:, 0]
        active = active[np.hypot(step[:, 4, 0], step[:, 5, 0]) > tolerance_px]
    values, _ = normalise(sample(g2, A, t))
    moved = ((np.einsum("ns,ns->n", values, template) >= min_correlation)
             & np.isfinite(t).all(axis=1) & (np.hypot(*(t - p2).T) < max_shift_px))
    return np.where(moved[:, None], t, p2), moved


@contextmanager
def previous_estimator() -> Iterator[None]:
    """The essential fit before issue #19: MAGSAC++ restarts compared at the threshold."""
    saved = essential_fit.NOISE_PROBE_OF_THRESHOLD, essential_fit.RESTART_METHOD
    essential_fit.NOISE_PROBE_OF_THRESHOLD, essential_fit.RESTART_METHOD = 1.0, cv2.USAC_MAGSAC
    try:
        yield
    finally:
        essential_fit.NOISE_PROBE_OF_THRESHOLD, essential_fit.RESTART_METHOD = saved


def poselib_pose(p1: np.ndarray, p2: np.ndarray, K: np.ndarray, size: tuple[int, int],
                 threshold_px: float) -> tuple[np.ndarray, np.ndarray]:
    import poselib

    cam = {"model": "PINHOLE", "width": size[0], "height": size[1],
           "params": [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]}
    pose, _ = poselib.estimate_relative_pose(p1, p2, cam, cam,
                                             {"max_epipolar_error": threshold_px}, {})
    return pose.R, pose.t


def run_lever(lever: str, cameras: list, pairs: list[tuple[int, int]],
              features: Callable[[int, float], Features], size: tuple[int, int],
              K: np.ndarray) -> dict:
    """Summary statistics (:func:`scene3D.evaluation.summarize_pose_errors`) and mean
    milliseconds per pair of one lever on the pairs of one scene at one size."""
    rot, tdir, flagged, t_feat, t_match, t_geom = [], [], [], [], [], []
    contrast = 0.02 if lever == "contrast-0.02" else 0.04
    for a, b in pairs:
        f1, f2 = features(a, contrast), features(b, contrast)
        t0 = time.perf_counter()
        d1, d2 = f1.descriptors, f2.descriptors
        if lever == "rootsift":
            d1, d2 = root_sift(d1), root_sift(d2)
        idx1, idx2 = match_descriptors(d1, d2, cv2.NORM_L2, 0.7 if lever == "ratio-0.7" else RATIO)
        if lever == "symmetric":
            keep = symmetric_filter(d1, d2, idx1, idx2)
            idx1, idx2 = idx1[keep], idx2[keep]
        elif lever == "self-ratio":
            keep = self_ratio_filter(f1, f2, idx1, idx2)
            idx1, idx2 = idx1[keep], idx2[keep]
        elif lever.startswith("locality"):
            keep = locality_filter(f1.pixels[idx1], f2.pixels[idx2], float(lever[9:]))
            idx1, idx2 = idx1[keep], idx2[keep]
        p1, p2 = f1.pixels[idx1], f2.pixels[idx2]
        if lever == "aligned":
            p2 = align_matches(f1.gray, f2.gray, p1, p2, f1.sizes[idx1], f2.sizes[idx2],
                               f1.angles[idx1], f2.angles[idx2])[0]
        t1 = time.perf_counter()
        truth = relative_pose(cameras[a], cameras[b])
        R = t = None
        flag = True
        try:
            if lever.startswith("poselib"):
                R, t = poselib_pose(p1, p2, K, size, 0.5 if lever.endswith("0.5px") else 1.0)
                flag = False
            else:
                if lever.startswith("guided"):
                    first = reconstruct_from_matches(p1, p2, K)
                    idx1, idx2 = guided_matches(f1, f2, first.F, float(lever[7:-2]))
                    p1, p2 = f1.pixels[idx1], f2.pixels[idx2]
                settings = TwoViewSettings(threshold_px=0.5 if lever.endswith("0.5px") else 1.0)
                with previous_estimator() if lever.startswith("previous") else nullcontext():
                    result = reconstruct_from_matches(p1, p2, K, settings)
                R, t, flag = result.R, result.t, not result.trusted
        except ReconstructionError:
            pass
        t2 = time.perf_counter()
        err = relative_pose_error(R, t, *truth) if R is not None else None
        rot.append(err.rotation_deg if err else np.inf)
        tdir.append(err.translation_deg if err else np.inf)
        flagged.append(flag)
        t_feat.append(f1.seconds + f2.seconds)
        t_match.append(t1 - t0)
        t_geom.append(t2 - t1)
    stats = summarize_pose_errors(rot, tdir, flagged)
    stats.update(features_ms=1000 * np.mean(t_feat), matching_ms=1000 * np.mean(t_match),
                 geometry_ms=1000 * np.mean(t_geom), worst_deg=np.maximum(rot, tdir))
    return stats


def _feature_cache(views: list, cameras: list, width: int
                   ) -> tuple[Callable[[int, float], Features], tuple[int, int], np.ndarray]:
    """The views' grey working images, a function giving each one's features once per
    contrast threshold, the working size and the working K (one camera per scene)."""
    images, K, size = [], None, None
    for (path, _), camera in zip(views, cameras):
        img, _, levels = load_working_image(path, camera.K, camera.dist, width)
        images.append(to_gray(img))
        K, size = scale_intrinsics_halved(camera.K, levels), (img.shape[1], img.shape[0])
    cache: dict[tuple[int, float], Features] = {}

    def features(i: int, contrast: float) -> Features:
        if (i, contrast) not in cache:
            cache[(i, contrast)] = detect(images[i], contrast)
        return cache[(i, contrast)]

    return features, size, K


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser, gaps=(1, 2), scenes=True)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1536, 768],
                        help="working widths in px")
    parser.add_argument("--levers", nargs="+", default=list(LEVERS), choices=LEVERS,
                        help="which variants to run (default: all)")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    data = data_folder(parser, args)
    levers = [lever for lever in args.levers
              if not lever.startswith("poselib") or _has("poselib")]
    print("| scene | width | lever | pairs | both < 2 deg | AUC@5deg | minus scene3D's [95 %] "
          "| median rot | median t-dir | flagged | right (< 1 deg) flagged | > 2 deg flagged "
          "| wrong & unflagged | features ms | matching ms | geometry ms |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        views = strecha_views(Path(data) / scene)
        cameras = [read_strecha_camera(camera) for _, camera in views]
        pairs = [(i, i + gap) for gap in args.gaps for i in range(len(views) - gap)]
        for width in args.sizes:
            features, size, K = _feature_cache(views, cameras, width)
            reference = None
            for lever in levers:
                s = run_lever(lever, cameras, pairs, features, size, K)
                if lever == "scene3D":
                    reference = s["worst_deg"]
                difference = "-"
                if reference is not None and lever != "scene3D":
                    diff, low, high = paired_auc_difference(s["worst_deg"], reference)
                    difference = f"{diff:+.2f} [{low:+.2f}, {high:+.2f}]"
                print(f"| {scene} | {width} | {lever} | {int(s['pairs'])} | "
                      f"{100 * s['within_2deg']:.1f}% | {s['auc_5deg']:.2f} | {difference} | "
                      f"{s['median_rotation_deg']:.3f} | {s['median_translation_deg']:.3f} | "
                      f"{int(s['flagged'])} | {int(s['right_flagged'])} | "
                      f"{int(s['off2_flagged'])} of {int(s['off2'])} | "
                      f"{int(s['wrong_unflagged'])} | "
                      f"{s['features_ms']:.0f} | {s['matching_ms']:.0f} | "
                      f"{s['geometry_ms']:.0f} |", flush=True)
    return 0


def _has(module: str) -> bool:
    try:
        __import__(module)
        return True
    except ImportError:
        return False


if __name__ == "__main__":
    raise SystemExit(main())
