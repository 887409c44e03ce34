"""In-fence navigation for a UAV confined to a (possibly concave) geofence polygon.

All coordinates are local planar metres (x east, y north); distances are metres.

Shortest paths use the classical visibility-graph construction (Lozano-Pérez & Wesley,
"An algorithm for planning collision-free paths among polyhedral obstacles",
Commun. ACM 22(10), 1979; see also de Berg et al., *Computational Geometry*, ch. 15):
a shortest path inside a polygonal domain is a polyline whose interior bend points
are reflex vertices of the domain, so it suffices to search the graph whose nodes are
the reflex vertices plus the two endpoints and whose edges are the mutually visible
(segment covered by the domain) pairs.  The vertex-to-vertex part of that graph, and
its all-pairs shortest paths, are computed once per fence in :class:`Navigator`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import Point, Polygon
from shapely.geometry.polygon import orient
from shapely.ops import nearest_points

XY = tuple[float, float]

#: Outward tolerance (m) of the polygon used for segment-visibility tests, so that paths may
#: run along edges and graze reflex vertices despite floating-point round-off.
COVER_TOLERANCE_M = 1e-6

#: Cross-product threshold (m^2) below which a vertex is treated as collinear (not reflex).
_COLLINEAR_EPS = 1e-12

#: A hover point with reduced clearance is accepted only if it lies within this many
#: ``margin_m`` of the sensor's distance to the fence (see :func:`hover_point`).
_HOVER_DETOUR_MARGINS = 4.0

#: Number of times :func:`hover_point` halves the clearance before giving up on it.
_HOVER_HALVINGS = 10

#: :meth:`Navigator.shortest_paths` tests the start's view of this many vertices one at a time
#: (smallest total first) before testing all of them at once for the rows left.
_LAZY_RANKS = 3


def _as_xy(p: XY | np.ndarray) -> XY:
    return (float(p[0]), float(p[1]))


def hover_point(fence: Polygon, sensor_xy: XY, margin_m: float = 1.0) -> XY:
    """Where the UAV should hover to serve a sensor at ``sensor_xy``.

    Returns the point with clearance ``c`` from the fence boundary that is closest to the
    sensor, where ``c`` is the largest of ``margin_m, margin_m/2, margin_m/4, ...`` for
    which that point is no more than ``4 * margin_m`` farther from the sensor than the
    fence itself is.  Hence:

    * a sensor inside the fence with at least ``margin_m`` clearance is returned unchanged;
    * a sensor outside (or too close to the boundary) is mapped to the nearest in-fence
      point, nudged ``margin_m`` inward (exactly ``margin_m`` along the inward normal when
      the nearest boundary feature is an edge);
    * near sharp corners or thin necks the clearance is reduced so the hover point does
      not jump to a distant part of the fence.  If no clearance works the nearest point
      on the boundary itself is returned.

    Args:
        fence: geofence polygon, metres.
        sensor_xy: sensor position ``(x, y)``, metres.
        margin_m: desired clearance from the fence boundary, metres (``>= 0``).

    Returns:
        Hover position ``(x, y)`` in metres, covered by ``fence``.
    """
    if margin_m < 0:
        raise ValueError(f"margin_m must be >= 0, got {margin_m}")
    sensor = Point(sensor_xy)
    boundary_dist = fence.exterior.distance(sensor)
    for ring in fence.interiors:
        boundary_dist = min(boundary_dist, ring.distance(sensor))
    if fence.contains(sensor) and boundary_dist >= margin_m:
        return _as_xy(sensor_xy)

    nearest = nearest_points(fence, sensor)[0]
    allowed = fence.distance(sensor) + _HOVER_DETOUR_MARGINS * margin_m
    clearance = margin_m
    for _ in range(_HOVER_HALVINGS + 1):
        if clearance <= 0:
            break
        inset = fence.buffer(-clearance)
        if not inset.is_empty:
            candidate = nearest_points(inset, sensor)[0]
            if candidate.distance(sensor) <= allowed and fence.contains(candidate):
                return (candidate.x, candidate.y)
        clearance /= 2.0
    return (nearest.x, nearest.y)


def step_lengths(max_step_m: np.ndarray | float, n: int) -> np.ndarray:
    """(n,) writable step lengths [m] from a scalar or (n,) ``max_step_m``; ValueError if any
    is negative."""
    steps = np.array(np.broadcast_to(np.asarray(max_step_m, float), (n,)))
    if np.any(steps < 0):
        raise ValueError(f"max_step_m must be >= 0, got {steps.min()}")
    return steps


def path_length(path: list[XY] | np.ndarray) -> float:
    """Total Euclidean length (m) of a polyline given as a sequence of ``(x, y)`` points."""
    pts = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(pts) < 2:
        return 0.0
    return float(np.hypot(*np.diff(pts, axis=0).T).sum())


def _ring_reflex_vertices(coords: np.ndarray) -> np.ndarray:
    """Reflex vertices, shape (k, 2), of a closed ring oriented with the domain on its left."""
    pts = coords[:-1]
    if len(pts) < 3:
        return np.empty((0, 2))
    prev = np.roll(pts, 1, axis=0)
    nxt = np.roll(pts, -1, axis=0)
    a = pts - prev
    b = nxt - pts
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return pts[cross < -_COLLINEAR_EPS]


def reflex_vertices(fence: Polygon) -> np.ndarray:
    """Vertices (m), shape (k, 2), at which the fence's interior angle exceeds 180°.

    These are the reflex corners of the outer ring and the convex corners of any holes:
    the only points at which a shortest in-fence path can bend.
    """
    oriented = orient(fence, sign=1.0)  # exterior CCW, holes CW: domain always on the left
    rings = [oriented.exterior, *oriented.interiors]
    parts = [_ring_reflex_vertices(np.asarray(r.coords)[:, :2]) for r in rings]
    return np.concatenate(parts, axis=0) if parts else np.empty((0, 2))


@dataclass(frozen=True)
class Navigator:
    """Shortest-path navigation inside one geofence, with the vertex graph cached.

    The reflex vertices, their pairwise visibility and all-pairs shortest distances are
    computed once in ``__post_init__``; each query then only tests visibility from the
    two endpoints to those vertices (vectorised shapely ``covers``) and minimises
    ``|s - i| + D[i, j] + |j - g|`` over visible vertex pairs with numpy.

    Attributes:
        fence: geofence polygon in local metres.
    """

    fence: Polygon
    _cover: Polygon = field(init=False, repr=False, compare=False)
    _goal_cover: Polygon = field(init=False, repr=False, compare=False)
    _vertices: np.ndarray = field(init=False, repr=False, compare=False)
    _dist: np.ndarray = field(init=False, repr=False, compare=False)
    _pred: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.fence, Polygon) or self.fence.is_empty:
            raise ValueError("fence must be a non-empty shapely Polygon")
        if not self.fence.is_valid:
            raise ValueError("fence polygon is not valid")
        cover = self.fence.buffer(COVER_TOLERANCE_M, join_style="mitre")
        shapely.prepare(cover)
        verts = reflex_vertices(self.fence)
        n = len(verts)
        weights = np.full((n, n), np.inf)
        if n:
            ii, jj = np.triu_indices(n, k=1)
            segs = np.stack([verts[ii], verts[jj]], axis=1)
            visible = np.asarray(shapely.covers(cover, shapely.linestrings(segs)), dtype=bool)
            lengths = np.hypot(*(verts[jj] - verts[ii]).T)
            weights[ii[visible], jj[visible]] = lengths[visible]
            weights[jj[visible], ii[visible]] = lengths[visible]
            # scipy.sparse.csgraph costs ~0.2 s to import: only concave fences get here
            from scipy.sparse.csgraph import csgraph_from_dense
            from scipy.sparse.csgraph import shortest_path as _csgraph_shortest_path

            graph = csgraph_from_dense(weights, null_value=np.inf)
            dist, pred = _csgraph_shortest_path(
                graph, method="D", directed=False, return_predecessors=True
            )
        else:
            dist, pred = np.empty((0, 0)), np.empty((0, 0), dtype=np.int32)
        # the fence grown by 1e-6 m (round joins), prepared once: goals are tested every slot
        goal_cover = self.fence.buffer(1e-6)
        shapely.prepare(goal_cover)
        object.__setattr__(self, "_cover", cover)
        object.__setattr__(self, "_goal_cover", goal_cover)
        object.__setattr__(self, "_vertices", verts)
        object.__setattr__(self, "_dist", dist)
        object.__setattr__(self, "_pred", pred)

    @property
    def vertices(self) -> np.ndarray:
        """Reflex vertices used as graph nodes, shape (k, 2), metres (read-only copy)."""
        return self._vertices.copy()

    @cached_property
    def fence_key(self) -> bytes:
        """The fence as WKB: equal for navigators of the same fence (to group missions)."""
        return bytes(shapely.to_wkb(self.fence))

    @property
    def vertex_graph_m(self) -> np.ndarray:
        """(k, k) all-pairs in-fence distances [m] between the graph vertices (read only)."""
        view = self._dist.view()
        view.flags.writeable = False
        return view

    def in_cover(self, points_xy: np.ndarray) -> np.ndarray:
        """(P,) True where a point is inside the fence (within ``COVER_TOLERANCE_M``)."""
        xy = np.asarray(points_xy, float).reshape(-1, 2)
        return np.asarray(shapely.intersects_xy(self._cover, xy[:, 0], xy[:, 1]), bool)

    def check_inside(self, starts: np.ndarray, goals: np.ndarray) -> None:
        """ValueError naming the first start or goal (P, 2) outside the fence, if any."""
        for name, xy in (("start", starts), ("goal", goals)):
            outside = ~self.in_cover(xy)
            if outside.any():
                raise ValueError(f"{name} {_as_xy(xy[np.argmax(outside)])} is outside the fence")

    def covers_goals(self, points_xy: np.ndarray) -> np.ndarray:
        """(P,) True where a point (P, 2) is inside the fence (within 1e-6 m): goals the UAV may
        fly to (for a point, "covered" and "intersects" are the same)."""
        p = np.asarray(points_xy, float).reshape(-1, 2)
        return np.asarray(shapely.intersects_xy(self._goal_cover, p[:, 0], p[:, 1]), bool)

    def entry_point(self, xy: XY) -> XY:
        """``xy`` itself when inside the fence (within 1e-6 m), else the nearest fence point.

        A start outside the fence is normal: a GPS reading near the fence's edge may lie just
        beyond it, and a policy plans from what it reads. Paths from such a start first fly
        straight to this point (the shortest way back in), then on inside the fence.
        """
        point = _as_xy(xy)
        if shapely.intersects_xy(self._cover, point[0], point[1]):
            return point
        return _as_xy(nearest_points(self.fence, Point(point))[0].coords[0])

    def shortest_path(self, start_xy: XY, goal_xy: XY) -> list[XY]:
        """Shortest in-fence polyline ``[start, ..., goal]`` (metres): one row of
        :meth:`shortest_paths`.

        A start outside the fence is accepted: the path first runs straight to the nearest
        fence point (:meth:`entry_point`), so it reads ``[start, entry, ..., goal]``.

        Raises:
            ValueError: if the goal is outside the fence or no path exists.
        """
        points, count = self.shortest_paths(np.array([start_xy], float), np.array([goal_xy], float))
        return [_as_xy(point) for point in points[0, : int(count[0])]]

    def vertex_distances(self, xy: XY) -> np.ndarray:
        """(k,) shortest in-fence travel distance (m) from ``xy`` to each graph vertex.

        In the order of :attr:`vertices`; ``inf`` where a vertex cannot be reached.

        A point outside the fence counts the straight way in to :meth:`entry_point`.
        """
        point = _as_xy(xy)
        entry = self.entry_point(point)
        if entry != point:
            return math.dist(point, entry) + self.vertex_distances(entry)
        if not len(self._vertices):
            return np.empty(0)
        vis, d = self.sights(np.array([point], float))
        return np.asarray(np.min(np.where(vis[0], d[0], np.inf)[:, None] + self._dist, axis=0))

    # --- the same queries for many (start, goal) pairs at once (the batched autonomous
    # engine); each equals the scalar method row by row, float for float -----------------

    @cached_property
    def vertex_routes(self) -> tuple[np.ndarray, np.ndarray]:
        """(k, k, k) vertex indices of the route i -> j (padded with j), (k, k) their count."""
        n = len(self._vertices)
        nodes = np.zeros((n, n, max(n, 1)), np.int64)
        count = np.zeros((n, n), np.int64)
        for i in range(n):
            for j in range(n):
                if not np.isfinite(self._dist[i, j]):
                    continue
                route = [j]
                while route[-1] != i:
                    route.append(int(self._pred[i, route[-1]]))
                nodes[i, j, :] = j
                nodes[i, j, : len(route)] = route[::-1]
                count[i, j] = len(route)
        return nodes, count

    def sights(self, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P, k) which graph vertices each of P points sees, and (P, k) distances [m] to them.

        Row p equals the scalar visibility test from ``points_xy[p]`` (one vectorised
        ``covers`` call); pass it as ``goal_sight`` to the methods below for goals used often.
        """
        return vertex_sights(points_xy, self._vertices, self.segments_visible)

    def segments_visible(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(P,) the scalar segment test for P segments a -> b (one ``covers`` call)."""
        same = (a[:, 0] == b[:, 0]) & (a[:, 1] == b[:, 1])
        visible = same.copy()
        rows = np.flatnonzero(~same)
        if rows.size:
            lines = shapely.linestrings(np.stack([a[rows], b[rows]], axis=1))
            visible[rows] = shapely.covers(self._cover, lines)
        return visible

    def shortest_paths(
        self,
        starts_xy: np.ndarray,
        goals_xy: np.ndarray,
        goal_sight: tuple[np.ndarray, np.ndarray] | None = None,
        checked: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """P shortest paths at once: (P, L, 2) points padded with the goal, (P,) point counts.

        Row p holds exactly the points of ``shortest_path(starts_xy[p], goals_xy[p])``. Where
        the start sees the vertex of the smallest total, that is the scalar method's minimiser
        (ties: lowest vertex pair) without testing the others. ``goal_sight``: (P, k)
        :meth:`sights` of the goals, if known. ``checked=False`` skips the test that every
        point is inside the fence (for callers whose points are by construction). Raises
        ValueError where no path exists.
        """
        starts = np.asarray(starts_xy, float).reshape(-1, 2)
        goals = np.asarray(goals_xy, float).reshape(-1, 2)
        if checked:
            outside = ~self.in_cover(goals)
            if outside.any():
                raise ValueError(f"goal {_as_xy(goals[np.argmax(outside)])} is outside the fence")
            outside = np.flatnonzero(~self.in_cover(starts))
            if outside.size:
                return self._paths_in(starts, goals, outside, goal_sight)
        direct = self.segments_visible(starts, goals)
        rest = np.flatnonzero(~direct)
        if not rest.size:
            return np.stack([starts, goals], axis=1), np.full(len(starts), 2, np.int64)
        if not len(self._vertices):
            raise ValueError("no in-fence path between start and goal")
        vis_g, d_g = goal_sights(self.sights, goals, rest, goal_sight)
        verts, start = self._vertices, starts[rest]
        d_s = np.hypot(verts[None, :, 0] - start[:, None, 0], verts[None, :, 1] - start[:, None, 1])
        total = d_s[:, :, None] + self._dist[None] + np.where(vis_g, d_g, np.inf)[:, None, :]
        row_min = total.min(axis=2)
        rows = np.arange(rest.size)
        order = np.argsort(row_min, axis=1, kind="stable")  # ties: the lower vertex first
        first = np.full(rest.size, -1, np.int64)
        # most paths bend at one of the vertices of the smallest totals: test those first,
        # nearest first, then the few rows left against every vertex at once
        for rank in range(min(_LAZY_RANKS, len(verts))):
            todo = np.flatnonzero(first < 0)
            if not todo.size:
                break
            vertex = order[todo, rank]
            seen = self.segments_visible(start[todo], verts[vertex]) | (d_s[todo, vertex] == 0)
            seen &= np.isfinite(row_min[todo, vertex])
            first[todo[seen]] = vertex[seen]
        last = np.argmin(total[rows, np.maximum(first, 0)], axis=1)
        todo = np.flatnonzero(first < 0)
        if todo.size:
            masked = np.where(self.sights(start[todo])[0][:, :, None], total[todo], np.inf)
            flat = np.argmin(masked.reshape(todo.size, -1), axis=1)
            first[todo], last[todo] = np.divmod(flat, len(verts))
        if not np.all(np.isfinite(total[rows, first, last])):
            raise ValueError("no in-fence path between start and goal")
        route_nodes, route_count = self.vertex_routes
        count = np.full(len(starts), 2, np.int64)
        count[rest] += route_count[first, last]
        points = np.repeat(goals[:, None, :], int(count.max()), axis=1)
        points[:, 0] = starts
        # row r: start, route vertices, goal (already in the padding)
        hops = route_nodes[first, last][:, : int(count.max()) - 2]
        inner = np.arange(hops.shape[1])[None, :] < route_count[first, last][:, None]
        rows, cols = np.nonzero(inner)
        points[rest[rows], cols + 1] = verts[hops[rows, cols]]
        return points, count

    def _paths_in(
        self,
        starts: np.ndarray,
        goals: np.ndarray,
        outside: np.ndarray,
        goal_sight: tuple[np.ndarray, np.ndarray] | None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`shortest_paths` where starts ``outside`` lie outside the fence: those first
        fly straight to the nearest fence point (:meth:`entry_point`), then on inside."""
        inner = starts.copy()
        lines = shapely.shortest_line(self.fence, shapely.points(starts[outside]))
        inner[outside] = shapely.get_coordinates(shapely.get_point(lines, 0))
        points, count = self.shortest_paths(inner, goals, goal_sight, checked=False)
        out = np.concatenate([points, goals[:, None, :]], axis=1)  # one more point of padding
        out[outside, 1:] = points[outside]
        out[outside, 0] = starts[outside]
        count[outside] += 1
        return out, count

    def travel_distances(
        self,
        starts_xy: np.ndarray,
        goals_xy: np.ndarray,
        goal_sight: tuple[np.ndarray, np.ndarray] | None = None,
        checked: bool = True,
    ) -> np.ndarray:
        """(P,) :meth:`travel_distance` of P (start, goal) pairs [m], float for float."""
        points, count = self.shortest_paths(starts_xy, goals_xy, goal_sight, checked)
        diff = np.diff(points, axis=1)
        lengths = np.hypot(diff[..., 0], diff[..., 1])
        if lengths.shape[1] == 1:
            return lengths[:, 0]
        out = np.empty(len(count))
        for n in np.unique(count):  # path_length sums one row at a time (pairwise summation)
            rows = np.flatnonzero(count == n)
            out[rows] = np.sum(lengths[rows, : n - 1], axis=1)
        return out

    def steps(
        self,
        positions_xy: np.ndarray,
        goals_xy: np.ndarray,
        max_step_m: np.ndarray | float,
        goal_sight: tuple[np.ndarray, np.ndarray] | None = None,
        checked: bool = True,
    ) -> np.ndarray:
        """(P, 2) :meth:`step` of P (position, goal) pairs, each with its own step [m]."""
        points, count = self.shortest_paths(positions_xy, goals_xy, goal_sight, checked)
        left = step_lengths(max_step_m, len(count))
        moved = points[np.arange(len(count)), count - 1].copy()  # the goal, if reached
        placed = np.zeros(len(count), bool)
        for seg in range(points.shape[1] - 1):  # one segment for all rows at a time
            rows = np.flatnonzero(~placed & (seg < count - 1))
            if not rows.size:
                break
            a, b = points[rows, seg], points[rows, seg + 1]
            dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
            length = np.hypot(dx, dy)
            short = left[rows] < length
            at = rows[short]
            t = left[at] / length[short]
            moved[at, 0] = a[short, 0] + t * dx[short]
            moved[at, 1] = a[short, 1] + t * dy[short]
            placed[at] = True
            left[rows[~short]] -= length[~short]
        return moved

    def travel_distance(self, a_xy: XY, b_xy: XY) -> float:
        """Length (m) of the shortest in-fence path from ``a_xy`` to ``b_xy`` (from outside
        the fence: the straight way in to :meth:`entry_point` plus the path on from there):
        one row of :meth:`travel_distances`."""
        return float(self.travel_distances(np.array([a_xy], float), np.array([b_xy], float))[0])

    def step(self, position_xy: XY, goal_xy: XY, max_step_m: float) -> XY:
        """New position after flying at most ``max_step_m`` metres toward ``goal_xy`` along
        the shortest in-fence path (from outside the fence, first the straight way in):
        one row of :meth:`steps`. Exactly ``goal_xy`` when it is within ``max_step_m``."""
        moved = self.steps(np.array([position_xy], float), np.array([goal_xy], float), max_step_m)
        return _as_xy(moved[0])


def goal_sights(
    sights: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    goals: np.ndarray,
    rows: np.ndarray,
    known: tuple[np.ndarray, np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray]:
    """(R, k) sights of ``goals[rows]``: from ``known`` (P, k) each where given, by
    ``sights`` for the rest (all of them without ``known``; else the rows whose distances are
    NaN, which are then written into ``known`` in place, so that a caller keeping the arrays
    computes a goal's sight once)."""
    if known is None:
        return sights(goals[rows])
    vis, dist = known
    if dist.shape[1]:
        unknown = rows[np.isnan(dist[rows, 0])]
        if unknown.size:
            vis[unknown], dist[unknown] = sights(goals[unknown])
    return vis[rows], dist[rows]


def vertex_sights(
    points_xy: np.ndarray,
    vertices: np.ndarray,
    segments_visible: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """(P, k) which of k ``vertices`` each of P points sees by ``segments_visible`` (a
    navigator's segment test), and (P, k) distances [m] to them."""
    p = np.asarray(points_xy, float).reshape(-1, 2)
    d = np.hypot(vertices[None, :, 0] - p[:, None, 0], vertices[None, :, 1] - p[:, None, 1])
    starts = np.repeat(p, len(vertices), axis=0)
    ends = np.tile(vertices, (len(p), 1))
    vis = segments_visible(starts, ends).reshape(d.shape)
    return vis | (d == 0.0), d


def shortest_path(fence: Polygon, start_xy: XY, goal_xy: XY) -> list[XY]:
    """Shortest polyline ``[start, ..., goal]`` (metres) from start to goal inside ``fence``.

    Convenience wrapper that builds a :class:`Navigator`; reuse a ``Navigator`` for many
    queries on the same fence.

    Raises:
        ValueError: if the goal lies outside the fence (a start outside first flies in).
    """
    return Navigator(fence).shortest_path(start_xy, goal_xy)
