"""The Schur complement's camera-camera product ``sum_p W_p V_p^-1 W_p^T`` of bundle
adjustment (:mod:`scene3D.optim.schur` solves the reduced system it makes): dense for few
cameras, by pairs of observations of one point for many, and as a sparse matrix that keeps
only the blocks of cameras that share points.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from ..geometry.conventions import FloatArray


def schur_product_dense(Y: FloatArray, W: FloatArray, camera: np.ndarray, point: np.ndarray,
                        num_cameras: int, chunk_entries: int = 1 << 22) -> FloatArray:
    """:func:`schur_product` for a few cameras: dense matrix products over chunks of points.

    A chunk of points at a time is laid out densely as ``(C c, 3 points)`` matrices
    (at most ``chunk_entries`` numbers each), so the sum is one matrix product per
    chunk; a camera sees a point at most once, so the blocks never collide. The cost
    grows with the square of the cameras times the points: fast (BLAS) for tens of
    cameras, slow for hundreds.

    Parameters
    ----------
    Y, W : (O, c, 3) ndarray
        Per-observation blocks (``Y[o] = W[o] V_p^-1`` in the Schur complement).
    camera : (O,) int ndarray
        Camera of each observation, in ``[0, num_cameras)``.
    point : (O,) int ndarray
        Point of each observation.
    num_cameras : int
        Number of cameras ``C``.
    chunk_entries : int, default 2**22
        Most numbers per dense chunk.

    Returns
    -------
    (C c, C c) float64 ndarray
    """
    c = Y.shape[1]
    size = num_cameras * c
    order = np.argsort(point, kind="stable")
    cam, pt, Y, W = camera[order], point[order], Y[order], W[order]
    per_chunk = max(1, chunk_entries // (3 * size))
    rows = (cam * c)[:, None, None] + np.arange(c)[None, :, None]
    S = np.zeros((size, size))
    bounds = np.searchsorted(pt, np.arange(0, pt[-1] + per_chunk + 1, per_chunk)) if len(pt) else []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if lo == hi:
            continue
        first = pt[lo]
        cols = ((pt[lo:hi] - first) * 3)[:, None, None] + np.arange(3)[None, None, :]
        width = 3 * (pt[hi - 1] - first + 1)
        Yd, Wd = np.zeros((size, width)), np.zeros((size, width))
        Yd[rows[lo:hi], cols] = Y[lo:hi]
        Wd[rows[lo:hi], cols] = W[lo:hi]
        S += Yd @ Wd.T
    return S


def pairs_within_groups(starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every ordered pair ``(a, b)`` of members of the same group, ``a == b`` included.

    Groups are consecutive runs ``starts[g] <= k < starts[g + 1]`` of some sorted
    array; returns the member indices ``a, b`` ``(M,)`` with ``M = sum n_g^2``.

    Parameters
    ----------
    starts : (G + 1,) int ndarray
        Start of each group, then the end of the last.

    Returns
    -------
    a, b : (M,) int ndarray
    """
    counts = np.diff(starts)
    squares = counts * counts
    group = np.repeat(np.arange(len(counts)), squares)
    k = np.arange(int(squares.sum())) - np.repeat(np.cumsum(squares) - squares, squares)
    n = counts[group]
    return starts[group] + k // n, starts[group] + k % n


def schur_product_sparse(Y: FloatArray, W: FloatArray, camera: np.ndarray, point: np.ndarray,
                         num_cameras: int, chunk_entries: int = 1 << 22) -> FloatArray:
    """:func:`schur_product` for many cameras: one matrix product per pair of cameras that
    share points, over the points they share.

    A table ``(C, points)`` holds each camera's observation of each point (-1: none),
    for a chunk of points at a time (at most ``chunk_entries`` entries). For camera
    ``a``, the observations by cameras ``b >= a`` of ``a``'s points are read from it
    (grouped by ``b``), and the block ``(a, b)`` gains ``sum Y[o_a] W[o_b]^T`` over them,
    one ``(c, 3k) x (3k, c)`` product. ``Y[o] = W[o] V_p^-1`` with ``V_p`` symmetric (as
    in the Schur complement), so the block ``(b, a)`` is the transpose of ``(a, b)``.
    The work grows with the points times the square of their track lengths, not with
    the square of the cameras; no block per pair of observations is stored.

    Parameters
    ----------
    Y, W : (O, c, 3) ndarray
        Per-observation blocks (``Y[o] = W[o] V_p^-1`` in the Schur complement).
    camera : (O,) int ndarray
        Camera of each observation, in ``[0, num_cameras)``.
    point : (O,) int ndarray
        Point of each observation.
    num_cameras : int
        Number of cameras ``C``.
    chunk_entries : int, default 2**22
        Most table entries per chunk.

    Returns
    -------
    (C c, C c) float64 ndarray
    """
    c = Y.shape[1]
    size = num_cameras * c
    if len(point) == 0:
        return np.zeros((size, size))
    _, local = np.unique(point, return_inverse=True)
    per_chunk = max(1, chunk_entries // num_cameras)
    index_type = np.int32 if len(point) < 2**31 else np.int64
    by_point = np.argsort(local, kind="stable")
    bounds = np.searchsorted(local[by_point], np.arange(0, local.max() + per_chunk + 1,
                                                         per_chunk))
    Yt = np.ascontiguousarray(Y.transpose(0, 2, 1))  # (O, 3, c): rows of a (3k, c) stack
    Wt = np.ascontiguousarray(W.transpose(0, 2, 1))
    S = np.zeros((num_cameras, c, num_cameras, c))
    for first, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        if lo == hi:
            continue
        chunk = by_point[lo:hi]
        column = local[chunk] - first * per_chunk
        slot = np.full((num_cameras, per_chunk), -1, dtype=index_type)
        slot[camera[chunk], column] = chunk
        by_camera = np.argsort(camera[chunk], kind="stable")
        starts = np.searchsorted(camera[chunk][by_camera], np.arange(num_cameras + 1))
        for a in np.flatnonzero(np.diff(starts)):
            mine = by_camera[starts[a]:starts[a + 1]]
            theirs = slot[a:, column[mine]]  # (C - a, n): cameras b >= a on a's points
            rows, cols = np.nonzero(theirs >= 0)  # grouped by b
            Ya, Wb = Yt[chunk[mine[cols]]], Wt[theirs[rows, cols]]
            cuts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1], True])
            for g0, g1 in zip(cuts[:-1], cuts[1:]):
                S[a, :, a + rows[g0]] += Ya[g0:g1].reshape(-1, c).T @ Wb[g0:g1].reshape(-1, c)
    diagonal = S[np.arange(num_cameras), :, np.arange(num_cameras)].copy()  # (C, c, c)
    S += S.transpose(2, 3, 0, 1)
    S[np.arange(num_cameras), :, np.arange(num_cameras)] -= diagonal
    return S.reshape(size, size)


