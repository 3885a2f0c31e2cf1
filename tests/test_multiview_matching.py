import numpy as np

from scene3D.multiview.matching import match_by_words, nearest_two


def _descriptors(rng, n, dim=16):
    """SIFT-like integer descriptors: their float32 squared distances are exact."""
    return rng.integers(0, 512, size=(n, dim)).astype(np.float32)


def _mutual_then_ratio(d_i, w_i, d_j, w_j, num_words, ratio=0.8):
    """The other order: the mutual check on every row, then the ratio test."""
    nearest, d1, d2 = nearest_two(d_i, w_i, d_j, w_j[:, 0], num_words)
    back = nearest_two(d_j, w_j, d_i, w_i[:, 0], num_words)[0]
    mutual = (nearest >= 0) & (back[np.maximum(nearest, 0)] == np.arange(len(d_i)))
    idx_i = np.flatnonzero(mutual & (d1 < ratio * ratio * d2))
    return idx_i, nearest[idx_i]


def test_all_words_probed_gives_the_exhaustive_ratio_and_mutual_matches():
    rng = np.random.default_rng(3)
    d_i, d_j = _descriptors(rng, 70), _descriptors(rng, 55)
    # d_j holds noisy copies of 40 rows of d_i, so that real matches exist.
    d_j[:40] = d_i[10:50] + rng.integers(-3, 4, size=(40, 16))
    num_words = 4
    w_i = np.tile(np.arange(num_words), (len(d_i), 1))
    w_j = np.tile(np.arange(num_words), (len(d_j), 1))
    w_j[:, 0] = rng.integers(0, num_words, len(d_j))  # where each base row is filed
    w_i[:, 0] = rng.integers(0, num_words, len(d_i))
    w_i = np.array([np.r_[r[0], np.setdiff1d(np.arange(num_words), r[0])] for r in w_i])
    w_j = np.array([np.r_[r[0], np.setdiff1d(np.arange(num_words), r[0])] for r in w_j])
    idx_i, idx_j, ratios = match_by_words(d_i, w_i, d_j, w_j, num_words)

    dist = ((d_i[:, None, :].astype(np.float64) - d_j[None]) ** 2).sum(-1)
    order = np.sort(dist, axis=1)
    fwd, back = dist.argmin(1), dist.argmin(0)
    keep = (order[:, 0] < 0.64 * order[:, 1]) & (back[fwd] == np.arange(len(d_i)))
    expected = np.flatnonzero(keep)
    np.testing.assert_array_equal(idx_i, expected)
    np.testing.assert_array_equal(idx_j, fwd[expected])
    np.testing.assert_allclose(ratios, np.sqrt(order[expected, 0] / order[expected, 1]),
                               rtol=1e-6)
    assert {(10 + k, k) for k in range(40)} <= set(zip(idx_i.tolist(), idx_j.tolist()))


def test_ratio_test_before_the_mutual_check_keeps_the_same_matches():
    # The matcher checks mutuality only for the ratio test's winners (cheaper); the
    # matches equal those of the mutual check on every row followed by the ratio test.
    rng = np.random.default_rng(5)
    d_i, d_j = _descriptors(rng, 300), _descriptors(rng, 260)
    d_j[:150] = d_i[:150] + rng.integers(-20, 21, size=(150, 16))
    num_words = 6
    w_i = np.stack([rng.permutation(num_words)[:2] for _ in d_i])
    w_j = np.stack([rng.permutation(num_words)[:2] for _ in d_j])
    idx_i, idx_j, _ = match_by_words(d_i, w_i, d_j, w_j, num_words)
    other_i, other_j = _mutual_then_ratio(d_i, w_i, d_j, w_j, num_words)
    assert len(idx_i) > 20  # not a vacuous equality
    np.testing.assert_array_equal(idx_i, other_i)
    np.testing.assert_array_equal(idx_j, other_j)
