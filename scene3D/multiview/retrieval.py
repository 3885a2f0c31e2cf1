"""Stage 2: image retrieval from the features already computed.

A visual vocabulary is learnt from the collection's own descriptors (k-means on an
even sample of every view's descriptors, seeded: the same views give the same
words). Each view is summarised by its VLAD vector (Jegou et al., "Aggregating
local descriptors into a compact image representation", CVPR 2010): for every word,
the sum of the residuals of the view's descriptors that fall in it, with signed
square roots and per-word normalisation (Arandjelovic and Zisserman, "All about
VLAD", CVPR 2013) against bursts of repeated texture. Views whose vectors point the
same way share many similar descriptors: they probably overlap.

The same words serve matching (:mod:`scene3D.multiview.matching`): a descriptor is
only compared with the other view's descriptors in its nearest words.

Binary descriptors (ORB, AKAZE) are unpacked to bits, where squared Euclidean
distance is the Hamming distance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .view_data import ViewFeatures


@dataclass(frozen=True)
class Vocabulary:
    """Visual words: k-means centres in descriptor space.

    Attributes
    ----------
    centres : (C, D) float32
    binary : bool
        The descriptors are binary and are unpacked to bits first.
    """

    centres: np.ndarray
    binary: bool

    @property
    def size(self) -> int:
        return len(self.centres)


def descriptor_space(descriptors: np.ndarray, binary: bool) -> np.ndarray:
    """Descriptors as ``(N, D) float32`` rows of the space the vocabulary lives in.

    Parameters
    ----------
    descriptors : (N, D0) ndarray
        float32 descriptors, or uint8 binary ones (unpacked to ``D = 8 D0`` bits).
    binary : bool
        The descriptors are binary.

    Returns
    -------
    (N, D) float32 ndarray
    """
    if binary:
        return np.unpackbits(np.asarray(descriptors, np.uint8), axis=1).astype(np.float32)
    return np.asarray(descriptors, np.float32)


def _squared_distances(x: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """``|x - c|^2`` ``(N, C)`` from one matrix product."""
    d = x @ centres.T
    d *= -2.0
    d += np.einsum("ij,ij->i", centres, centres)[None, :]
    d += np.einsum("ij,ij->i", x, x)[:, None]
    return np.maximum(d, 0.0, out=d)


def kmeans(samples: np.ndarray, k: int, iterations: int = 15, seed: int = 0) -> np.ndarray:
    """Lloyd's k-means from a k-means++ start: ``(k, D) float32`` centres of ``(M, D)`` rows.

    Seeded and independent of anything but ``samples``: the same rows in the same
    order give the same centres. A centre left without samples moves to the sample
    farthest from its centre. Fewer samples than ``k`` give as many centres as samples
    (none without samples: images without keypoints).

    Parameters
    ----------
    samples : (M, D) array_like
        Rows to cluster (converted to float32).
    k : int
        Number of centres wanted.
    iterations : int, default 15
        Lloyd iterations.
    seed : int, default 0
        Seed of the k-means++ start.

    Returns
    -------
    (min(k, M), D) float32 ndarray
    """
    samples = np.asarray(samples, np.float32)
    rng = np.random.default_rng(seed)
    k = min(k, len(samples))
    if k == 0:
        return np.zeros((0, samples.shape[1] if samples.ndim == 2 else 0), np.float32)
    centres = np.empty((k, samples.shape[1]), np.float32)
    centres[0] = samples[rng.integers(len(samples))]
    closest = _squared_distances(samples, centres[:1])[:, 0]
    for c in range(1, k):  # k-means++: far from the centres so far, by chance
        total = float(closest.sum())
        pick = rng.choice(len(samples), p=closest / total) if total > 0 else rng.integers(
            len(samples))
        centres[c] = samples[pick]
        np.minimum(closest, _squared_distances(samples, centres[c:c + 1])[:, 0], out=closest)
    for _ in range(iterations):
        d = _squared_distances(samples, centres)
        label = d.argmin(axis=1)
        counts = np.bincount(label, minlength=k)
        sums = np.zeros_like(centres)
        np.add.at(sums, label, samples)
        moved = centres.copy()
        filled = counts > 0
        moved[filled] = sums[filled] / counts[filled, None]
        if not filled.all():
            far = np.argsort(d[np.arange(len(samples)), label])[::-1]
            moved[~filled] = samples[far[:int((~filled).sum())]]
        if np.allclose(moved, centres):
            break
        centres = moved
    return centres


def train_vocabulary(features: Sequence[ViewFeatures], words: int = 64,
                     samples_per_word: int = 200, seed: int = 0) -> Vocabulary:
    """A vocabulary of ``words`` words from an even sample of every view's descriptors.

    Each view gives an equal share of the ``words * samples_per_word`` samples,
    taken at evenly spaced rows of its descriptors, in the order of ``features``.

    Parameters
    ----------
    features : sequence of ViewFeatures
        The views' features (all float or all binary descriptors).
    words : int, default 64
        Vocabulary size.
    samples_per_word : int, default 200
        Samples per word drawn in total.
    seed : int, default 0
        Seed of :func:`kmeans`.

    Returns
    -------
    Vocabulary
    """
    binary = features[0].descriptors.dtype == np.uint8
    share = max(1, words * samples_per_word // len(features))
    parts = []
    for f in features:
        n = len(f.descriptors)
        rows = np.unique(np.linspace(0, n - 1, min(n, share)).astype(int)) if n else []
        parts.append(descriptor_space(f.descriptors[rows], binary))
    return Vocabulary(kmeans(np.concatenate(parts), words, seed=seed), binary)


def describe_view(features: ViewFeatures, vocabulary: Vocabulary,
                  probe_words: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """The task of one view once the vocabulary is known: its words and its VLAD vector.

    Parameters
    ----------
    features : ViewFeatures
        The view's features.
    vocabulary : Vocabulary
        ``C`` centres of dimension ``D`` (:func:`train_vocabulary`).
    probe_words : int, default 3
        Number of nearest words kept per descriptor.


    Returns
    -------
    words : (N, min(probe_words, C)) int16
        Each descriptor's nearest words, nearest first.
    vlad : (C * D,) float32
        Unit VLAD vector (zero for a view without descriptors; empty when no view has
        any, and the vocabulary no words).
    """
    x = descriptor_space(features.descriptors, vocabulary.binary)
    C = vocabulary.size
    if len(x) == 0 or C == 0:  # no keypoints here, or in any view (an empty vocabulary)
        return (np.zeros((len(x), min(probe_words, C)), np.int16),
                np.zeros(C * vocabulary.centres.shape[1], np.float32))
    d = _squared_distances(x, vocabulary.centres)
    p = min(probe_words, C)
    nearest = np.argpartition(d, p - 1, axis=1)[:, :p] if p < C else np.tile(np.arange(C),
                                                                                 (len(x), 1))
    order = np.take_along_axis(d, nearest, axis=1).argsort(axis=1, kind="stable")
    nearest = np.take_along_axis(nearest, order, axis=1)
    word = nearest[:, 0]
    residual = np.zeros_like(vocabulary.centres)
    np.add.at(residual, word, x - vocabulary.centres[word])
    residual = np.sign(residual) * np.sqrt(np.abs(residual))  # power normalisation
    norms = np.linalg.norm(residual, axis=1, keepdims=True)
    residual /= np.maximum(norms, 1e-12)  # intra-normalisation
    vlad = residual.ravel()
    vlad /= max(float(np.linalg.norm(vlad)), 1e-12)
    return nearest.astype(np.int16), vlad


def similarity_ranking(vlads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every view's other views, most similar first.

    Parameters
    ----------
    vlads : (V, L) float32
        Unit VLAD vectors.

    Returns
    -------
    ranking : (V, V - 1) int
        ``ranking[i]`` lists the other views by falling similarity (ties: lower index).
    similarity : (V, V) float64
        Cosine similarities.
    """
    S = np.asarray(vlads, np.float64) @ np.asarray(vlads, np.float64).T
    V = len(S)
    keyed = S.copy()
    keyed[np.arange(V), np.arange(V)] = -np.inf
    ranking = np.argsort(-keyed, axis=1, kind="stable")[:, :V - 1]
    return ranking, S

