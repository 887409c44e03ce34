"""Certain answers to the navigator's segment test, for the segments that are far from the fence.

The navigator decides whether a UAV can fly straight from a to b with shapely's ``covers``
against the fence grown by ``COVER_TOLERANCE_M`` (1e-6 m) -- an exact predicate, but about a
microsecond per segment from Python. Most segments the batched autonomous engine asks about
are nowhere near the fence's edges, and for those plain geometry gives the same answer for
certain:

* if no point of the segment, except endpoints that are fence vertices, comes within
  ``margin_m`` of an edge (any ring), the open segment does not meet the boundary, so it lies
  wholly inside or wholly outside the fence, as its midpoint does; a midpoint more than
  ``margin_m`` from every edge is classified by the even-odd rule without round-off doubt:
  inside -> :data:`VISIBLE` (the fence covers the closed segment), outside -> :data:`HIDDEN`;
* a segment along an edge (both ends on it, up to round-off) is covered: :data:`VISIBLE`;
* a segment that starts on an edge (a UAV flying along the fence, up to round-off) and ends
  more than ``margin_m`` inside that edge's line moves steadily away from it: if the rest of
  the boundary is clear of it and its midpoint is inside, :data:`VISIBLE`;
* otherwise, if some point of the segment lies outside the fence and more than ``margin_m``
  from every edge, the segment leaves the grown fence: :data:`HIDDEN`. Candidates are b and
  the midpoints between a, the places where the segment crosses the edges' lines, and b.

Everything else (segments that graze an edge, e.g. from within 1 mm of a vertex) is
:data:`UNKNOWN` and goes to ``covers``. Round-off in these formulas is ~1e-12 m for
coordinates of kilometres, nine orders below the 1 mm margin, so a certain answer is the
predicate's answer; the test suite checks them against ``covers`` on many random segments in
concave fences with holes.

Plain Python that numba compiles (``skymule.sim.batch_paths``); it also runs uncompiled.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

VISIBLE, HIDDEN, UNKNOWN = 1, 0, -1

#: Clearance [m] from every fence edge that makes an answer certain: far above round-off, far
#: below any distance that matters to a flight.
MARGIN_M = 1e-3

#: Fences with more edges than this keep shapely's test: the certificate scans every edge
#: (~4 ns each), the prepared ``covers`` test takes ~1-1.6 us whatever the fence (measured
#: on random star-shaped fences: 256 edges 1.1 vs 1.7 us per segment, 512 edges 2.2 vs 1.6).
MAX_EDGES = 256

#: A start this close to an edge [m] is on it: a UAV flying along the fence (round-off only).
ON_EDGE_M = 1e-9


def fence_edges(fence: Polygon) -> np.ndarray:
    """(E, 4) edges x0, y0, x1, y1 of every ring of ``fence`` (exterior and holes) [m],
    oriented so that the fence's inside is on the left of each edge."""
    fence = orient(fence, sign=1.0)  # exterior counter-clockwise, holes clockwise
    parts = []
    for ring in (fence.exterior, *fence.interiors):
        xy = shapely.get_coordinates(ring)
        parts.append(np.hstack([xy[:-1], xy[1:]]))
    return np.ascontiguousarray(np.concatenate(parts), float)


def _point_segment_distance2(
    px: float, py: float, x0: float, y0: float, x1: float, y1: float
) -> float:
    """Squared distance from point p to the segment (x0, y0) -> (x1, y1) [m^2]."""
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy
    t = 0.0
    if length2 > 0.0:
        t = min(1.0, max(0.0, ((px - x0) * dx + (py - y0) * dy) / length2))
    ex, ey = px - (x0 + t * dx), py - (y0 + t * dy)
    return ex * ex + ey * ey


def _segments_apart(
    ax: float,
    ay: float,
    bx: float,
    by: float,
    x0: float,
    y0: float,
    x1: float,
    y1: float,
    margin_m: float,
    reach: float,
) -> bool:
    """True only if segment ab and the edge (x0, y0) -> (x1, y1) are more than ``margin_m``
    apart. ``reach``: ``margin_m * |ab|`` (the sides below are scaled by |ab|)."""
    ux, uy = bx - ax, by - ay
    side_0 = ux * (y0 - ay) - uy * (x0 - ax)
    side_1 = ux * (y1 - ay) - uy * (x1 - ax)
    # the usual case: the whole edge lies on one side of the segment's line, beyond the margin
    if (side_0 > reach and side_1 > reach) or (side_0 < -reach and side_1 < -reach):
        return True
    vx, vy = x1 - x0, y1 - y0
    edge_reach = margin_m * math.hypot(vx, vy)
    side_a = vx * (ay - y0) - vy * (ax - x0)
    side_b = vx * (by - y0) - vy * (bx - x0)
    if (side_a > edge_reach and side_b > edge_reach) or (
        side_a < -edge_reach and side_b < -edge_reach
    ):
        return True
    margin2 = margin_m * margin_m
    if (
        _point_segment_distance2(ax, ay, x0, y0, x1, y1) <= margin2
        or _point_segment_distance2(bx, by, x0, y0, x1, y1) <= margin2
        or _point_segment_distance2(x0, y0, ax, ay, bx, by) <= margin2
        or _point_segment_distance2(x1, y1, ax, ay, bx, by) <= margin2
    ):
        return False
    # every endpoint is clear of the other segment: apart unless they cross (an X)
    return not ((side_0 > 0.0) != (side_1 > 0.0) and (side_a > 0.0) != (side_b > 0.0))


