"""Stage 3: matching and geometric verification of one pair of views, as a task.

Matching compares each descriptor only with the other view's descriptors filed
under its few nearest visual words (an inverted file over the collection's
vocabulary, :mod:`scene3D.multiview.retrieval`), then applies Lowe's ratio test and
the mutual check as :func:`scene3D.features.match_descriptors` does: a small share of
the distances of the full matrix product is computed, for nearly all the verified inliers
of exhaustive matching (measured in docs/benchmarks.md).

Verification fits an essential matrix with OpenCV's USAC: MAGSAC++ scoring, sigma
local optimisation and PROSAC sampling, the matches tried best first (by their
ratio test). A pair that overlaps is found in a few hundred iterations, so the
iterations can be capped (``SfMSettings.max_verify_iterations``), which bounds the
time lost on pairs that do not overlap.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..features.matching import match_descriptors
from ..geometry.conventions import FloatArray
from ..geometry.epipolar import essential_distances
from .settings import SfMSettings
from .view_data import PairMatches, ViewFeatures


def _by_word(words: np.ndarray, num_words: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows sorted by word and the bounds of each word's run: ``rows[bounds[w]:bounds[w+1]]``."""
    rows = np.argsort(words, kind="stable")
    return rows, np.searchsorted(words[rows], np.arange(num_words + 1))


