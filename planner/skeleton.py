"""A binary mask thinned into a stroke skeleton: polylines along the middle of the ink.

:func:`mask_strokes` is what turns rendered text (or any ink mask) into a
drawing for :mod:`planner.strokes`:

1. *Thinning* (Zhang and Suen, 1984): border pixels are peeled off in two
   alternating sub-passes until a one-pixel-wide, 8-connected skeleton is
   left that keeps the ink's topology (an ``O`` stays a loop, an ``A`` keeps
   its hole).
2. *Tracing*: the skeleton pixels become a graph (4-neighbours, plus
   diagonal neighbours that are not already joined through a 4-neighbour).
   Pixels with other than two neighbours are nodes; touching junction
   pixels are merged into one node at their centroid.  Every chain of
   pixels between two nodes is an edge; a component without nodes is a
   closed loop.
3. *Pruning*: short spurs (an end joined to a junction by less than about
   the ink's width) are thinning artefacts of corners and serifs, and are
   removed repeatedly; a node left with two edges joins them.
4. *Smoothing*: each chain is smoothed by a short moving average (ends
   kept) and simplified (Douglas-Peucker, half a pixel), which removes the
   pixel staircase while keeping sharp corners.

Coordinates: pixel ``(row, col)`` of the mask has its centre at
``(col + 0.5, row + 0.5)``; rows count upwards (y up).  A dot (a component
that thins to a single pixel) is a zero-length stroke.
"""

from __future__ import annotations

import networkx as nx
import numpy as np
from scipy import ndimage

__all__ = ["mask_strokes", "thin"]

_MAX_PIXELS = 4_000_000  # a mask bigger than this is refused
_SMOOTH = 2  # half-width of the moving average [px]
_SIMPLIFY = 0.5  # Douglas-Peucker tolerance [px]


def thin(mask: np.ndarray) -> np.ndarray:
    """The Zhang-Suen skeleton of a boolean mask (same shape, bool)."""
    img = np.pad(np.asarray(mask, bool), 1).astype(np.uint8)
    while True:
        changed = False
        for first in (True, False):
            p2 = img[:-2, 1:-1]
            p3 = img[:-2, 2:]
            p4 = img[1:-1, 2:]
            p5 = img[2:, 2:]
            p6 = img[2:, 1:-1]
            p7 = img[2:, :-2]
            p8 = img[1:-1, :-2]
            p9 = img[:-2, :-2]
            ring = (p2, p3, p4, p5, p6, p7, p8, p9, p2)
            b = p2 + p3 + p4 + p5 + p6 + p7 + p8 + p9
            a = sum(((ring[k] == 0) & (ring[k + 1] == 1)).astype(np.uint8) for k in range(8))
            if first:
                c = (p2 * p4 * p6 == 0) & (p4 * p6 * p8 == 0)
            else:
                c = (p2 * p4 * p8 == 0) & (p2 * p6 * p8 == 0)
            core = img[1:-1, 1:-1]
            kill = (core == 1) & (b >= 2) & (b <= 6) & (a == 1) & c
            if kill.any():
                core[kill] = 0
                changed = True
        if not changed:
            return img[1:-1, 1:-1].astype(bool)


def _pixel_graph(skel: np.ndarray) -> nx.Graph:
    """Skeleton pixels ``(row, col)`` joined to 4-neighbours and to unshortcut diagonals."""
    g = nx.Graph()
    rows, cols = np.nonzero(skel)
    g.add_nodes_from(zip(rows.tolist(), cols.tolist()))
    h, w = skel.shape

    def on(r, c):
        return 0 <= r < h and 0 <= c < w and bool(skel[r, c])

    for r, c in zip(rows.tolist(), cols.tolist()):
        for dr, dc in ((0, 1), (1, 0)):
            if on(r + dr, c + dc):
                g.add_edge((r, c), (r + dr, c + dc))
        for dr, dc in ((1, 1), (1, -1)):
            if on(r + dr, c + dc) and not (on(r + dr, c) or on(r, c + dc)):
                g.add_edge((r, c), (r + dr, c + dc))
    return g


def _xy(pixels) -> np.ndarray:
    a = np.asarray(pixels, float).reshape(-1, 2)
    return np.stack([a[:, 1] + 0.5, a[:, 0] + 0.5], axis=1)


def _trace(g: nx.Graph) -> tuple[dict, list, list]:
    """Nodes (id -> xy), edges ``(u, v, (k, 2) xy)`` between them, and closed loops."""
    special = {p for p in g if g.degree(p) != 2}
    junction = [p for p in special if g.degree(p) >= 3]
    node_of: dict = {}
    nodes: dict = {}
    for comp in nx.connected_components(g.subgraph(junction)):
        nid = len(nodes)
        nodes[nid] = _xy(sorted(comp)).mean(axis=0)
        for p in comp:
            node_of[p] = nid
    for p in sorted(special):
        if p not in node_of:
            nid = len(nodes)
            nodes[nid] = _xy([p])[0]
            node_of[p] = nid
    edges = []
    seen = set()
    for p in sorted(node_of):
        for q in sorted(g.neighbors(p)):
            if q in node_of:
                if node_of[q] != node_of[p] and (q, p) not in seen:
                    seen.add((p, q))
                    edges.append((node_of[p], node_of[q], np.stack([nodes[node_of[p]], nodes[node_of[q]]])))
                continue
            if (p, q) in seen:
                continue
            chain = [p, q]
            prev, cur = p, q
            while cur not in node_of:
                nxt = [n for n in g.neighbors(cur) if n != prev]
                prev, cur = cur, nxt[0]
                chain.append(cur)
            seen.add((chain[-1], chain[-2]))
            xy = _xy(chain)
            xy[0], xy[-1] = nodes[node_of[p]], nodes[node_of[cur]]
            edges.append((node_of[p], node_of[cur], xy))
    loops = []
    done = set(node_of)
    for p in sorted(g):
        if p in done or g.degree(p) != 2:
            continue
        comp = nx.node_connected_component(g, p)
        done |= comp
        if not comp.isdisjoint(node_of):
            continue
        chain = [p]
        prev, cur = None, p
        while True:
            nxt = sorted(n for n in g.neighbors(cur) if n != prev)
            prev, cur = cur, nxt[0]
            if cur == p:
                break
            chain.append(cur)
        xy = _xy(chain)
        loops.append(np.vstack([xy, xy[:1]]))
    return nodes, edges, loops


