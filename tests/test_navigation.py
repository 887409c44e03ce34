"""Tests for skymule.flight.navigation (in-fence shortest paths, stepping, hover points)."""

from __future__ import annotations

import itertools
import json
import math
from importlib import resources

import numpy as np
import pyproj
import pytest
from shapely.geometry import Point, Polygon
from shapely.ops import nearest_points

from skymule.flight.navigation import (
    Navigator,
    hover_point,
    path_length,
    shortest_path,
)

# U-shaped fence: a 30 m x 30 m square with a 10 m wide notch cut from the top (x 10..20,
# y 10..30).  Reflex corners at (10, 10) and (20, 10).
U_FENCE = Polygon([(0, 0), (30, 0), (30, 30), (20, 30), (20, 10), (10, 10), (10, 30), (0, 30)])
U_START = (5.0, 25.0)
U_GOAL = (25.0, 25.0)
# Around the notch: (5,25) -> (10,10) -> (20,10) -> (25,25).
U_LENGTH = 2.0 * math.hypot(5.0, 15.0) + 10.0

TOL = 1e-6


def _dense_points(path: list[tuple[float, float]], spacing_m: float = 0.05) -> np.ndarray:
    """Points every ``spacing_m`` along a polyline (including all vertices), shape (m, 2)."""
    pts = [np.asarray(path[0], dtype=float)]
    for a, b in itertools.pairwise(path):
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n = max(2, math.ceil(np.hypot(*(b - a)) / spacing_m) + 1)
        t = np.linspace(0.0, 1.0, n)[1:, None]
        pts.extend(a + t * (b - a))
    return np.asarray(pts)


def _assert_inside(fence: Polygon, path: list[tuple[float, float]], spacing_m: float) -> None:
    cover = fence.buffer(TOL)
    for x, y in _dense_points(path, spacing_m):
        assert cover.covers(Point(x, y)), (x, y)


# --------------------------------------------------------------------------- shortest path


def test_u_shape_straight_line_leaves_fence() -> None:
    from shapely.geometry import LineString

    assert not U_FENCE.buffer(TOL).covers(LineString([U_START, U_GOAL]))


def test_u_shape_path_goes_round_the_notch() -> None:
    path = shortest_path(U_FENCE, U_START, U_GOAL)
    assert path[0] == U_START and path[-1] == U_GOAL
    expected = [U_START, (10.0, 10.0), (20.0, 10.0), U_GOAL]
    np.testing.assert_allclose(path, expected, atol=1e-12)
    assert path_length(path) == pytest.approx(U_LENGTH, abs=1e-9)
    _assert_inside(U_FENCE, path, spacing_m=0.01)


def test_straight_line_case_is_euclidean() -> None:
    nav = Navigator(U_FENCE)
    a, b = (2.0, 3.0), (28.0, 7.5)
    assert nav.shortest_path(a, b) == [a, b]
    assert nav.travel_distance(a, b) == pytest.approx(math.dist(a, b), abs=1e-12)


def test_one_corner_path() -> None:
    # From the left arm down to the bottom bar, right of the notch: bends only at (10, 10).
    nav = Navigator(U_FENCE)
    a, b = (5.0, 29.0), (19.0, 2.0)
    expected = math.dist(a, (10.0, 10.0)) + math.dist((10.0, 10.0), b)
    np.testing.assert_allclose(nav.shortest_path(a, b), [a, (10.0, 10.0), b], atol=1e-12)
    assert nav.travel_distance(a, b) == pytest.approx(expected, abs=1e-9)


def test_path_around_hole() -> None:
    outer = [(0, 0), (40, 0), (40, 40), (0, 40)]
    hole = [(10, 10), (30, 10), (30, 30), (10, 30)]
    fence = Polygon(outer, [hole])
    a, b = (20.0, 5.0), (20.0, 35.0)
    path = shortest_path(fence, a, b)
    # Round one side of the hole: (20,5)->(10,10)->(10,30)->(20,35), or mirror image.
    expected = 2.0 * math.hypot(10.0, 5.0) + 20.0
    assert path_length(path) == pytest.approx(expected, abs=1e-9)
    _assert_inside(fence, path, spacing_m=0.05)
    for x, y in _dense_points(path, 0.05):
        assert not Polygon(hole).contains(Point(x, y))


def test_goal_outside_raises() -> None:
    nav = Navigator(U_FENCE)
    with pytest.raises(ValueError, match="goal"):
        nav.shortest_path(U_START, (31.0, 5.0))
    with pytest.raises(ValueError, match="goal"):
        nav.travel_distance(U_START, (15.0, 25.0))  # inside the notch = outside the fence


