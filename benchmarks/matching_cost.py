"""What one pair of views costs to match and verify, and what the alternatives would cost.

    python benchmarks/matching_cost.py [--data DIR] [--scenes castle-P19 fountain-P11]
                                       [--width 1536] [--pairs 40]

Features, vocabulary and pairs as ``reconstruct-views`` makes them (SIFT at ``--width``,
64 words, 3 probed, the pairs its ``auto`` mode selects, the views in file order; the
first ``--pairs`` of them).
Each matcher runs on the same pairs, one after the other in one process (the machine is
shared: compare the ratios within a run, not seconds across runs), one OpenCV and one
BLAS thread unless the row says threads. Every matcher's matches, best first by ratio,
go through the same USAC verification (:func:`scene3D.multiview.matching.verify_matches`),
so that each row gives: ms a pair of descriptor matching, ms a pair of verification,
pairs verified, pairs verified that the current matcher also verifies, and the verified
inliers summed over the pairs against the current matcher's.

Rows: the current matcher (words-restricted float32 distances, ratio test, then the mutual
check on the ratio winners); the same words with float16 descriptors (scaled by 1/512;
numpy has no half precision BLAS); the exhaustive float32 product
(:func:`scene3D.features.match_descriptors`);
``cv2.BFMatcher`` knnMatch both ways (ratio test, then mutual); ``cv2.FlannBasedMatcher``
(4 kd-trees, 64 checks) both ways; the mutual check before the ratio test; and the current
matcher over pairs in a ``ThreadPoolExecutor`` of 2 threads (wall time a pair).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import dataclasses
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np
from bench_cli import data_folder

from scene3D.features import match_descriptors
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io.datasets import read_strecha_scene
from scene3D.multiview import SfMSettings
from scene3D.multiview.features import view_features
from scene3D.multiview.matching import (
    match_by_words,
    match_views,
    nearest_two,
    verify_matches,
    verify_pair,
)
from scene3D.multiview.pairs import select_pairs
from scene3D.multiview.retrieval import describe_view, similarity_ranking, train_vocabulary

Matcher = Callable[[object, object, int], tuple[np.ndarray, np.ndarray]]


def _best_first(idx_i: np.ndarray, idx_j: np.ndarray, ratios: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(ratios, kind="stable")
    return idx_i[order], idx_j[order]


def words_half(f_i, f_j, num_words: int):
    """The current matcher on float16 descriptors, scaled by 1/512 (SIFT's integers reach
    511: their squared norms would overflow half precision's 65504)."""
    half_i = (f_i.descriptors / 512).astype(np.float16)
    half_j = (f_j.descriptors / 512).astype(np.float16)
    idx_i, idx_j, ratios = match_by_words(half_i, f_i.words, half_j, f_j.words, num_words)
    return _best_first(idx_i, idx_j, ratios)


def exhaustive(f_i, f_j, num_words: int):
    return match_descriptors(f_i.descriptors, f_j.descriptors, f_i.norm, 0.8)


def knn_both_ways(matcher: cv2.DescriptorMatcher, f_i, f_j, ratio: float = 0.8):
    """Ratio test on the forward two nearest, then the mutual check on the backward nearest."""
    forward = matcher.knnMatch(f_i.descriptors, f_j.descriptors, k=2)
    backward = matcher.knnMatch(f_j.descriptors, f_i.descriptors, k=1)
    back = np.array([m[0].trainIdx if m else -1 for m in backward])
    keep = [(m[0].queryIdx, m[0].trainIdx, m[0].distance / max(m[1].distance, 1e-12))
            for m in forward if len(m) == 2 and m[0].distance < ratio * m[1].distance]
    keep = [k for k in keep if back[k[1]] == k[0]]
    if not keep:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    a = np.array(keep)
    return _best_first(a[:, 0].astype(np.intp), a[:, 1].astype(np.intp), a[:, 2])


def brute_force(f_i, f_j, num_words: int):
    return knn_both_ways(cv2.BFMatcher(cv2.NORM_L2), f_i, f_j)


def flann(f_i, f_j, num_words: int):
    return knn_both_ways(cv2.FlannBasedMatcher({"algorithm": 1, "trees": 4},
                                               {"checks": 64}), f_i, f_j)


def mutual_first(f_i, f_j, num_words: int):
    """Mutual check on every row, then the ratio test on the mutual pairs."""
    nearest, d1, d2 = nearest_two(f_i.descriptors, f_i.words, f_j.descriptors,
                                  f_j.words[:, 0], num_words)
    back = nearest_two(f_j.descriptors, f_j.words, f_i.descriptors, f_i.words[:, 0],
                       num_words)[0]
    mutual = (nearest >= 0) & (back[np.maximum(nearest, 0)] == np.arange(len(nearest)))
    idx_i = np.flatnonzero(mutual & (d1 < 0.64 * d2))
    return _best_first(idx_i, nearest[idx_i], np.sqrt(d1[idx_i] / d2[idx_i]))


def scene_pairs(root, width: int, settings: SfMSettings, count: int):
    """Features with words, working K and the first ``count`` pairs of the auto selection."""
    truth = read_strecha_scene(root)
    K = np.loadtxt(root / "images" / "K.txt")
    found = [view_features(p, K, np.zeros(5), width, p.name) for p in truth.paths]
    K_work = scale_intrinsics_halved(K, found[0][3])
    features = [f[0] for f in found]
    vocabulary = train_vocabulary(features, settings.vocabulary_words)
    described = [describe_view(f, vocabulary, settings.probe_words) for f in features]
    features = [dataclasses.replace(f, words=w) for f, (w, _) in zip(features, described)]
    ranking, _ = similarity_ranking(np.array([v for _, v in described]))
    pairs, _ = select_pairs(len(features), "auto", settings.neighbours, ranking,
                            settings.retrieval_neighbours)
    return features, K_work, pairs[:count], vocabulary.size


def run_matcher(matcher: Matcher, features, K, pairs, num_words: int, settings: SfMSettings
                ) -> tuple[float, float, dict[tuple[int, int], int]]:
    """Seconds of matching and of verification, and each verified pair's inliers."""
    t_match = t_verify = 0.0
    verified = {}
    for i, j in pairs:
        t0 = time.perf_counter()
        idx_i, idx_j = matcher(features[i], features[j], num_words)
        t1 = time.perf_counter()
        if len(idx_i) >= settings.min_pair_inliers:
            inl = verify_matches(features[i].keypoints[idx_i], features[j].keypoints[idx_j],
                                 K, settings.threshold_px, settings.max_verify_iterations)
            if inl.sum() >= settings.min_pair_inliers:
                verified[(i, j)] = int(inl.sum())
        t_verify += time.perf_counter() - t1
        t_match += t1 - t0
    return t_match, t_verify, verified


def threaded_seconds(features, K, pairs, num_words: int, settings: SfMSettings,
                     threads: int) -> float:
    t0 = time.perf_counter()
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda p: verify_pair(features[p[0]], features[p[1]], K, settings,
                                            p[0], p[1], num_words), pairs))
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", default=None, type=Path)
    parser.add_argument("--scenes", nargs="+", default=["castle-P19", "fountain-P11"])
    parser.add_argument("--width", type=int, default=1536)
    parser.add_argument("--pairs", type=int, default=40, help="pairs per scene")
    args = parser.parse_args()
    root = data_folder(parser, args)
    cv2.setNumThreads(1)
    settings = SfMSettings()
    matchers: dict[str, Matcher] = {
        "words float32 (current)": lambda a, b, w: match_views(a, b, w),
        "words float16": words_half,
        "mutual check before ratio": mutual_first,
        "exhaustive float32 product": exhaustive,
        "cv2.BFMatcher knn": brute_force,
        "cv2.FlannBasedMatcher knn": flann,
    }
    print("| scene | matcher | match ms/pair | verify ms/pair | match x current | "
          "pairs verified | also by current | inliers (current) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.scenes:
        features, K, pairs, num_words = scene_pairs(root / name, args.width, settings,
                                                    args.pairs)
        base = None
        for label, matcher in matchers.items():
            t_m, t_v, verified = run_matcher(matcher, features, K, pairs, num_words, settings)
            if base is None:
                base = (t_m, verified)
            same = sorted(set(verified) & set(base[1]))
            print(f"| {name} | {label} | {1000 * t_m / len(pairs):.1f} | "
                  f"{1000 * t_v / len(pairs):.1f} | {t_m / base[0]:.2f} | "
                  f"{len(verified)} of {len(pairs)} | {len(same)} | "
                  f"{sum(verified.values())} ({sum(base[1].values())}) |", flush=True)
        one = threaded_seconds(features, K, pairs, num_words, settings, 1)
        two = threaded_seconds(features, K, pairs, num_words, settings, 2)
        print(f"| {name} | verify_pair, 1 thread -> 2 threads (wall) | "
              f"{1000 * one / len(pairs):.1f} -> {1000 * two / len(pairs):.1f} "
              f"(x{one / two:.2f}) | | | | | |", flush=True)


if __name__ == "__main__":
    main()
