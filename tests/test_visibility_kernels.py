"""The certain answers of ``sim/visibility_kernels`` are the navigator's ``covers`` answers."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from conftest import preset_mission
from skymule.flight.navigation import Navigator
from skymule.sim import compiled
from skymule.sim import visibility_kernels as vk
from test_batch_autonomous import U_FENCE

#: a concave shell with a concave hole, a hole vertex on the shell's x range
HOLED = Polygon(
    [(0, 0), (400, 0), (400, 300), (250, 300), (250, 150), (200, 300), (0, 300)],
    [[(100, 100), (200, 100), (200, 200), (150, 120), (100, 200)]],
)


def fences() -> list[Polygon]:
    preset = preset_mission("paper-sim-autonomous").navigator
    assert preset is not None
    return [U_FENCE, preset.fence, HOLED]


def hard_segments(fence: Polygon, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """n segments: random ends in and around the fence, ends on the fence's vertices, on its
    edges, between vertices, along edges, and degenerate ones."""
    low, high = np.array(fence.bounds[:2]), np.array(fence.bounds[2:])
    pad = 0.05 * (high - low)
    a = rng.uniform(low - pad, high + pad, (n, 2))
    b = rng.uniform(low - pad, high + pad, (n, 2))
    vertices = shapely.get_coordinates(fence)
    edges = vk.fence_edges(fence)
    k = n // 8
    a[:k] = vertices[rng.integers(len(vertices), size=k)]
    b[k : 2 * k] = vertices[rng.integers(len(vertices), size=k)]
    on_edge = edges[rng.integers(len(edges), size=k)]
    share = rng.uniform(size=(k, 1))
    a[2 * k : 3 * k] = on_edge[:, :2] + share * (on_edge[:, 2:] - on_edge[:, :2])
    a[3 * k : 4 * k] = vertices[rng.integers(len(vertices), size=k)]
    b[3 * k : 4 * k] = vertices[rng.integers(len(vertices), size=k)]
    # along an edge, part of it, and just off it (1e-4 m: inside the margin)
    along = edges[rng.integers(len(edges), size=k)]
    a[4 * k : 5 * k] = along[:, :2]
    b[4 * k : 5 * k] = along[:, :2] + share * (along[:, 2:] - along[:, :2])
    b[4 * k : 4 * k + k // 2, 1] += 1e-4
    # points 1 mm and 2 mm inside an edge's middle, toward random goals
    middle = 0.5 * (along[:, :2] + along[:, 2:])
    a[5 * k : 6 * k] = middle + rng.choice([-2e-3, -1e-3, 1e-3, 2e-3], (k, 2))
    a[6 * k : 6 * k + 20] = b[6 * k : 6 * k + 20]  # a == b
    return a, b


def classify(a: np.ndarray, b: np.ndarray, edges: np.ndarray, compile_it: bool) -> np.ndarray:
    out = np.empty(len(a), np.int8)
    if compile_it:
        from skymule.sim.batch_paths import _kernels

        _kernels()["classify_segments"](a, b, edges, vk.MARGIN_M, out)
    else:
        vk.classify_segments(a, b, edges, vk.MARGIN_M, out)
    return out


@pytest.mark.parametrize(
    "compile_it",
    [
        False,
        pytest.param(
            True,
            marks=pytest.mark.skipif(not compiled.available(), reason="numba not installed"),
        ),
    ],
)
def test_certain_answers_equal_covers(compile_it):
    """Never a certain answer the exact predicate contradicts; most answers certain."""
    rng = np.random.default_rng(11)
    n = 40_000 if compile_it else 2_000
    for fence in fences():
        navigator = Navigator(fence)
        a, b = hard_segments(fence, n, rng)
        answer = classify(a, b, vk.fence_edges(fence), compile_it)
        exact = navigator.segments_visible(a, b)
        certain = answer != vk.UNKNOWN
        np.testing.assert_array_equal(answer[certain] == vk.VISIBLE, exact[certain])
        assert certain.mean() > 0.5
        assert (answer == vk.VISIBLE).any() and (answer == vk.HIDDEN).any()


def test_segments_to_vertices_are_answered():
    """Views of the fence's vertices from inside (what the navigator asks when a path bends):
    certain where they do not graze another edge, and right."""
    for fence in fences():
        navigator = Navigator(fence)
        vertices = shapely.get_coordinates(fence)
        rng = np.random.default_rng(3)
        low, high = np.array(fence.bounds[:2]), np.array(fence.bounds[2:])
        points = rng.uniform(low, high, (400, 2))
        points = points[navigator.covers_goals(points)][:100]
        a = np.repeat(points, len(vertices), axis=0)
        b = np.tile(vertices, (len(points), 1))
        answer = classify(a, b, vk.fence_edges(fence), False)
        exact = navigator.segments_visible(a, b)
        certain = answer != vk.UNKNOWN
        np.testing.assert_array_equal(answer[certain] == vk.VISIBLE, exact[certain])
        assert certain.mean() > 0.9
        assert (answer[exact] == vk.VISIBLE).mean() > 0.9


def test_segments_from_the_fence_edge_are_answered():
    """A UAV flying along the fence starts its segments on an edge (up to round-off): those
    leaving the edge into the fence are visible, those leaving it outward hidden, for certain."""
    rng = np.random.default_rng(8)
    for fence in fences():
        navigator = Navigator(fence)
        edges = vk.fence_edges(fence)
        low, high = np.array(fence.bounds[:2]), np.array(fence.bounds[2:])
        pick = edges[rng.integers(len(edges), size=600)]
        share = rng.uniform(0.2, 0.8, (600, 1))
        a = pick[:, :2] + share * (pick[:, 2:] - pick[:, :2])
        b = rng.uniform(low, high, (600, 2))
        answer = classify(a, b, edges, False)
        exact = navigator.segments_visible(a, b)
        certain = answer != vk.UNKNOWN
        np.testing.assert_array_equal(answer[certain] == vk.VISIBLE, exact[certain])
        assert certain[exact].mean() > 0.9 and certain[~exact].mean() > 0.9


def test_edges_of_every_ring():
    edges = vk.fence_edges(HOLED)
    assert edges.shape == (7 + 5, 4)
    np.testing.assert_array_equal(edges[0], [0, 0, 400, 0])
    np.testing.assert_array_equal(edges[7, :2], [100, 100])
