"""The navigator's batched path queries with the arithmetic compiled (numba, ``fast`` extra).

The batched autonomous engine moves its UAVs with :meth:`Navigator.steps` and measures tours
and the way home with :meth:`Navigator.travel_distances`. Both pay numpy's per-call overhead
on a few dozen small arrays per query. :class:`CompiledPaths` answers the same queries, row
for row the same floats: the visibility predicate (shapely ``covers`` against the
navigator's prepared cover polygon) is answered by a compiled certificate where it is certain
(:mod:`skymule.sim.visibility_kernels`: segments clear of the fence's edges, ~99 % of those
the engine asks about) and by shapely for the rest, on the segments the numpy methods also
test (the direct segment, then the start's view of the vertices in order of their smallest
total, one rank at a time until one is seen: the numpy method tests three ranks, then every
vertex of the rows left, and both pick the first vertex seen in that order, so the same
path), and everything else runs in the compiled loops of :mod:`skymule.sim.path_kernels`.

``tests/test_batch_paths.py`` compares it with the navigator's methods on random queries, and
the compiled engine with the numpy engine on the batched autonomous engine's test cases.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import Any, Protocol

import numpy as np

from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator, goal_sights, step_lengths, vertex_sights
from skymule.sim import compiled
from skymule.sim import path_kernels as pk
from skymule.sim import visibility_kernels as vk

#: Longest route [vertices] the kernels sum as ``np.sum`` does (numpy's summation block, 128
#: values, minus the start and goal segments): larger fences keep the numpy path.
MAX_ROUTE = 120

Sight = tuple[np.ndarray, np.ndarray]


class Paths(Protocol):
    """What the batched autonomous engine asks of a navigator (:class:`Navigator` or
    :class:`CompiledPaths`)."""

    def sights(self, points_xy: np.ndarray) -> Sight: ...

    def steps(
        self,
        positions_xy: np.ndarray,
        goals_xy: np.ndarray,
        max_step_m: np.ndarray | float,
        goal_sight: Sight | None = None,
        checked: bool = True,
    ) -> np.ndarray: ...

    def travel_distances(
        self,
        starts_xy: np.ndarray,
        goals_xy: np.ndarray,
        goal_sight: Sight | None = None,
        checked: bool = True,
    ) -> np.ndarray: ...


def supports(navigator: Navigator) -> bool:
    """True if :class:`CompiledPaths` can answer for ``navigator`` (routes of at most
    :data:`MAX_ROUTE` vertices)."""
    return len(navigator.vertices) <= MAX_ROUTE


KERNELS = (
    pk.rank_vertices,
    pk.pick_routes,
    pk.advance_rows,
    pk.path_lengths,
    vk.classify_segments,
    vk.first_seen,
)
"""The compiled entry points of :mod:`~skymule.sim.path_kernels` and
:mod:`~skymule.sim.visibility_kernels` (plain Python functions numba compiles)."""


def _plain_kernels() -> dict[str, Callable[..., Any]]:
    """The kernels as plain Python (``CompiledPaths(..., plain=True)``: the tests run the
    compiled twin's code without numba)."""
    return {function.__name__: function for function in KERNELS}


@cache
def _kernels() -> dict[str, Callable[..., Any]]:
    """The kernels of :mod:`~skymule.sim.path_kernels` compiled, once per process (cached on
    disk by :func:`skymule.sim.compiled.jit`)."""
    helpers = (
        pk._path_point,
        pk._path_size,
        vk._point_segment_distance2,
        vk._segments_apart,
        vk._clear_of_edges,
        vk._inside,
        vk._certainly_outside,
        vk._hidden_or_unknown,
        vk._leaves_edge_inward,
        vk._along_edge,
        vk.segment_visibility,
    )
    return {function.__name__: compiled.jit(function, helpers) for function in KERNELS}


def path_queries(navigator: Navigator, engine: str, context: str = "") -> Paths:
    """The navigator's batched path queries for an engine choice: :class:`CompiledPaths` (the
    same floats) for ``"compiled"``, or ``"auto"`` when numba is installed and the fence is
    small enough (:func:`supports`); the navigator itself for ``"numpy"``; ``"plain"`` (for
    tests): the compiled twin's kernels run as plain Python. A bad or impossible choice is a
    one-line SkymuleError (prefixed with ``context``)."""
    if engine == "plain":
        return CompiledPaths(navigator, plain=True)
    compiled.check_engine(engine, context)
    usable = compiled.available() and supports(navigator)
    if engine == "compiled" and not usable:
        why = "numba is not installed" if not compiled.available() else "the fence is too large"
        raise SkymuleError(f"{context}engine = 'compiled' cannot run this batch: {why}")
    if engine == "compiled" or (engine == "auto" and usable):
        return CompiledPaths(navigator)
    return navigator


class CompiledPaths:
    """:meth:`Navigator.steps` and :meth:`Navigator.travel_distances` of one navigator, with
    the arithmetic in compiled loops (needs numba; :func:`supports` the navigator).
    ``plain=True`` runs the same loops as plain Python (slow; the tests' check without numba)."""

    def __init__(self, navigator: Navigator, plain: bool = False) -> None:
        self._nav = navigator
        self._vertices = navigator.vertices
        # the navigator's graph tables (read only): all-pairs distances and vertex routes
        self._dist = np.ascontiguousarray(navigator.vertex_graph_m, float)
        nodes, count = navigator.vertex_routes
        self._nodes, self._count = np.ascontiguousarray(nodes), np.ascontiguousarray(count)
        self._edges = vk.fence_edges(navigator.fence)
        self._certify = len(self._edges) <= vk.MAX_EDGES
        self._k = _plain_kernels() if plain else _kernels()

    def segments_visible(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(P,) :meth:`Navigator.segments_visible`: segments clear of the fence's edges
        answered by :mod:`~skymule.sim.visibility_kernels`, the rest by ``covers``."""
        if not self._certify:
            return self._nav.segments_visible(a, b)
        a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
        answer = np.empty(len(a), np.int8)
        self._k["classify_segments"](a, b, self._edges, vk.MARGIN_M, answer)
        visible = answer == vk.VISIBLE
        unknown = np.flatnonzero(answer == vk.UNKNOWN)
        if unknown.size:
            visible[unknown] = self._nav.segments_visible(a[unknown], b[unknown])
        return visible

    def _routes(
        self, starts: np.ndarray, goals: np.ndarray, goal_sight: Sight | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(P,) row among the bending paths or -1, then first and last route vertex of
        each bending path: the choices of ``Navigator.shortest_paths``."""
        nav = self._nav
        direct = self.segments_visible(starts, goals)
        rest = np.flatnonzero(~direct)
        bend = np.full(len(starts), -1, np.int64)
        bend[rest] = np.arange(rest.size)
        first = np.full(rest.size, -1, np.int64)
        last = np.zeros(rest.size, np.int64)
        if not rest.size:
            return bend, first, last
        k = len(self._vertices)
        if not k:
            raise ValueError("no in-fence path between start and goal")
        vis_g, d_g = goal_sights(self.sights, goals, rest, goal_sight)
        start = np.ascontiguousarray(starts[rest])
        d_s = np.empty((rest.size, k))
        row_min = np.empty((rest.size, k))
        order = np.empty((rest.size, k), np.int64)
        vis_g, d_g = np.ascontiguousarray(vis_g), np.ascontiguousarray(d_g)
        self._k["rank_vertices"](start, vis_g, d_g, self._vertices, self._dist, d_s, row_min, order)
        # the start's view of the vertices in order of their smallest total, rank by rank
        # (Navigator.shortest_paths: three ranks, then every vertex at once): the first seen
        # is the minimiser's first vertex either way, and most rows stop within a few ranks;
        # shapely decides where the certificate cannot, and those rows go on from there
        rows = np.arange(rest.size)
        from_rank = np.zeros(rest.size, np.int64)
        while rows.size:
            unknown = np.empty(rows.size, np.int64)
            self._k["first_seen"](
                rows, from_rank, start, order, row_min, d_s, self._vertices, self._edges,
                vk.MARGIN_M, self._certify, first, unknown,
            )  # fmt: skip
            stuck = unknown >= 0
            rows, from_rank = rows[stuck], unknown[stuck]
            if rows.size:
                vertex = order[rows, from_rank]
                seen = nav.segments_visible(start[rows], self._vertices[vertex])
                first[rows[seen]] = vertex[seen]
                rows, from_rank = rows[~seen], from_rank[~seen] + 1
        found = self._k["pick_routes"](first, d_s, vis_g, d_g, self._dist, last)
        if not found:
            raise ValueError("no in-fence path between start and goal")
        return bend, first, last

    def _query(
        self, starts_xy: np.ndarray, goals_xy: np.ndarray, goal_sight: Sight | None, checked: bool
    ) -> tuple[np.ndarray, ...]:
        """Starts and goals (P, 2) as contiguous floats (checked inside the fence if asked),
        then :meth:`_routes` of them: what both path queries start from."""
        starts = np.ascontiguousarray(starts_xy, float).reshape(-1, 2)
        goals = np.ascontiguousarray(goals_xy, float).reshape(-1, 2)
        if checked:
            self._nav.check_inside(starts, goals)
        return (starts, goals, *self._routes(starts, goals, goal_sight))

    def sights(self, points_xy: np.ndarray) -> Sight:
        """(P, k) :meth:`Navigator.sights`, by :meth:`segments_visible`."""
        return vertex_sights(points_xy, self._vertices, self.segments_visible)

    def steps(
        self,
        positions_xy: np.ndarray,
        goals_xy: np.ndarray,
        max_step_m: np.ndarray | float,
        goal_sight: Sight | None = None,
        checked: bool = True,
    ) -> np.ndarray:
        """(P, 2) :meth:`Navigator.steps`, float for float."""
        starts, goals, bend, first, last = self._query(positions_xy, goals_xy, goal_sight, checked)
        step = step_lengths(max_step_m, len(starts))
        moved = np.empty_like(starts)
        self._k["advance_rows"](
            starts, goals, step, bend, first, last, self._nodes, self._count, self._vertices, moved
        )
        return moved

    def travel_distances(
        self,
        starts_xy: np.ndarray,
        goals_xy: np.ndarray,
        goal_sight: Sight | None = None,
        checked: bool = True,
    ) -> np.ndarray:
        """(P,) :meth:`Navigator.travel_distances` [m], float for float."""
        starts, goals, bend, first, last = self._query(starts_xy, goals_xy, goal_sight, checked)
        out = np.empty(len(starts))
        self._k["path_lengths"](
            starts, goals, bend, first, last, self._nodes, self._count, self._vertices, out
        )
        return out
