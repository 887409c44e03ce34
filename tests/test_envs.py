"""The learning environments: Gymnasium API, seeding, agreement with the engine and each other."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from shapely.geometry import Point

gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import skymule.envs  # noqa: E402  (registers skymule/DataMule-v0)
from skymule.envs.datamule import DataMuleEnv  # noqa: E402
from skymule.errors import SkymuleError  # noqa: E402
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario  # noqa: E402
from skymule.metrics.summary import aadm_score  # noqa: E402
from skymule.scenario import Scenario, load_scenario  # noqa: E402

SHORT = LayoutRanges(n_sensors=(4, 4), duration_s=(30, 70))


def noisy_scenario() -> Scenario:
    base = load_scenario("paper-sim-autonomous")
    radio = base.radio.model_copy(update={"shadowing_std_db": 6.0, "fading": "rician"})
    mission = base.mission.model_copy(update={"duration_s": 100.0})
    return base.model_copy(update={"radio": radio, "mission": mission})


def run_episode(env: Any, seed: int, action_seed: int) -> tuple[list[np.ndarray], list[float]]:
    observation, _ = env.reset(seed=seed)
    actions = np.random.default_rng(action_seed)
    observations, rewards = [observation], []
    done = False
    while not done:
        serve = int(actions.integers(0, env.unwrapped.n_sensors + 1))
        heading = int(actions.integers(0, 9))
        observation, reward, done, truncated, _ = env.step(np.array([serve, heading]))
        assert not truncated
        observations.append(observation)
        rewards.append(reward)
    return observations, rewards


@pytest.mark.parametrize(
    ("scenario", "kwargs"),
    [
        ("paper-sim-autonomous", {}),
        ("paper-sim-autonomous", {"move": "velocity", "reward": "aadm", "scaled": True}),
        ("paper-sim-fixed", {}),
    ],
)
def test_registered_env_passes_gymnasiums_checker(scenario: str, kwargs: dict[str, Any]) -> None:
    env = gymnasium.make(skymule.envs.ENV_ID, scenario=scenario, **kwargs)
    check_env(env.unwrapped, skip_render_check=True)
    n = 4
    assert env.observation_space.shape == (3 + 5 * n,)


def test_same_seed_same_episode_and_the_seed_drives_the_channel() -> None:
    first = run_episode(DataMuleEnv(noisy_scenario()), seed=11, action_seed=3)
    again = run_episode(DataMuleEnv(noisy_scenario()), seed=11, action_seed=3)
    other = run_episode(DataMuleEnv(noisy_scenario()), seed=12, action_seed=3)
    assert all(np.array_equal(a, b) for a, b in zip(first[0], again[0], strict=True))
    assert first[1] == again[1]
    # shadowing and fading are drawn from the reset seed: another seed, another channel
    assert not np.array_equal(first[0][0][3:7], other[0][0][3:7])


def test_random_missions_are_drawn_from_the_reset_seed() -> None:
    base = load_scenario("paper-sim-autonomous")

    def draw(rng: np.random.Generator) -> Scenario:
        return random_autonomous_scenario(rng, base, SHORT)

    env = DataMuleEnv(draw)
    a, _ = env.reset(seed=4)
    b, _ = env.reset(seed=4)
    c, _ = env.reset(seed=5)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


@pytest.mark.parametrize("scenario", ["paper-sim-autonomous", "paper-sim-fixed"])
def test_rewards_are_the_engines_downloads_and_aadm_shaping_sums_to_the_score(
    scenario: str,
) -> None:
    env = DataMuleEnv(scenario)
    _, rewards = run_episode(env, seed=0, action_seed=8)
    log = env.log()
    assert log.n_slots == env.mission.n_slots
    assert sum(rewards) == pytest.approx(log.downloaded_bit.sum() / 1e6, rel=1e-12)
    assert sum(rewards) > 0
    shaped = DataMuleEnv(scenario, reward="aadm")
    _, shaped_rewards = run_episode(shaped, seed=0, action_seed=8)
    assert sum(shaped_rewards) == pytest.approx(aadm_score(shaped.log()), abs=1e-9)


def test_the_autonomous_episode_ends_at_home_and_the_engine_enforces_the_fence() -> None:
    env = DataMuleEnv("paper-sim-autonomous")
    env.reset(seed=0)
    done, observation = False, None
    while not done:  # always fly north-east at full speed: the engine keeps it legal
        observation, _, done, _, _ = env.step(np.array([0, 2]))
    log = env.log()
    assert observation is not None and observation[2] == 0.0  # no time left
    assert np.allclose(log.end_position_m[:2], env.mission.home_m, atol=1e-6)
    fence = env.mission.fence
    assert fence is not None
    assert all(fence.buffer(1e-3).covers(Point(p[:2])) for p in log.position_m)


@pytest.mark.parametrize(
    "action",
    [np.array([5, 0]), np.array([0, 9]), np.array([-1, 0]), np.array([1.0, 2.0]), np.array([1])],
)
def test_a_bad_action_is_one_clear_error(action: np.ndarray) -> None:
    env = DataMuleEnv("paper-sim-autonomous")
    env.reset(seed=0)
    with pytest.raises(SkymuleError, match="not allowed; allowed"):
        env.step(action)


def test_bad_velocity_and_bad_keywords_are_clear_errors() -> None:
    env = DataMuleEnv("paper-sim-autonomous", move="velocity")
    env.reset(seed=0)
    with pytest.raises(SkymuleError, match="velocity"):
        env.step({"serve": 1, "velocity": np.array([2.0, 0.0])})
    with pytest.raises(SkymuleError, match="serve"):
        env.step({"serve": 7, "velocity": np.zeros(2)})
    with pytest.raises(SkymuleError, match="move = 'teleport'"):
        DataMuleEnv("paper-sim-autonomous", move="teleport")
    with pytest.raises(SkymuleError, match="before reset"):
        DataMuleEnv("paper-sim-autonomous").step(np.array([0, 0]))