def nearest_two(queries: np.ndarray, query_words: np.ndarray, base: np.ndarray,
                 base_word: np.ndarray, num_words: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest and second-nearest base rows of each query among the base rows filed under
    the query's words.

    Parameters
    ----------
    queries : (N, D) float32
    query_words : (N, p) int
        Words each query probes.
    base : (M, D) float32
    base_word : (M,) int
        The word each base row is filed under.

    Returns
    -------
    nearest : (N,) int
        -1 where no base row shares a word.
    d1, d2 : (N,) float32
        Squared distances to the nearest and second nearest (inf when missing).
    """
    n = len(queries)
    nearest = np.full(n, -1, dtype=np.intp)
    d1 = np.full(n, np.inf, np.float32)
    d2 = np.full(n, np.inf, np.float32)
    base_rows, base_bounds = _by_word(base_word, num_words)
    probe_query = np.repeat(np.arange(n), query_words.shape[1])
    probe_rows, probe_bounds = _by_word(query_words.ravel(), num_words)
    q_norm = np.einsum("ij,ij->i", queries, queries)
    b_norm = np.einsum("ij,ij->i", base, base)
    for w in range(num_words):
        b = base_rows[base_bounds[w]:base_bounds[w + 1]]
        if len(b) == 0:
            continue
        q = probe_query[probe_rows[probe_bounds[w]:probe_bounds[w + 1]]]
        if len(q) == 0:
            continue
        dist = queries[q] @ base[b].T
        dist *= -2.0
        dist += q_norm[q, None]
        dist += b_norm[None, b]
        rows = np.arange(len(q))
        k = dist.argmin(axis=1)
        first = dist[rows, k]
        if len(b) > 1:
            dist[rows, k] = np.inf
            second = dist.min(axis=1)
        else:
            second = np.full(len(q), np.inf, np.float32)
        old1, old2 = d1[q], d2[q]
        better = first < old1
        d2[q] = np.where(better, np.minimum(old1, second), np.minimum(old2, first))
        d1[q] = np.where(better, first, old1)
        nearest[q] = np.where(better, b[k], nearest[q])
    return nearest, np.maximum(d1, 0.0), d2


def match_by_words(desc_i: np.ndarray, words_i: np.ndarray, desc_j: np.ndarray,
                   words_j: np.ndarray, num_words: int, ratio: float = 0.8
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ratio-test and mutual matches of float descriptors through their visual words.

    Parameters
    ----------
    desc_i, desc_j : (N_i, D), (N_j, D) float32
    words_i, words_j : (N_i, p), (N_j, p) int
        Nearest words of each descriptor, nearest first (the first is where it is filed).
    num_words : int

    Returns
    -------
    idx_i, idx_j : (M,) int
        Matched rows.
    ratios : (M,) float64
        Distance to the nearest over distance to the second nearest (lower is surer).
    """
    nearest, d1, d2 = nearest_two(desc_i, words_i, desc_j, words_j[:, 0], num_words)
    passed = (nearest >= 0) & (d1 < ratio * ratio * d2)
    candidates = np.unique(nearest[passed])
    back = np.full(len(desc_j), -1, dtype=np.intp)
    if len(candidates):
        back[candidates] = nearest_two(desc_j[candidates], words_j[candidates], desc_i,
                                        words_i[:, 0], num_words)[0]
    idx_i = np.flatnonzero(passed & (back[np.maximum(nearest, 0)] == np.arange(len(desc_i))))
    idx_j = nearest[idx_i]
    return idx_i, idx_j, np.sqrt(d1[idx_i] / d2[idx_i]).astype(np.float64)


def match_views(f_i: ViewFeatures, f_j: ViewFeatures, num_words: int, ratio: float = 0.8
                ) -> tuple[np.ndarray, np.ndarray]:
    """Matches of two views, best first (by ratio; binary descriptors in matcher order).

    Float descriptors with words go through :func:`match_by_words`; others (binary
    descriptors, or no vocabulary) through the exhaustive
    :func:`scene3D.features.match_descriptors`.

    Parameters
    ----------
    f_i, f_j : ViewFeatures
        The two views' features.
    num_words : int
        Vocabulary size; 0 for exhaustive matching.
    ratio : float, default 0.8
        Lowe's ratio test threshold.

    Returns
    -------
    idx_i, idx_j : (M,) intp ndarray
        Keypoint indices of the matches in ``f_i`` and ``f_j``.
    """
    if len(f_i.descriptors) < 2 or len(f_j.descriptors) < 2:  # a blank view
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    float_words = (f_i.words is not None and f_j.words is not None
                   and f_i.descriptors.dtype == np.float32 and num_words > 0)
    if not float_words:
        return match_descriptors(f_i.descriptors, f_j.descriptors, f_i.norm, ratio)
    idx_i, idx_j, ratios = match_by_words(f_i.descriptors, f_i.words, f_j.descriptors,
                                          f_j.words, num_words, ratio)
    order = np.argsort(ratios, kind="stable")
    return idx_i[order], idx_j[order]


def verify_matches(pts_i: FloatArray, pts_j: FloatArray, K: FloatArray, threshold_px: float,
                   max_iterations: int) -> np.ndarray:
    """Inliers ``(N,) bool`` of one essential matrix (USAC: MAGSAC++ score, PROSAC order).

    ``pts_i, pts_j`` ``(N, 2)`` must come best first: PROSAC draws its early samples
    from the top of the list. Inliers are those within ``threshold_px`` (Sampson
    distance) of the essential matrix found.

    Parameters
    ----------
    pts_i, pts_j : (N, 2) float64 array_like
        Matched pixels (OpenCV convention), best first.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float
        Inlier threshold (px).
    max_iterations : int
        Most RANSAC iterations.

    Returns
    -------
    (N,) bool ndarray
        All False when no essential matrix is found.
    """
    params = cv2.UsacParams()
    params.confidence = 0.999
    params.threshold = threshold_px
    params.maxIterations = max_iterations
    params.sampler = cv2.SAMPLING_PROSAC
    params.score = cv2.SCORE_METHOD_MAGSAC
    params.loMethod = cv2.LOCAL_OPTIM_SIGMA
    params.loIterations = 10
    params.loSampleSize = 50
    zero = np.zeros(5)
    E, _ = cv2.findEssentialMat(pts_i, pts_j, K, K, zero, zero, params)
    if E is None or E.shape != (3, 3) or not np.all(np.isfinite(E)):
        return np.zeros(len(pts_i), dtype=bool)
    return essential_distances(E, pts_i, pts_j, K) <= threshold_px


def verify_pair(f_i: ViewFeatures, f_j: ViewFeatures, K: FloatArray, settings: SfMSettings,
                i: int = 0, j: int = 1, num_words: int = 0) -> PairMatches | None:
    """The task of one pair: match views ``i`` and ``j`` and keep the matches one essential
    matrix explains; None when fewer than ``settings.min_pair_inliers`` remain.

    Parameters
    ----------
    f_i, f_j : ViewFeatures
        The two views' features.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    settings : SfMSettings
        Gives ``min_pair_inliers``, ``threshold_px`` and ``max_verify_iterations``.
    i, j : int, default 0 and 1
        The views' indices stored in the result.
    num_words : int, default 0
        Vocabulary size; 0 for exhaustive matching.

    Returns
    -------
    PairMatches or None
    """
    return match_and_verify_pair(f_i, f_j, K, settings, i, j, num_words)[1]


def match_and_verify_pair(f_i: ViewFeatures, f_j: ViewFeatures, K: FloatArray,
                          settings: SfMSettings, i: int = 0, j: int = 1, num_words: int = 0,
                          putative: tuple[np.ndarray, np.ndarray] | None = None
                          ) -> tuple[tuple[np.ndarray, np.ndarray], PairMatches | None]:
    """:func:`verify_pair` that also returns the putative matches, and takes them when
    known: they depend on the descriptors alone, so a pass that verifies again under a
    new camera estimate (undistorted keypoints, another ``K``) need not match again.

    Parameters
    ----------
    f_i, f_j, K, settings, i, j, num_words
        As in :func:`verify_pair`.
    putative : tuple of two (M,) intp ndarray, optional
        ``match_views(f_i, f_j, num_words)`` from an earlier call.

    Returns
    -------
    putative : tuple of two (M,) intp ndarray
        The putative matches, best first.
    PairMatches or None
        As in :func:`verify_pair`.
    """
    if putative is None:
        putative = match_views(f_i, f_j, num_words)
    idx_i, idx_j = putative
    if len(idx_i) < max(settings.min_pair_inliers, 5):
        return putative, None
    inliers = verify_matches(f_i.keypoints[idx_i], f_j.keypoints[idx_j], K,
                             settings.threshold_px, settings.max_verify_iterations)
    if inliers.sum() < settings.min_pair_inliers:
        return putative, None
    return putative, PairMatches(i, j, idx_i[inliers], idx_j[inliers], len(idx_i))
