"""Random mission layouts for studies over many missions (benchmarks, validity checks).

:func:`random_autonomous_scenario` draws a flyable autonomous scenario around a base
scenario's geofence: a home point inside the fence, sensors anywhere within ``margin_m`` of
it (outside the fence too, like LW4), buffers, mission length and speed. Every draw comes
from the ``rng`` passed in, so a seeded generator reproduces the same layouts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import Point

from skymule.errors import ScenarioError, SkymuleError
from skymule.scenario import Scenario
from skymule.world import build_mission


@dataclass(frozen=True)
class LayoutRanges:
    """Ranges the random layouts are drawn from (uniform; integer ranges include both ends).

    Attributes:
        n_sensors: (low, high) number of sensors.
        buffer_mbit: (low, high) buffer per sensor [Mbit].
        height_m: (low, high) antenna height [m].
        duration_s: (low, high) mission time [s] (whole seconds).
        max_speed_mps: (low, high) UAV speed cap [m/s].
        margin_m: sensors fall within this distance of the fence's bounding box [m].
        return_home_probability: chance that ``return_home`` is set.
        draw_seed: also draw the scenario's ``seed`` (for shadowing/fading studies).
    """

    n_sensors: tuple[int, int] = (3, 6)
    buffer_mbit: tuple[float, float] = (300.0, 1500.0)
    height_m: tuple[float, float] = (0.0, 20.0)
    duration_s: tuple[int, int] = (200, 450)
    max_speed_mps: tuple[float, float] = (6.0, 12.0)
    margin_m: float = 300.0
    return_home_probability: float = 1.0
    draw_seed: bool = False


def _draw(rng: np.random.Generator, base: Scenario, ranges: LayoutRanges) -> Scenario:
    fence = build_mission(base).fence
    if fence is None:
        raise SkymuleError(
            f"scenario {base.name!r}: random layouts need a geofence (site.geofence)"
        )
    minx, miny, maxx, maxy = fence.bounds
    inner = fence.buffer(-2.0)
    while True:
        home = rng.uniform([minx, miny], [maxx, maxy])
        if inner.covers(Point(home)):
            break
    count = int(rng.integers(ranges.n_sensors[0], ranges.n_sensors[1] + 1))
    margin = ranges.margin_m
    sensors = [
        base.sensors[0].model_copy(
            update={
                "name": f"S{k + 1}",
                "lat": None,
                "lon": None,
                "x_m": float(rng.uniform(minx - margin, maxx + margin)),
                "y_m": float(rng.uniform(miny - margin, maxy + margin)),
                "height_m": float(rng.uniform(*ranges.height_m)),
                "buffer_mbit": float(rng.uniform(*ranges.buffer_mbit)),
            }
        )
        for k in range(count)
    ]
    duration_s = float(rng.integers(ranges.duration_s[0], ranges.duration_s[1] + 1))
    trajectory = {
        "home": [float(home[0]), float(home[1])],
        "max_speed_mps": float(rng.uniform(*ranges.max_speed_mps)),
    }
    if ranges.return_home_probability < 1.0:
        trajectory["return_home"] = bool(rng.random() < ranges.return_home_probability)
    update: dict[str, object] = {
        "sensors": sensors,
        "mission": base.mission.model_copy(update={"duration_s": duration_s}),
        "trajectory": base.trajectory.model_copy(update=trajectory),
    }
    if ranges.draw_seed:
        update["seed"] = int(rng.integers(1 << 30))
    return base.model_copy(update=update)


def random_autonomous_scenario(
    rng: np.random.Generator, base: Scenario, ranges: LayoutRanges = LayoutRanges()
) -> Scenario:
    """A random autonomous scenario around ``base``'s geofence that is long enough to fly.

    Layouts whose mission is too short to reach the nearest hover point and return are
    redrawn (the engine would reject them).
    """
    while True:
        scenario = _draw(rng, base, ranges)
        try:
            build_mission(scenario)  # rejects missions too short to fly
        except ScenarioError:
            continue
        return scenario
