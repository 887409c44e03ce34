"""DataMuleVectorEnv: step for step the single environments (each the same engine core with
one mission), on the concave Lake Wheeler fence, faults included."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Point

pytest.importorskip("gymnasium")

from skymule.envs.datamule import DataMuleEnv
from skymule.envs.vector import DataMuleVectorEnv
from skymule.errors import SkymuleError
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.scenario import load_scenario, scenario_from_dict
from skymule.sim import compiled
from skymule.sim.autonomous import legal_goals
from skymule.sim.batch_signal import BatchSignal
from skymule.world import Mission, build_mission, with_fence

PRESET = "paper-sim-autonomous"
SHORT = LayoutRanges(n_sensors=(4, 4), duration_s=(30, 50), return_home_probability=0.5)
NEEDS_NUMBA = pytest.mark.skipif(not compiled.available(), reason="numba is not installed")


def preset(*overrides: str) -> Mission:
    return build_mission(load_scenario(PRESET, overrides))


def at(mission: Mission, home: np.ndarray) -> Mission:
    """``mission`` taking off from ``home`` (a corner of the fence, say)."""
    return replace(mission, home_m=np.asarray(home, float))


def mixed_missions() -> list[Mission]:
    """Missions of one concave fence with every kind of difference the vector env allows."""
    base = load_scenario(PRESET)
    rng = np.random.default_rng(7)
    layouts = [build_mission(random_autonomous_scenario(rng, base, SHORT)) for _ in range(4)]
    fence = layouts[0].fence
    assert fence is not None
    ring = np.asarray(fence.exterior.coords)[:-1]
    reflex = layouts[0].navigator.vertices if layouts[0].navigator is not None else ring
    short = "mission.duration_s=40"
    return [
        *layouts,
        preset(short),
        preset("mission.duration_s=45", "trajectory.return_home=false"),
        at(preset(short), ring[0]),  # at the fence's corners: headings push outside at once
        at(preset("mission.duration_s=35", "trajectory.return_home=false"), ring[len(ring) // 2]),
        at(preset(short, "trajectory.max_speed_mps=17"), reflex[0]),  # a reflex corner
        preset(short, "radio.shadowing_std_db=6", "seed=3"),
        preset(short, "radio.fading=rician", "seed=4"),
        preset(short, "radio.fading=rayleigh", "radio.shadowing_std_db=4", "seed=5"),
        preset(short, "radio.model=two-ray", "radio.tx_power_dbm=20"),
        preset("mission.duration_s=60", "radio.model=3gpp-uma-av", "trajectory.altitude_m=60"),
        preset("mission.duration_s=50", "radio.rate_table=shannon", "mission.aadm_window_s=20"),
        faulty(short, "seed=6"),
    ]


def faulty(*overrides: str) -> Mission:
    """The preset with every kind of fault at once (wind and battery included)."""
    base = load_scenario(PRESET, overrides)
    data = base.to_toml_dict()
    data["faults"] = [
        {"kind": "outage", "params": {"mean_duration_s": 20.0}},
        {"kind": "snr-error", "params": {"std_db": 4.0}},
        {"kind": "gps-error", "params": {"std_m": 5.0}},
        {"kind": "wind", "params": {"speed_mps": 4.0, "from_deg": 45.0}},
        {"kind": "battery", "params": {"capacity_wh": 4.0}},
    ]
    return build_mission(scenario_from_dict(data, "faulty", Path(base.base_dir)))


def actions(rng: np.random.Generator, heading: np.ndarray, n_sensors: int) -> np.ndarray:
    """Random serves; headings kept for a while (so UAVs reach and push into the fence)."""
    change = rng.random(heading.size) < 0.15
    heading[change] = rng.integers(0, 9, int(change.sum()))
    return np.column_stack([rng.integers(0, n_sensors + 1, heading.size), heading])


@pytest.mark.parametrize(
    ("reward", "engine"), [("mbit", "numpy"), pytest.param("aadm", "compiled", marks=NEEDS_NUMBA)]
)
def test_vector_env_equals_single_envs_step_for_step(reward: str, engine: str) -> None:
    missions = mixed_missions()
    count = len(missions)
    vector = DataMuleVectorEnv(missions, reward=reward, engine=engine)  # type: ignore[arg-type]
    singles = [DataMuleEnv(m, reward=reward) for m in missions]
    observations, _ = vector.reset(seed=0)
    assert np.array_equal(observations, np.array([env.reset(seed=0)[0] for env in singles]))
    rng = np.random.default_rng(1)
    heading = np.zeros(count, np.int64)
    ended = np.zeros(count, int)
    ends: list[list[np.ndarray]] = [[] for _ in missions]
    on_edge = 0
    for _ in range(125):  # twice past the longest mission (60 slots): autoresets included
        action = actions(rng, heading, 4)
        observations, rewards, terminated, truncated, _ = vector.step(action)
        assert not truncated.any()
        for index, env in enumerate(singles):
            if env._done:  # gymnasium's next-step autoreset: a reset, reward 0
                expected, _ = env.reset()
                reward_expected, done = 0.0, False
            else:
                expected, reward_expected, done, _, _ = env.step(action[index])
            np.testing.assert_array_equal(observations[index], expected)
            assert rewards[index] == pytest.approx(reward_expected, rel=1e-12, abs=1e-12)
            assert terminated[index] == done
            assert env._core is not None
            assert tuple(vector.position_m[index]) == tuple(env._core.engine.position[0])
            if done:
                ends[index].append(vector.position_m[index].copy())
        fence = missions[0].fence
        assert fence is not None
        on_edge += sum(fence.exterior.distance(Point(p)) < 1e-6 for p in vector.position_m)
        ended += terminated
    assert (ended >= 2).all()
    assert on_edge > 20  # the fence stopped UAVs (goals outside moved onto it)
    at_home = [
        [bool(np.allclose(p, mission.home_m, atol=1e-6)) for p in where]
        for mission, where in zip(missions, ends, strict=True)
    ]
    # the override brought every UAV that must return home in time; the others roam
    assert all(all(home) for home, m in zip(at_home, missions, strict=True) if m.return_home)
    assert not all(all(h) for h, m in zip(at_home, missions, strict=True) if not m.return_home)


def test_engines_step_alike_and_a_bad_engine_is_one_clear_error() -> None:
    missions = mixed_missions()[:6]
    envs = [DataMuleVectorEnv(missions, engine=engine) for engine in ("numpy", "auto")]
    for env in envs:
        env.reset()
    rng = np.random.default_rng(3)
    heading = np.zeros(len(missions), np.int64)
    for _ in range(80):
        action = actions(rng, heading, 4)
        numpy_step, auto_step = (env.step(action) for env in envs)
        np.testing.assert_array_equal(numpy_step[0], auto_step[0])
        np.testing.assert_array_equal(envs[0].position_m, envs[1].position_m)
    with pytest.raises(SkymuleError, match="engine = 'fast'; allowed: auto, numpy, compiled"):
        DataMuleVectorEnv(missions, engine="fast")  # type: ignore[arg-type]


def test_legal_goals_keep_goals_in_the_fence_and_move_the_others_onto_it() -> None:
    navigator = preset().navigator
    assert navigator is not None
    fence = navigator.fence
    rng = np.random.default_rng(5)
    ring = np.asarray(fence.exterior.coords)[:-1]
    x0, y0, x1, y1 = fence.bounds
    goals = np.concatenate([
        rng.uniform((x0 - 300, y0 - 300), (x1 + 300, y1 + 300), (400, 2)),  # in and out
        ring + rng.normal(0.0, 20.0, ring.shape),  # around the corners (concave ones too)
        ring + rng.choice([-1.0, 1.0], ring.shape) * 5e-7,  # within the engine's tolerance
    ])  # fmt: skip
    legal = legal_goals(navigator, goals)
    moved = np.any(legal != goals, axis=1)
    assert 50 < moved.sum() < len(goals) - 50
    covered = navigator.covers_goals(goals)
    assert not moved[covered].any()  # a goal the fence covers is kept, float for float
    for goal, point in zip(goals[moved], legal[moved], strict=True):  # the nearest fence point
        assert fence.exterior.distance(Point(point)) < 1e-9
        assert np.hypot(*(goal - point)) == pytest.approx(fence.distance(Point(goal)), abs=1e-9)


def test_per_mission_slots_give_each_mission_its_own_fading() -> None:
    missions = [preset("radio.fading=rician", f"seed={s}", f"mission.duration_s={t}")
                for s, t in ((1, 20), (2, 30))]  # fmt: skip
    missions.append(preset("mission.duration_s=10"))  # no fading
    signal = BatchSignal(missions, 4)
    rng = np.random.default_rng(0)
    position = rng.uniform(-200, 200, (3, 2))
    slots = np.array([3, 30, 7])  # mission 1 is past its last slot (the longest): no fading
    snr = signal.snr_db(position, slots)
    plain = signal.snr_db(position, None)
    np.testing.assert_array_equal(snr[:, 0], signal.snr_db(position, 3)[:, 0])
    np.testing.assert_array_equal(snr[:, 1:], plain[:, 1:])
    assert not np.array_equal(snr[:, 0], plain[:, 0])
    fading = missions[0].fading_db
    assert fading is not None
    np.testing.assert_allclose(snr[:, 0] - plain[:, 0], fading[3], atol=1e-9)


def test_vector_env_refuses_what_it_cannot_step(tmp_path: Path) -> None:
    with pytest.raises(SkymuleError, match=r"mission 0 .* not supported: it is not autonomous"):
        DataMuleVectorEnv(["paper-sim-fixed"])
    mission = preset()
    assert mission.fence is not None
    hull = with_fence(mission, mission.fence.convex_hull)
    with pytest.raises(SkymuleError, match=r"mission 1 .* another geofence"):
        DataMuleVectorEnv([mission, hull])
    base = load_scenario(PRESET)
    five = random_autonomous_scenario(np.random.default_rng(0), base, LayoutRanges((5, 5)))
    with pytest.raises(SkymuleError, match=r"missions have \[4, 5\] sensors"):
        DataMuleVectorEnv([mission, build_mission(five)])
    vector = DataMuleVectorEnv([mission, preset()])  # separately built, one fence
    vector.reset()
    with pytest.raises(SkymuleError, match=r"action \[0, 9\] of mission 1 is not allowed"):
        vector.step(np.array([[0, 0], [0, 9]]))
