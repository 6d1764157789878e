"""Write a MovingAI-format .scen for a .map: N agents on distinct free cells, seeded.

Used for maps whose benchmark ``-random-1.scen`` was not available here:
``python tests/data/maps/make_scen.py MAP N SEED OUT``.  Starts are distinct
free cells of the largest 4-connected free region, goals too (drawn
independently); optimal_length is the octile shortest path without corner
cutting, as in the benchmark.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from sim.scenario.maps import read_grid


def main(map_path: str, n: int, seed: int, out: str) -> None:
    grid = read_grid(Path(map_path))
    free = ~grid.blocked
    labels, _ = ndimage.label(free)
    biggest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    cells = np.argwhere(labels == biggest)  # (row, col)
    rng = np.random.default_rng(seed)
    starts = cells[rng.choice(len(cells), n, replace=False)]
    goals = cells[rng.choice(len(cells), n, replace=False)]
    rows, cols = free.shape
    idx = -np.ones(free.shape, int)
    idx[free] = np.arange(free.sum())
    src, dst, w = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        for r, c in np.argwhere(free):
            r2, c2 = r + dr, c + dc
            if 0 <= r2 < rows and 0 <= c2 < cols and free[r2, c2] and free[r, c2] and free[r2, c]:
                src.append(idx[r, c])
                dst.append(idx[r2, c2])
                w.append(np.hypot(dr, dc))
    g = coo_matrix((w, (src, dst)), shape=(free.sum(),) * 2).tocsr()
    dist = dijkstra(g, directed=False, indices=idx[starts[:, 0], starts[:, 1]])
    lines = ["version 1"]
    name = Path(map_path).name
    for i, ((sr, sc), (gr, gc)) in enumerate(zip(starts, goals)):
        length = dist[i, idx[gr, gc]]
        lines.append(f"{i // 10}\t{name}\t{cols}\t{rows}\t{sc}\t{sr}\t{gc}\t{gr}\t{length:.8f}")
    Path(out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
