"""Validity of the fixed-trajectory bound: no simulated policy ever downloads more.

A seeded generator draws random Lake Wheeler missions: 1-4 sensors inside the geofence
(shapely rejection sampling), buffers 50..1500 Mbit, 50..400 s, a random fixed path of
waypoints inside the fence, and either a propagation-model source (free space, sometimes with
shadowing) or a recorded trace (a small digital-twin export written into ``tmp_path``, shorter
or longer than the mission). Greedy, HGAD (thresholds 1.0 and 0.8) and optimal-fixed are run
through the reference engine; each total must stay within ``bound (1 + 1e-6)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from skymule.bounds.fixed import mission_track_rates
from skymule.bounds.mission import mission_bound
from skymule.geo import LocalFrame, load_geofence
from skymule.io.traces import write_dt_export
from skymule.policies import HGAD, Greedy, Policy
from skymule.policies.optimal_fixed import OptimalFixed
from skymule.scenario import Scenario
from skymule.sim.run import run_mission
from skymule.world import Mission, build_mission

N_MISSIONS = 30  # per signal source
REL_TOL = 1e-6
ORIGIN = {"lat": 35.7274824, "lon": -78.6962749}


@pytest.fixture(scope="module")
def fence() -> Polygon:
    return load_geofence("lake-wheeler", LocalFrame(ORIGIN["lat"], ORIGIN["lon"]))


def points_inside(rng: np.random.Generator, fence: Polygon, n: int) -> np.ndarray:
    """(n, 2) uniform points inside the polygon [m] (rejection sampling on its bounds)."""
    x0, y0, x1, y1 = fence.bounds
    found = np.zeros((0, 2))
    while len(found) < n:
        cand = rng.uniform((x0, y0), (x1, y1), size=(4 * n, 2))
        inside = shapely.contains_xy(fence.buffer(-1.0), cand[:, 0], cand[:, 1])
        found = np.vstack([found, cand[inside]])
    return found[:n]


def policies() -> list[Policy]:
    return [Greedy(), HGAD(1.0, 60.0), HGAD(0.8, 30.0), OptimalFixed()]


def check_no_policy_beats_the_bound(mission: Mission) -> bool:
    """Assert every policy <= bound; optimal-fixed within the slotting loss of it.

    Returns whether the bound is below the total buffer (time, not data, is binding).
    """
    bound = mission_bound(mission).upper_bound_bit
    totals = {}
    for policy in policies():
        got = float(run_mission(mission, policy).downloaded_bit.sum())
        assert got <= bound * (1 + REL_TOL) + 1e-6, (policy.name, got, bound)
        totals[policy.name] = got
    loss = mission_track_rates(mission)[: mission.n_slots].max(axis=0).sum() * mission.slot_s
    assert bound - totals["optimal-fixed"] <= loss + 1e-6
    return bound < mission.buffers_bit.sum() * (1 - 1e-6)


def sensors(rng: np.random.Generator, fence: Polygon, with_xy: bool) -> list[dict]:
    n = int(rng.integers(1, 5))
    xy = points_inside(rng, fence, n)
    specs = []
    for i in range(n):
        spec = {"name": f"S{i + 1}", "buffer_mbit": float(rng.uniform(50, 1500))}
        if with_xy:
            spec |= {"x_m": float(xy[i, 0]), "y_m": float(xy[i, 1]), "height_m": 10.0}
        specs.append(spec)
    return specs


def model_scenario(rng: np.random.Generator, fence: Polygon) -> Scenario:
    waypoints = points_inside(rng, fence, int(rng.integers(2, 6)))
    altitude = float(rng.uniform(20, 60))
    return Scenario.model_validate(
        {
            "name": "random-model",
            "seed": int(rng.integers(0, 2**31)),
            "mission": {"duration_s": float(rng.integers(50, 401))},
            "site": {"origin": ORIGIN, "geofence": "lake-wheeler"},
            "sensors": sensors(rng, fence, with_xy=True),
            "radio": {"shadowing_std_db": float(rng.choice([0.0, 0.0, 6.0]))},
            "trajectory": {
                "waypoints": [[x, y, altitude] for x, y in waypoints],
                "speed_mps": float(rng.uniform(5, 15)),
            },
            "policy": {"name": "hgad"},
        }
    )


def trace_scenario(rng: np.random.Generator, fence: Polygon, folder: Path) -> Scenario:
    specs = sensors(rng, fence, with_xy=False)
    n_samples = int(rng.integers(30, 300))
    corners = points_inside(rng, fence, 4)
    s = np.linspace(0, 3, n_samples)
    xy = np.column_stack([np.interp(s, np.arange(4), corners[:, j]) for j in range(2)])
    towers = points_inside(rng, fence, len(specs))
    dist = np.hypot(np.linalg.norm(xy[:, None] - towers[None], axis=2), 30.0)
    snr = 65.0 - 20 * np.log10(dist) + rng.normal(0, 3, dist.shape)
    snr[rng.uniform(size=snr.shape) < 0.03] = np.nan  # missing samples
    path = folder / "flight.csv"
    names = [spec["name"] for spec in specs]
    write_dt_export(path, np.arange(float(n_samples)), snr, names, xy[:, 0], xy[:, 1], 30 + s)
    duration = None if rng.uniform() < 0.4 else float(rng.integers(50, 401))
    return Scenario.model_validate(
        {
            "name": "random-trace",
            "mission": {"duration_s": duration},
            "site": {"origin": ORIGIN, "geofence": "lake-wheeler"},
            "sensors": specs,
            "signal": {"source": "trace", "trace": str(path)},
        }
    )


def test_model_source_missions(fence: Polygon) -> None:
    rng = np.random.default_rng(20240611)
    binding = [
        check_no_policy_beats_the_bound(build_mission(model_scenario(rng, fence)))
        for _ in range(N_MISSIONS)
    ]
    assert 0 < sum(binding) < N_MISSIONS  # both time-limited and data-limited missions


def test_trace_source_missions(fence: Polygon, tmp_path: Path) -> None:
    rng = np.random.default_rng(20240612)
    binding = []
    for index in range(N_MISSIONS):
        folder = tmp_path / f"m{index}"
        folder.mkdir()
        mission = build_mission(trace_scenario(rng, fence, folder))
        assert mission.track is not None and not mission.track.hold_at_end
        binding.append(check_no_policy_beats_the_bound(mission))
    assert 0 < sum(binding) < N_MISSIONS
