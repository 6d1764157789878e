"""Greedy picks of points that keep a separation from each other (KD-tree accelerated)."""

from __future__ import annotations

import numpy as np

__all__ = ["greedy_separated"]


def greedy_separated(cand: np.ndarray, sep: float, existing: np.ndarray | None = None,
                     limit: int | None = None) -> np.ndarray:
    """Indices of candidates accepted in order when ``sep`` from all accepted so far.

    Candidates too close to ``existing`` points are skipped; at most
    ``limit`` are accepted.  KD-trees keep this near-linear.
    """
    from scipy.spatial import cKDTree

    cand = np.asarray(cand, float).reshape(-1, 2)
    idx = np.arange(len(cand))
    if existing is not None and len(existing) and len(cand):
        d, _ = cKDTree(existing).query(cand, distance_upper_bound=sep)
        idx = idx[d >= sep]
    if len(idx) == 0 or limit == 0:
        return idx[:0]
    later = [[] for _ in range(len(idx))]
    for i, j in cKDTree(cand[idx]).query_pairs(sep, output_type="ndarray"):
        later[min(i, j)].append(max(i, j))
    blocked = np.zeros(len(idx), bool)
    accepted = []
    for i in range(len(idx)):
        if blocked[i]:
            continue
        accepted.append(i)
        if limit is not None and len(accepted) >= limit:
            break
        blocked[later[i]] = True
    return idx[accepted]