def _clear_of_edges(px: float, py: float, edges: np.ndarray, margin_m: float) -> bool:
    """True if p is more than ``margin_m`` from every edge."""
    margin2 = margin_m * margin_m
    for e in range(edges.shape[0]):
        x0, y0, x1, y1 = edges[e, 0], edges[e, 1], edges[e, 2], edges[e, 3]
        if _point_segment_distance2(px, py, x0, y0, x1, y1) <= margin2:
            return False
    return True


def _inside(px: float, py: float, edges: np.ndarray) -> bool:
    """The even-odd rule (a ray toward +x): True if p is inside the fence (p off the edges)."""
    inside = False
    for e in range(edges.shape[0]):
        x0, y0, x1, y1 = edges[e, 0], edges[e, 1], edges[e, 2], edges[e, 3]
        if (y0 > py) != (y1 > py) and px < x0 + (py - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def _certainly_outside(px: float, py: float, edges: np.ndarray, margin_m: float) -> bool:
    return _clear_of_edges(px, py, edges, margin_m) and not _inside(px, py, edges)


def _hidden_or_unknown(
    ax: float, ay: float, bx: float, by: float, edges: np.ndarray, margin_m: float, t: np.ndarray
) -> int:
    """:data:`HIDDEN` if b, or a point of ab halfway between a (or a crossing of an edge's
    line) and the next crossing along ab, is certainly outside the fence; else
    :data:`UNKNOWN`.
    ``t``: scratch (E,)."""
    if _certainly_outside(bx, by, edges, margin_m):
        return HIDDEN
    ux, uy = bx - ax, by - ay
    n = 0
    for e in range(edges.shape[0]):
        x0, y0, x1, y1 = edges[e, 0], edges[e, 1], edges[e, 2], edges[e, 3]
        side_0 = ux * (y0 - ay) - uy * (x0 - ax)
        side_1 = ux * (y1 - ay) - uy * (x1 - ax)
        if (side_0 > 0.0) == (side_1 > 0.0):
            continue
        vx, vy = x1 - x0, y1 - y0
        denominator = ux * vy - uy * vx
        if denominator == 0.0:
            continue
        along = ((x0 - ax) * vy - (y0 - ay) * vx) / denominator
        if 0.0 < along < 1.0:
            t[n] = along
            n += 1
    for i in range(-1, n):  # -1: from a (a may lie on an edge itself)
        after = 0.0 if i < 0 else t[i]
        following = 1.0
        for j in range(n):
            if after < t[j] < following:
                following = t[j]
        middle = 0.5 * (after + following)
        if _certainly_outside(ax + middle * ux, ay + middle * uy, edges, margin_m):
            return HIDDEN
    return UNKNOWN


def segment_visibility(
    ax: float, ay: float, bx: float, by: float, edges: np.ndarray, margin_m: float, t: np.ndarray
) -> int:
    """:data:`VISIBLE`, :data:`HIDDEN` or :data:`UNKNOWN` for the segment a -> b (a != b).

    An edge with an endpoint at a (a fence vertex) meets the segment only at a if b and the
    edge's other end are clear of the edge and of the segment (two lines through a cross only
    there); likewise at b. Such edges are the only ones the midpoint may be near.
    ``t``: scratch (E,).
    """
    margin2 = margin_m * margin_m
    middle_x, middle_y = 0.5 * (ax + bx), 0.5 * (ay + by)
    from_edge = False
    ux, uy = bx - ax, by - ay
    reach = margin_m * math.hypot(ux, uy)
    for e in range(edges.shape[0]):
        x0, y0, x1, y1 = edges[e, 0], edges[e, 1], edges[e, 2], edges[e, 3]
        # most edges lie on one side of the segment's line, beyond the margin (never one
        # with an end at a or b: such an end is on the line, exactly)
        side_0 = ux * (y0 - ay) - uy * (x0 - ax)
        side_1 = ux * (y1 - ay) - uy * (x1 - ax)
        if (side_0 > reach and side_1 > reach) or (side_0 < -reach and side_1 < -reach):
            continue
        at_a_0, at_a_1 = ax == x0 and ay == y0, ax == x1 and ay == y1
        at_b_0, at_b_1 = bx == x0 and by == y0, bx == x1 and by == y1
        if (at_a_0 or at_a_1) and (at_b_0 or at_b_1):
            return VISIBLE  # the segment is the edge
        if at_a_0 or at_a_1 or at_b_0 or at_b_1:
            # p: the segment's end away from the vertex; q: the edge's end away from it
            px, py = (bx, by) if at_a_0 or at_a_1 else (ax, ay)
            qx, qy = (x1, y1) if at_a_0 or at_b_0 else (x0, y0)
            clear = (
                _point_segment_distance2(px, py, x0, y0, x1, y1) > margin2
                and _point_segment_distance2(qx, qy, ax, ay, bx, by) > margin2
                and _point_segment_distance2(middle_x, middle_y, x0, y0, x1, y1) > margin2
            )
        else:
            clear = _segments_apart(ax, ay, bx, by, x0, y0, x1, y1, margin_m, reach)
            if not clear and not from_edge:
                from_edge = clear = _leaves_edge_inward(ax, ay, bx, by, x0, y0, x1, y1, margin_m)
        if not clear:
            if _along_edge(ax, ay, bx, by, x0, y0, x1, y1):
                return VISIBLE
            return _hidden_or_unknown(ax, ay, bx, by, edges, margin_m, t)
    # the open segment does not meet the boundary: inside or outside as its midpoint, which is
    # clear of every edge (of the others because the whole segment is)
    if _inside(middle_x, middle_y, edges):
        return VISIBLE
    return UNKNOWN if from_edge else HIDDEN


def _along_edge(
    ax: float, ay: float, bx: float, by: float, x0: float, y0: float, x1: float, y1: float
) -> bool:
    """True if a and b both lie on the edge (within :data:`ON_EDGE_M`): then so does every
    point between them (the distance to a segment is convex), and the fence grown by 1e-6 m
    covers the segment (a UAV flying along the fence toward a vertex)."""
    on2 = ON_EDGE_M * ON_EDGE_M
    return (
        _point_segment_distance2(ax, ay, x0, y0, x1, y1) <= on2
        and _point_segment_distance2(bx, by, x0, y0, x1, y1) <= on2
    )


def _leaves_edge_inward(
    ax: float,
    ay: float,
    bx: float,
    by: float,
    x0: float,
    y0: float,
    x1: float,
    y1: float,
    margin_m: float,
) -> bool:
    """True if a lies on the edge (within :data:`ON_EDGE_M`) and b is more than ``margin_m``
    inside its line: the segment then moves steadily away from the edge into the fence (the
    rest of the boundary must be clear of it, which the caller checks), so the fence grown by
    1e-6 m covers it although it starts on the boundary."""
    if _point_segment_distance2(ax, ay, x0, y0, x1, y1) > ON_EDGE_M * ON_EDGE_M:
        return False
    vx, vy = x1 - x0, y1 - y0
    return vx * (by - y0) - vy * (bx - x0) > margin_m * math.hypot(vx, vy)


def classify_segments(
    a: np.ndarray, b: np.ndarray, edges: np.ndarray, margin_m: float, out: np.ndarray
) -> None:
    """``out`` (P,): :func:`segment_visibility` of P segments ``a`` (P, 2) -> ``b`` (P, 2);
    a == b is :data:`VISIBLE` (the navigator's rule)."""
    scratch = np.empty(edges.shape[0])
    for p in range(a.shape[0]):
        ax, ay, bx, by = a[p, 0], a[p, 1], b[p, 0], b[p, 1]
        if ax == bx and ay == by:
            out[p] = VISIBLE
        else:
            out[p] = segment_visibility(ax, ay, bx, by, edges, margin_m, scratch)


def first_seen(
    rows: np.ndarray,
    from_rank: np.ndarray,
    start: np.ndarray,
    order: np.ndarray,
    row_min: np.ndarray,
    d_s: np.ndarray,
    vertices: np.ndarray,
    edges: np.ndarray,
    margin_m: float,
    certify: bool,
    first: np.ndarray,
    unknown_rank: np.ndarray,
) -> None:
    """The first vertex each start sees, in its ``order`` (R, k), from rank ``from_rank``.

    For each of the C rows ``rows`` (into ``start`` (R, 2), ``order``, ``row_min`` and
    ``d_s`` (R, k) of ``path_kernels.rank_vertices``): ``first[row]`` becomes the first vertex
    of finite total that the start sees (or stands on), and ``unknown_rank`` (C,) -1; where
    the certificate cannot tell before a vertex is seen, ``unknown_rank`` is that rank (the
    caller asks ``covers`` and goes on from the next rank; every time when ``certify`` is
    False).
    """
    scratch = np.empty(edges.shape[0])
    for i in range(rows.shape[0]):
        r = rows[i]
        unknown_rank[i] = -1
        for rank in range(from_rank[i], order.shape[1]):
            v = order[r, rank]
            if not row_min[r, v] < math.inf:
                break  # the totals are in order: no later vertex has a path either
            if d_s[r, v] == 0.0:
                first[r] = v
                break
            answer = UNKNOWN
            if certify:
                answer = segment_visibility(
                    start[r, 0], start[r, 1], vertices[v, 0], vertices[v, 1], edges, margin_m,
                    scratch,
                )  # fmt: skip
            if answer == VISIBLE:
                first[r] = v
                break
            if answer == UNKNOWN:
                unknown_rank[i] = rank
                break