def test_a_start_outside_first_flies_to_the_nearest_fence_point() -> None:
    # a GPS reading in the notch, 3 m from its right edge: in at (20, 25), then on to the goal
    nav = Navigator(U_FENCE)
    outside = (17.0, 25.0)
    assert nav.entry_point(outside) == pytest.approx((20.0, 25.0))
    assert nav.entry_point(U_START) == U_START  # inside: unchanged
    path = nav.shortest_path(outside, U_GOAL)
    assert path[0] == outside and np.allclose(path[1:], [(20.0, 25.0), U_GOAL])
    assert nav.travel_distance(outside, U_GOAL) == pytest.approx(3.0 + 5.0)
    assert nav.step(outside, U_GOAL, 2.0) == pytest.approx((19.0, 25.0))  # still on the way in
    assert nav.step(outside, U_GOAL, 4.0) == pytest.approx((21.0, 25.0))
    # just beyond the outer edge: in at (25, 0), to the notch's corner (10, 10), up to (5, 25)
    below = (25.0, -0.5)
    assert nav.travel_distance(below, U_START) == pytest.approx(
        0.5 + math.hypot(15.0, 10.0) + math.hypot(5.0, 15.0)
    )
    corners = nav.vertices
    expected = [0.5 + nav.travel_distance((25.0, 0.0), tuple(c)) for c in corners]
    assert np.allclose(nav.vertex_distances(below), expected)


def test_start_equals_goal() -> None:
    nav = Navigator(U_FENCE)
    assert nav.travel_distance(U_START, U_START) == 0.0
    assert nav.step(U_START, U_START, 3.0) == U_START


def test_path_symmetry_and_triangle_inequality() -> None:
    nav = Navigator(U_FENCE)
    pts = [(5.0, 25.0), (25.0, 25.0), (15.0, 5.0), (2.0, 12.0), (28.0, 29.0)]
    for a in pts:
        for b in pts:
            d_ab = nav.travel_distance(a, b)
            assert d_ab == pytest.approx(nav.travel_distance(b, a), abs=1e-9)
            assert d_ab >= math.dist(a, b) - 1e-9
            for c in pts:
                assert d_ab <= nav.travel_distance(a, c) + nav.travel_distance(c, b) + 1e-9


# --------------------------------------------------------------------------- polyline helpers


def test_path_length_and_steps_along_a_bent_path() -> None:
    """A step moves its length along the in-fence path, bends included; a goal within reach
    is reached exactly."""
    assert path_length([(0.0, 0.0), (3.0, 4.0), (3.0, 10.0)]) == pytest.approx(11.0)
    assert path_length([(1.0, 1.0)]) == 0.0
    nav = Navigator(U_FENCE)  # (5, 25) -> (10, 10) -> (20, 10) -> (25, 25) round the notch
    first = math.hypot(5.0, 15.0)
    starts, goals = np.array([U_START] * 4), np.array([U_GOAL] * 4)
    moved = nav.steps(starts, goals, np.array([2.5, first, first + 4.0, 50.0]))
    t = 2.5 / first
    np.testing.assert_allclose(moved[0], (5.0 + 5.0 * t, 25.0 - 15.0 * t), atol=1e-12)
    np.testing.assert_allclose(moved[1], (10.0, 10.0), atol=1e-12)  # exactly at the bend
    np.testing.assert_allclose(moved[2], (14.0, 10.0), atol=1e-12)
    assert tuple(moved[3]) == U_GOAL


# --------------------------------------------------------------------------- stepping


@pytest.mark.parametrize("max_step", [0.7, 3.0, 4.4, 11.0])
def test_repeated_steps_reach_goal(max_step: float) -> None:
    nav = Navigator(U_FENCE)
    cover = U_FENCE.buffer(TOL)
    length = nav.travel_distance(U_START, U_GOAL)
    expected_steps = math.ceil(length / max_step)
    pos = U_START
    steps = 0
    while pos != U_GOAL:
        new = nav.step(pos, U_GOAL, max_step)
        assert math.dist(pos, new) <= max_step + 1e-9
        assert nav.travel_distance(U_START, new) <= max_step * (steps + 1) + 1e-9
        assert cover.covers(Point(new))
        pos = new
        steps += 1
        assert steps <= expected_steps
    assert steps == expected_steps


def test_step_returns_goal_exactly_when_within_reach() -> None:
    nav = Navigator(U_FENCE)
    goal = (7.0, 8.0)
    assert nav.step((6.0, 7.0), goal, 5.0) == goal


def test_navigator_is_frozen() -> None:
    nav = Navigator(U_FENCE)
    with pytest.raises(AttributeError):
        nav.fence = U_FENCE  # type: ignore[misc]


# --------------------------------------------------------------------------- hover point


def test_hover_inside_with_clearance_unchanged() -> None:
    assert hover_point(U_FENCE, (5.0, 20.0), margin_m=1.0) == (5.0, 20.0)


def test_hover_inside_near_boundary_gets_margin() -> None:
    assert hover_point(U_FENCE, (15.0, 0.5), margin_m=1.0) == pytest.approx((15.0, 1.0))


