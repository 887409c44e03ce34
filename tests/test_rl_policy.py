"""``rl:path/to/model.zip``: a trained model runs as a skymule policy (needs skymule[rl])."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skymule.errors import SkymuleError
from skymule.policies import make_policy, resolve_policy
from skymule.scenario import PolicySpec, Scenario, load_scenario
from skymule.trust import trusting


def short_mission() -> Scenario:
    base = load_scenario("paper-sim-autonomous")
    return base.model_copy(update={"mission": base.mission.model_copy(update={"duration_s": 80})})


def test_a_missing_model_is_one_clear_error(tmp_path: Path) -> None:
    factory = resolve_policy(f"rl:{tmp_path / 'none.zip'}")  # resolving never loads
    pytest.importorskip("stable_baselines3")
    with pytest.raises(SkymuleError, match=r"none.zip': no such model file"):
        factory(PolicySpec(name=f"rl:{tmp_path / 'none.zip'}"))


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("torch")
    from stable_baselines3 import PPO

    from skymule.envs.datamule import DataMuleEnv

    env = DataMuleEnv(short_mission(), scaled=True)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=64)
    path = tmp_path_factory.mktemp("rl") / "tiny.zip"
    model.save(str(path))
    return path


def test_a_saved_model_loads_as_a_policy_and_flies_as_in_the_env(tiny_model: Path) -> None:
    from stable_baselines3 import PPO

    from skymule.envs.datamule import DataMuleEnv
    from skymule.sim.run import run_mission

    with trusting([tiny_model]):  # the model this test has just trained
        policy = make_policy(PolicySpec(name=f"rl:{tiny_model}"))
    assert policy.name == "rl:tiny"
    env = DataMuleEnv(short_mission(), scaled=True)
    log = run_mission(env.mission, policy)
    assert log.n_slots == env.mission.n_slots
    # the same model stepping the environment takes the same actions: same downloads, path
    model = PPO.load(str(tiny_model), device="cpu")
    observation, _ = env.reset(seed=0)
    done = False
    while not done:
        action, _ = model.predict(observation, deterministic=True)
        observation, _, done, _, _ = env.step(action)
    mirrored = env.log()
    np.testing.assert_array_equal(mirrored.served, log.served)
    np.testing.assert_allclose(mirrored.position_m, log.position_m, atol=1e-9)
    np.testing.assert_allclose(mirrored.downloaded_bit, log.downloaded_bit, rtol=1e-12)


def test_a_model_for_another_sensor_count_is_refused(tiny_model: Path) -> None:
    from skymule.sim.run import run_mission
    from skymule.world import build_mission

    base = short_mission()
    three = base.model_copy(update={"sensors": base.sensors[:3]})
    with trusting([tiny_model]):
        policy = make_policy(PolicySpec(name=f"rl:{tiny_model}"))
    with pytest.raises(SkymuleError, match=r"MultiDiscrete\(\[4, 9\]\) \(3 sensors"):
        run_mission(build_mission(three), policy)
