"""Stage 4: tracks, the verified matches chained across views.

Every keypoint of every view is a node, numbered view after view
(``node = offsets[view] + keypoint``). Verified matches are edges; a track is a
connected component of two nodes or more. A component holding two keypoints of one
view is ambiguous (some match in it is wrong) and is dropped whole.

Components come from vectorised label propagation with pointer jumping (each node
takes the smallest node number of its component), so chaining a million matches
costs a few numpy passes, not a Python loop per match. Track numbers follow the
smallest node of each track: the same matches give the same tracks.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from .view_data import PairMatches


@dataclass(frozen=True)
class Tracks:
    """Tracks over all views' keypoints.

    Attributes
    ----------
    offsets : (V + 1,) int
        Node numbers of view ``v`` are ``offsets[v] .. offsets[v + 1] - 1``.
    node_track : (N,) int
        Track of each node, -1 for none.
    num_tracks : int
    """

    offsets: np.ndarray
    node_track: np.ndarray
    num_tracks: int

    @property
    def node_view(self) -> np.ndarray:
        """View of each node ``(N,)``."""
        return np.repeat(np.arange(len(self.offsets) - 1), np.diff(self.offsets))

    def members(self) -> tuple[np.ndarray, np.ndarray]:
        """Nodes grouped by track: ``nodes[starts[k]:starts[k + 1]]`` are track ``k``'s."""
        used = np.flatnonzero(self.node_track >= 0)
        nodes = used[np.argsort(self.node_track[used], kind="stable")]
        starts = np.searchsorted(self.node_track[nodes], np.arange(self.num_tracks + 1))
        return nodes, starts

    def as_dicts(self) -> list[dict[int, int]]:
        """Each track as ``{view: keypoint}`` (for reading and tests)."""
        nodes, starts = self.members()
        view = self.node_view
        return [{int(view[n]): int(n - self.offsets[view[n]]) for n in nodes[a:b]}
                for a, b in zip(starts[:-1], starts[1:])]


def connected_components(num_nodes: int, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Label ``(num_nodes,)`` of each node: the smallest node of its component.

    ``u, v`` ``(E,)`` are the edges. Each round hooks every component onto the smallest
    label across its edges, then jumps pointers until every label is a root.

    Parameters
    ----------
    num_nodes : int
        Number of nodes.
    u, v : (E,) int ndarray
        Edge end points, nodes in ``[0, num_nodes)``.

    Returns
    -------
    (num_nodes,) int ndarray
    """
    label = np.arange(num_nodes)
    while True:
        lu, lv = label[u], label[v]
        differ = lu != lv
        if not differ.any():
            return label
        lo, hi = np.minimum(lu[differ], lv[differ]), np.maximum(lu[differ], lv[differ])
        np.minimum.at(label, hi, lo)
        while True:
            jumped = label[label]
            if np.array_equal(jumped, label):
                break
            label = jumped


def _edges(pairs: Iterable[PairMatches] | dict, offsets: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    items = ([(i, j, a, b) for (i, j), (a, b) in pairs.items()] if isinstance(pairs, dict)
             else [(p.i, p.j, p.idx_i, p.idx_j) for p in pairs])
    if not items:
        return np.zeros(0, int), np.zeros(0, int)
    u = np.concatenate([offsets[i] + np.asarray(a, int) for i, _, a, _ in items])
    v = np.concatenate([offsets[j] + np.asarray(b, int) for _, j, _, b in items])
    return u, v


def build_tracks(num_keypoints: Sequence[int], pairs: Iterable[PairMatches] | dict) -> Tracks:
    """Chain verified matches into tracks.

    Parameters
    ----------
    num_keypoints : sequence of int
        Keypoints per view.
    pairs : iterable of PairMatches, or dict ``{(i, j): (idx_i, idx_j)}``

    Returns
    -------
    Tracks
        Components of at least two nodes with at most one node per view.
    """
    offsets = np.concatenate([[0], np.cumsum(np.asarray(num_keypoints, dtype=int))])
    total = int(offsets[-1])
    u, v = _edges(pairs, offsets)
    label = connected_components(total, u, v)
    used = np.zeros(total, dtype=bool)
    used[u] = used[v] = True
    nodes = np.flatnonzero(used)
    roots = label[nodes]
    view = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))[nodes]
    # A component is kept when its (root, view) pairs are all distinct.
    key = roots * (len(offsets) - 1) + view
    keys, counts = np.unique(key, return_counts=True)
    bad_roots = np.unique(keys[counts > 1] // (len(offsets) - 1))
    keep = ~np.isin(roots, bad_roots)
    node_track = np.full(total, -1, dtype=int)
    kept_roots, track = np.unique(roots[keep], return_inverse=True)
    node_track[nodes[keep]] = track
    return Tracks(offsets, node_track, len(kept_roots))