@pytest.mark.parametrize(
    ("sensor", "expected"),
    [
        ((15.0, -5.0), (15.0, 1.0)),  # below the bottom edge
        ((14.0, 25.0), (9.0, 25.0)),  # inside the notch, nearer its left wall
        ((40.0, 12.0), (29.0, 12.0)),  # right of the fence
    ],
)
def test_hover_outside_facing_edge(sensor: tuple[float, float], expected: tuple) -> None:
    margin = 1.0
    hover = hover_point(U_FENCE, sensor, margin_m=margin)
    nearest = nearest_points(U_FENCE, Point(sensor))[0]
    assert hover == pytest.approx(expected, abs=1e-9)
    assert U_FENCE.contains(Point(hover))
    # The hover point is the nearest fence point nudged margin_m inward.
    assert math.dist(hover, (nearest.x, nearest.y)) == pytest.approx(margin, abs=1e-9)
    assert math.dist(sensor, hover) == pytest.approx(
        U_FENCE.distance(Point(sensor)) + margin, abs=1e-9
    )


def test_hover_outside_corner() -> None:
    sensor = (-3.0, -4.0)
    hover = hover_point(U_FENCE, sensor, margin_m=1.0)
    nearest = nearest_points(U_FENCE, Point(sensor))[0]
    assert (nearest.x, nearest.y) == pytest.approx((0.0, 0.0))
    assert hover == pytest.approx((1.0, 1.0), abs=1e-6)
    assert U_FENCE.contains(Point(hover))


# --------------------------------------------------------------------------- Lake Wheeler


@pytest.fixture(scope="module")
def lake_wheeler_fence() -> Polygon:
    text = resources.files("skymule").joinpath("data/lake_wheeler.geojson").read_text()
    features = json.loads(text)["features"]
    (geofence,) = [f for f in features if f["properties"].get("kind") == "geofence"]
    lonlat = np.asarray(geofence["geometry"]["coordinates"][0], dtype=float)
    proj = pyproj.Proj(proj="aeqd", lat_0=35.7274824, lon_0=-78.6962749, datum="WGS84")
    x, y = proj(lonlat[:, 0], lonlat[:, 1])
    fence = Polygon(np.column_stack([x, y]))
    assert fence.is_valid
    return fence


def _random_inside(fence: Polygon, rng: np.random.Generator, n: int) -> list:
    minx, miny, maxx, maxy = fence.bounds
    out: list[tuple[float, float]] = []
    while len(out) < n:
        x, y = rng.uniform(minx, maxx), rng.uniform(miny, maxy)
        if fence.contains(Point(x, y)):
            out.append((float(x), float(y)))
    return out


def test_lake_wheeler_fence_is_concave(lake_wheeler_fence: Polygon) -> None:
    assert lake_wheeler_fence.area < 0.95 * lake_wheeler_fence.convex_hull.area
    assert len(Navigator(lake_wheeler_fence).vertices) > 0


def test_lake_wheeler_random_paths_stay_inside(lake_wheeler_fence: Polygon) -> None:
    fence = lake_wheeler_fence
    nav = Navigator(fence)
    rng = np.random.default_rng(20240521)
    pts = _random_inside(fence, rng, 80)
    bent = 0
    for start, goal in zip(pts[0::2], pts[1::2], strict=True):
        path = nav.shortest_path(start, goal)
        assert path[0] == start and path[-1] == goal
        bent += len(path) > 2
        _assert_inside(fence, path, spacing_m=1.0)
        length = path_length(path)
        assert length >= math.dist(start, goal) - 1e-9
        assert length == pytest.approx(nav.travel_distance(goal, start), abs=1e-6)
    assert bent > 0  # some pairs must actually need to go round a corner


def test_lake_wheeler_steps_stay_inside(lake_wheeler_fence: Polygon) -> None:
    fence = lake_wheeler_fence
    cover = fence.buffer(TOL)
    nav = Navigator(fence)
    rng = np.random.default_rng(7)
    pts = _random_inside(fence, rng, 10)
    for start, goal in zip(pts[0::2], pts[1::2], strict=True):
        max_step = 37.0
        n_expected = math.ceil(nav.travel_distance(start, goal) / max_step)
        pos, steps = start, 0
        while pos != goal:
            new = nav.step(pos, goal, max_step)
            assert math.dist(pos, new) <= max_step + 1e-9
            assert cover.covers(Point(new))
            pos, steps = new, steps + 1
            assert steps <= n_expected + 1
        assert steps in (n_expected, n_expected + 1)  # +1 only for float ties at k*step


def test_lake_wheeler_hover_points(lake_wheeler_fence: Polygon) -> None:
    fence = lake_wheeler_fence
    rng = np.random.default_rng(3)
    minx, miny, maxx, maxy = fence.bounds
    margin = 2.0
    for _ in range(40):
        sensor = (rng.uniform(minx - 200, maxx + 200), rng.uniform(miny - 200, maxy + 200))
        hover = hover_point(fence, sensor, margin_m=margin)
        assert fence.buffer(TOL).covers(Point(hover))
        d_fence = fence.distance(Point(sensor))
        d_hover = math.dist(sensor, hover)
        assert d_fence - 1e-9 <= d_hover <= d_fence + 4.0 * margin + 1e-9
        if not fence.contains(Point(sensor)):
            nearest = nearest_points(fence, Point(sensor))[0]
            assert math.dist(hover, (nearest.x, nearest.y)) <= 4.0 * margin + 1e-9