#: Above this many camera unknowns the Schur product is summed per pair of cameras.
SPARSE_SCHUR_UNKNOWNS = 180


def schur_product(Y: FloatArray, W: FloatArray, camera: np.ndarray, point: np.ndarray,
                  num_cameras: int) -> FloatArray:
    """``sum over points p of Y_p W_p^T``, ``(C c, C c)``, where ``Y_p`` stacks the
    ``(c, 3)`` blocks ``Y[o]`` of the observations of ``p`` by camera (zero where a camera
    does not see ``p``), and likewise ``W_p``.

    Dense chunked products for a few cameras (BLAS is fastest there), one product per
    pair of cameras that share points for many (the dense layout grows with the square
    of the cameras): both give the same sum.

    Parameters
    ----------
    Y, W : (O, c, 3) ndarray
        Per-observation blocks (``Y[o] = W[o] V_p^-1`` in the Schur complement).
    camera : (O,) int ndarray
        Camera of each observation, in ``[0, num_cameras)``.
    point : (O,) int ndarray
        Point of each observation.
    num_cameras : int
        Number of cameras ``C``.

    Returns
    -------
    (C c, C c) float64 ndarray
    """
    if num_cameras * Y.shape[1] <= SPARSE_SCHUR_UNKNOWNS:
        return schur_product_dense(Y, W, camera, point, num_cameras)
    return schur_product_sparse(Y, W, camera, point, num_cameras)


def schur_matrix_sparse(Y: FloatArray, W: FloatArray, camera: np.ndarray, point: np.ndarray,
                        num_cameras: int, chunk_pairs: int = 1 << 17) -> sparse.csr_matrix:
    """:func:`schur_product` as a sparse matrix: only the blocks of cameras that share
    points are stored.

    Each pair of observations of the same point (by cameras ``a``, ``b``) adds
    ``Y[o_a] W[o_b]^T`` to the block ``(a, b)``; the pairs, sorted by their block, are
    taken ``chunk_pairs`` at a time and summed per block. Memory grows with the pairs of
    cameras that share points, not with the square of the cameras.

    Parameters
    ----------
    Y, W : (O, c, 3) ndarray
        Per-observation blocks (``Y[o] = W[o] V_p^-1`` in the Schur complement).
    camera : (O,) int ndarray
        Camera of each observation, in ``[0, num_cameras)``.
    point : (O,) int ndarray
        Point of each observation.
    num_cameras : int
        Number of cameras ``C``.
    chunk_pairs : int, default 2**17
        Most pairs of observations per chunk.

    Returns
    -------
    (C c, C c) scipy.sparse.csr_matrix
    """
    c = Y.shape[1]
    size = num_cameras * c
    order = np.argsort(point, kind="stable")
    starts = np.searchsorted(point[order], np.r_[np.unique(point), np.iinfo(np.int64).max])
    first, second = pairs_within_groups(starts)
    first, second = order[first], order[second]
    key = camera[first].astype(np.int64) * num_cameras + camera[second]
    by_key = np.argsort(key, kind="stable")
    first, second, key = first[by_key], second[by_key], key[by_key]
    keys, block_of = np.unique(key, return_inverse=True)
    blocks = np.zeros((len(keys), c, c))
    for lo in range(0, len(first), chunk_pairs):
        hi = min(lo + chunk_pairs, len(first))
        values = Y[first[lo:hi]] @ W[second[lo:hi]].transpose(0, 2, 1)  # (n, c, c)
        cuts = np.flatnonzero(np.r_[True, block_of[lo + 1:hi] != block_of[lo:hi - 1]])
        blocks[block_of[lo + cuts]] += np.add.reduceat(values, cuts, axis=0)
    indptr = np.searchsorted(keys // num_cameras, np.arange(num_cameras + 1))
    return sparse.bsr_matrix((blocks, keys % num_cameras, indptr),
                             shape=(size, size)).tocsr()
