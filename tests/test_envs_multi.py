"""The PettingZoo environment for several UAVs (optional extra ``skymule[marl]``)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test

from skymule.envs.multi import DataMuleParallelEnv
from skymule.errors import SkymuleError
from skymule.scenario import Scenario, UavSpec, load_scenario


def _scenario(duration_s: float = 60.0) -> Scenario:
    base = load_scenario("paper-sim-autonomous")
    uavs = [UavSpec(name="A"), UavSpec(name="B", home=[-200.0, -100.0])]
    mission = base.mission.model_copy(update={"duration_s": duration_s})
    return base.model_copy(update={"uavs": uavs, "mission": mission})


def test_parallel_api_test_passes() -> None:
    parallel_api_test(DataMuleParallelEnv(_scenario()), num_cycles=100)


def _episode(env: DataMuleParallelEnv, seed: int) -> list[tuple[np.ndarray, float]]:
    observations, _ = env.reset(seed=seed)
    env.action_space("A").seed(seed)
    trace = []
    while env.agents:
        actions = {a: env.action_space(a).sample() for a in env.agents}
        observations, rewards, _, _, _ = env.step(actions)
        trace += [(observations[a], rewards[a]) for a in sorted(observations)]
    return trace


def test_same_seed_same_episode_and_rewards_are_the_downloads() -> None:
    env = DataMuleParallelEnv(_scenario(duration_s=60.0))
    first, second = _episode(env, 5), _episode(env, 5)
    assert len(first) == 2 * 60
    for (obs_a, rew_a), (obs_b, rew_b) in zip(first, second, strict=True):
        assert np.array_equal(obs_a, obs_b) and rew_a == rew_b
    # both UAVs ask for LW1 (500 Mbit) and stay home: A, next to it, wins every slot
    env.reset(seed=1)
    total = {"A": 0.0, "B": 0.0}
    while env.agents:
        _, rewards, _, _, infos = env.step({a: np.array([0, 8]) for a in env.agents})
        total = {a: total[a] + rewards[a] for a in total}
        assert infos["B"]["lost"] and not infos["A"]["lost"]
    assert total["B"] == 0.0
    assert total["A"] == pytest.approx(60 * 7.77)  # top AADM rate 7.77 Mbit/s


def test_action_out_of_range_is_one_clear_error() -> None:
    env = DataMuleParallelEnv(_scenario())
    env.reset()
    with pytest.raises(SkymuleError, match=r"action for UAV 'B' = .*allowed: \[sensor 0..4"):
        env.step({"A": np.array([0, 0]), "B": np.array([9, 0])})


def test_docs_example_runs_as_written() -> None:
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "fleet.md").read_text()
    (block,) = [b for b in re.findall(r"```python\n(.*?)```", text, flags=re.S) if "env" in b]
    namespace: dict[str, object] = {}
    exec(compile(block.replace("examples/", f"{root}/examples/"), "fleet.md", "exec"), namespace)
    assert namespace["env"].agents == []  # type: ignore[attr-defined]
