"""Which pairs of views to match.

- ``"all"``: every pair (quadratic; the surest for small sets).
- ``"sequential"``: each view with its ``neighbours`` followers in the input order
  (photos or frames taken along a path).
- ``"retrieval"``: each view with its ``retrieval_neighbours`` most similar views
  (:mod:`scene3D.multiview.retrieval`); any collection, in any order.
- ``"auto"``: all pairs while that is hardly more than retrieval would match
  (at most ``2 k + 1`` views); beyond, retrieval, plus the sequential neighbours when
  the input order is a sequence by the images' own evidence (most consecutive views
  are among each other's most similar), never by their file names.

Pairs are ``(i, j)`` with ``i < j``, sorted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

PAIR_MODES = ("auto", "retrieval", "sequential", "all")

#: ``auto`` takes the input order for a sequence when at least this share of consecutive
#: views are among each other's most similar views.
SEQUENCE_EVIDENCE = 0.75


def all_pairs(num_views: int) -> list[tuple[int, int]]:
    """Every pair of ``num_views`` views (exhaustive matching).

    Parameters
    ----------
    num_views : int
        Number of views.

    Returns
    -------
    list of (int, int)
        Every pair ``(i, j)`` with ``i < j``, sorted.
    """
    return [(i, j) for i in range(num_views) for j in range(i + 1, num_views)]


def _ordered(pairs: set[tuple[int, int]]) -> list[tuple[int, int]]:
    return sorted({(min(a, b), max(a, b)) for a, b in pairs if a != b})


def sequential_pairs(sequence: Sequence[int], neighbours: int) -> list[tuple[int, int]]:
    """Each view with its ``neighbours`` followers in ``sequence`` (view indices in order).

    Parameters
    ----------
    sequence : sequence of int
        View indices in capture order.
    neighbours : int
        Number of following views each view is paired with.

    Returns
    -------
    list of (int, int)
        Pairs ``(i, j)`` with ``i < j``, sorted.
    """
    return _ordered({(sequence[a], sequence[b]) for a in range(len(sequence))
                     for b in range(a + 1, min(len(sequence), a + 1 + neighbours))})


def retrieval_pairs(ranking: np.ndarray, k: int) -> list[tuple[int, int]]:
    """Each view with its ``k`` most similar views (``ranking`` as from
    :func:`scene3D.multiview.retrieval.similarity_ranking`).

    Parameters
    ----------
    ranking : (V, V') int ndarray
        Row ``i``: the other views, most similar first.
    k : int
        Number of most similar views each view is paired with.

    Returns
    -------
    list of (int, int)
        Pairs ``(i, j)`` with ``i < j``, sorted.
    """
    return _ordered({(i, int(j)) for i in range(len(ranking)) for j in ranking[i, :k]})


def sequence_evidence(sequence: Sequence[int], ranking: np.ndarray, k: int) -> float:
    """Share of consecutive views of ``sequence`` that are among each other's ``k`` most
    similar views (one way or the other).

    Parameters
    ----------
    sequence : sequence of int
        View indices in capture order.
    ranking : (V, V') int ndarray
        Row ``i``: the other views, most similar first.
    k : int
        How many of the most similar views count.

    Returns
    -------
    float
        In ``[0, 1]``; 0 for fewer than two views.
    """
    if len(sequence) < 2:
        return 0.0
    top = [set(int(v) for v in row[:k]) for row in ranking]
    hits = [b in top[a] or a in top[b] for a, b in zip(sequence[:-1], sequence[1:])]
    return float(np.mean(hits))


def select_pairs(num_views: int, mode: str = "auto", neighbours: int = 3,
                 ranking: np.ndarray | None = None, retrieval_neighbours: int = 8,
                 sequence: Sequence[int] | None = None) -> tuple[list[tuple[int, int]], str]:
    """Pairs of views to match, and a description of the choice.

    Parameters
    ----------
    num_views : int
    mode : str
        One of :data:`PAIR_MODES` (see the module docstring).
    neighbours : int
        Followers per view for sequential pairs.
    ranking : (V, V - 1) int, optional
        Views by similarity (needed by ``"retrieval"``, and by ``"auto"`` beyond
        ``2 * retrieval_neighbours + 1`` views).
    retrieval_neighbours : int
    sequence : sequence of int, optional
        The views in their input order (default ``0 .. V-1``).
    """
    if mode not in PAIR_MODES:
        raise ValueError(f"`pairs` must be one of {', '.join(map(repr, PAIR_MODES))}, "
                         f"got {mode!r}")
    sequence = list(range(num_views)) if sequence is None else list(sequence)
    if mode == "all":
        return all_pairs(num_views), "all pairs"
    if mode == "sequential":
        return (sequential_pairs(sequence, neighbours),
                f"sequential ({neighbours} following views)")
    auto = mode == "auto"
    if auto and num_views <= 2 * retrieval_neighbours + 1:
        return all_pairs(num_views), f"all pairs (auto: {num_views} views)"
    if ranking is None:
        raise ValueError(f"pair selection {mode!r} needs the views' similarity ranking")
    k = min(retrieval_neighbours, num_views - 1)
    pairs = set(retrieval_pairs(ranking, k))
    text = f"retrieval ({k} most similar views)"
    if auto:
        evidence = sequence_evidence(sequence, ranking, k)
        if evidence >= SEQUENCE_EVIDENCE:
            pairs |= set(sequential_pairs(sequence, neighbours))
            text += (f" + sequential ({neighbours} following views; auto: the input order is "
                     f"a sequence, {100 * evidence:.0f} % of consecutive views similar)")
        else:
            text += (f" (auto: {num_views} views, input order not a sequence, "
                     f"{100 * evidence:.0f} % of consecutive views similar)")
    return _ordered(pairs), text