def _length(xy: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())


def _prune(nodes: dict, edges: list, spur: float) -> list:
    """Remove spurs shorter than ``spur`` that end at a junction; join two-edge nodes."""
    edges = list(edges)
    while True:
        deg: dict = {}
        for u, v, _ in edges:
            deg[u] = deg.get(u, 0) + 1
            deg[v] = deg.get(v, 0) + 1
        cut = None
        best = spur
        for n, (u, v, xy) in enumerate(edges):
            if u == v:
                continue
            ell = _length(xy)
            if ell < best and ((deg[u] == 1 and deg[v] >= 3) or (deg[v] == 1 and deg[u] >= 3)):
                cut, best = n, ell
        if cut is not None:
            edges.pop(cut)
            continue
        # join the two edges at a node of degree 2 (left by a removed spur)
        joined = False
        for node, d in sorted(deg.items()):
            if d != 2:
                continue
            at = [n for n, (u, v, _) in enumerate(edges) if node in (u, v)]
            if len(at) != 2:
                continue  # a loop edge u == v == node
            (u1, v1, a), (u2, v2, b) = edges[at[0]], edges[at[1]]
            a = a if v1 == node else a[::-1]
            b = b if u2 == node else b[::-1]
            s = u1 if v1 == node else v1
            t = v2 if u2 == node else u2
            for n in sorted(at, reverse=True):
                edges.pop(n)
            edges.append((s, t, np.vstack([a, b[1:]])))
            joined = True
            break
        if not joined:
            return edges


def _smooth(xy: np.ndarray, closed: bool) -> np.ndarray:
    """Moving average of half-width :data:`_SMOOTH` (ends of open chains kept)."""
    n = len(xy) - (1 if closed else 0)
    if n < 3:
        return xy
    k = _SMOOTH
    if closed:
        base = xy[:-1]
        idx = (np.arange(n)[:, None] + np.arange(-k, k + 1)[None]) % n
        out = base[idx].mean(axis=1)
        return np.vstack([out, out[:1]])
    out = xy.copy()
    for i in range(1, n - 1):
        h = min(k, i, n - 1 - i)
        out[i] = xy[i - h : i + h + 1].mean(axis=0)
    return out


def _simplify(xy: np.ndarray, tol: float) -> np.ndarray:
    """Douglas-Peucker: the fewest vertices within ``tol`` of the chain."""
    if len(xy) <= 2:
        return xy
    keep = np.zeros(len(xy), bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(xy) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = xy[i], xy[j]
        ab = b - a
        L = float(np.hypot(*ab))
        seg = xy[i + 1 : j]
        if L == 0:
            d = np.hypot(*(seg - a).T)
        else:
            d = np.abs(ab[0] * (seg[:, 1] - a[1]) - ab[1] * (seg[:, 0] - a[0])) / L
        k = int(np.argmax(d))
        if d[k] > tol:
            keep[i + 1 + k] = True
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return xy[keep]


def mask_strokes(mask: np.ndarray, *, spur: float | None = None) -> list[np.ndarray]:
    """Polylines ``(k, 2)`` along the middle of the ink of ``mask`` (y-up pixel coordinates).

    ``spur``: end branches shorter than this are removed [px]; default 1.5
    times the ink's typical half-width (the median distance from a
    skeleton pixel to the background), and at least 2 px.  A closed
    polyline repeats its first point at the end.  Raises ``ValueError`` for
    an empty or oversized mask.
    """
    mask = np.asarray(mask, bool)
    if mask.ndim != 2 or mask.size > _MAX_PIXELS:
        raise ValueError(f"mask must be 2-D with at most {_MAX_PIXELS} pixels, got shape {mask.shape}")
    if not mask.any():
        raise ValueError("mask holds no ink")
    skel = thin(mask)
    # thinning erases a 2 x 2 block entirely: such an ink blob keeps its
    # pixel nearest to its centroid as a dot
    labels, count = ndimage.label(mask, structure=np.ones((3, 3), int))
    kept = np.unique(labels[skel])
    for lab in sorted(set(range(1, count + 1)) - set(kept.tolist())):
        rows, cols = np.nonzero(labels == lab)
        k = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
        skel[rows[k], cols[k]] = True
    if spur is None:
        depth = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
        spur = max(2.0, 1.5 * float(np.median(depth[skel])))
    g = _pixel_graph(skel)
    nodes, edges, loops = _trace(g)
    edges = _prune(nodes, edges, spur)
    out = []
    for u, v, xy in edges:
        closed = u == v and len(xy) > 3
        out.append(_simplify(_smooth(xy, closed), _SIMPLIFY))
    for xy in loops:
        out.append(_simplify(_smooth(xy, True), _SIMPLIFY))
    # single-pixel components (dots) are zero-length strokes
    for p in sorted(g):
        if g.degree(p) == 0:
            xy = _xy([p])[0]
            out.append(np.stack([xy, xy]))
    return out
