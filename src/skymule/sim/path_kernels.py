"""The arithmetic of :meth:`Navigator.steps` and :meth:`~Navigator.travel_distances` for many
rows, as plain loops numba can compile (the batched autonomous engine's ``compiled`` path).

Nothing here tests visibility: the geofence predicate (shapely ``covers``) stays in Python,
between these kernels (:mod:`skymule.sim.batch_paths`). What is here is the rest of a
shortest-path query, written so every float is the one the numpy methods compute (up to the
order of a sum):

* the same operations in the same order (``(d_s + D) + d_g``, first index of the minimum,
  stable order of ties);
* segment lengths as ``np.hypot`` (the C library's, which numba also calls);
* path lengths summed with ``np.sum`` (numba's sums in another order: the compiled twin
  equals the numpy methods to a relative 1e-12, and bit for bit as plain Python).

Nothing imports a compiler: the module runs as plain Python too (slowly).
"""

from __future__ import annotations

import numpy as np


def rank_vertices(
    start: np.ndarray,
    goal_vis: np.ndarray,
    goal_d: np.ndarray,
    vertices: np.ndarray,
    dist: np.ndarray,
    d_s: np.ndarray,
    row_min: np.ndarray,
    order: np.ndarray,
) -> None:
    """For R starts (R, 2) not seeing their goals: ``d_s`` (R, k) straight distances to the
    vertices, ``row_min`` (R, k) the smallest total through each first vertex and ``order``
    (R, q) the q first vertices by that total (ties: the lower vertex: a stable argsort), as
    ``Navigator.shortest_paths`` computes them."""
    n_rows, k = d_s.shape
    ranks = order.shape[1]
    for r in range(n_rows):
        for i in range(k):
            d_s[r, i] = np.hypot(vertices[i, 0] - start[r, 0], vertices[i, 1] - start[r, 1])
            best = np.inf
            for j in range(k):
                g = goal_d[r, j] if goal_vis[r, j] else np.inf
                total = d_s[r, i] + dist[i, j] + g
                if total < best:
                    best = total
            row_min[r, i] = best
        # insertion sort of the vertices by total: a stable argsort (ties keep the lower
        # vertex first, because a vertex moves only past strictly larger totals)
        for i in range(k):
            q = min(i, ranks)
            while q > 0 and row_min[r, i] < row_min[r, order[r, q - 1]]:
                if q < ranks:
                    order[r, q] = order[r, q - 1]
                q -= 1
            if q < ranks:
                order[r, q] = i


def pick_routes(
    first: np.ndarray,
    d_s: np.ndarray,
    goal_vis: np.ndarray,
    goal_d: np.ndarray,
    dist: np.ndarray,
    last: np.ndarray,
) -> bool:
    """The last route vertex of each row's path, from its ``first`` (-1: none seen); False
    if some row has no path (no first vertex, or no finite total from it).

    The last vertex is the first of the smallest total ``(d_s + D) + d_g`` from ``first``,
    as ``np.argmin``.
    """
    n_rows, k = d_s.shape
    found = True
    for r in range(n_rows):
        i = first[r]
        last[r] = 0
        if i < 0:
            found = False
            continue
        best = np.inf
        for j in range(k):
            g = goal_d[r, j] if goal_vis[r, j] else np.inf
            total = d_s[r, i] + dist[i, j] + g
            if total < best:
                best = total
                last[r] = j
        if not best < np.inf:
            found = False
    return found


def _path_point(
    row: int,
    index: int,
    start: np.ndarray,
    goal: np.ndarray,
    bend: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    nodes: np.ndarray,
    count: np.ndarray,
    vertices: np.ndarray,
) -> tuple[float, float]:
    """Point ``index`` of row ``row``'s path: start, the route's vertices, goal."""
    if index == 0:
        return start[row, 0], start[row, 1]
    b = bend[row]
    if b >= 0 and index - 1 < count[first[b], last[b]]:
        v = nodes[first[b], last[b], index - 1]
        return vertices[v, 0], vertices[v, 1]
    return goal[row, 0], goal[row, 1]


def _path_size(
    row: int, bend: np.ndarray, first: np.ndarray, last: np.ndarray, count: np.ndarray
) -> int:
    """Points of row ``row``'s path: 2, plus the route's vertices where the path bends."""
    b = bend[row]
    return 2 if b < 0 else 2 + int(count[first[b], last[b]])


def advance_rows(
    start: np.ndarray,
    goal: np.ndarray,
    step_m: np.ndarray,
    bend: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    nodes: np.ndarray,
    count: np.ndarray,
    vertices: np.ndarray,
    moved: np.ndarray,
) -> None:
    """``moved`` (P, 2): each row's ``advance_along`` of its path by ``step_m`` (P,).

    ``bend[p]``: the row among the bending paths (index into ``first``/``last``), or -1 for a
    straight path. Segment lengths as ``np.hypot``.
    """
    for row in range(start.shape[0]):
        n = _path_size(row, bend, first, last, count)
        left = step_m[row]
        moved[row, 0], moved[row, 1] = goal[row, 0], goal[row, 1]
        ax, ay = start[row, 0], start[row, 1]
        for seg in range(n - 1):
            bx, by = _path_point(
                row, seg + 1, start, goal, bend, first, last, nodes, count, vertices
            )
            dx, dy = bx - ax, by - ay
            length = np.hypot(dx, dy)
            if left < length:
                t = left / length
                moved[row, 0] = ax + t * dx
                moved[row, 1] = ay + t * dy
                break
            left -= length
            ax, ay = bx, by


def path_lengths(
    start: np.ndarray,
    goal: np.ndarray,
    bend: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    nodes: np.ndarray,
    count: np.ndarray,
    vertices: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out`` (P,): each row's path length, as ``Navigator.travel_distances`` (segment
    lengths by ``np.hypot``, summed by ``np.sum``)."""
    lengths = np.empty(nodes.shape[2] + 1)
    for row in range(start.shape[0]):
        n = _path_size(row, bend, first, last, count)
        ax, ay = start[row, 0], start[row, 1]
        for seg in range(n - 1):
            bx, by = _path_point(
                row, seg + 1, start, goal, bend, first, last, nodes, count, vertices
            )
            lengths[seg] = np.hypot(bx - ax, by - ay)
            ax, ay = bx, by
        out[row] = lengths[: n - 1].sum()
