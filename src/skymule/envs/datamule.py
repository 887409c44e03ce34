"""``skymule/DataMule-v0``: one data-mule mission as a Gymnasium environment.

The environment is the engine with one mission (the core of
:class:`~skymule.envs.vector.DataMuleVectorEnv`, B = 1: :class:`~skymule.envs.vector.EnvMissions`).
Each ``step`` is one slot: the action becomes the engine's action, the engine applies the slot
contract, the geofence, the speed cap, the return home and the mission's faults. Nothing here
re-implements a rule.

* observation and action: :mod:`skymule.envs.observation` (shapes and units);
* reward (``reward="mbit"``, default): Mbit downloaded this slot. ``reward="aadm"``: the AADM
  score in force spread over the episode (:mod:`skymule.aadm.score`): 100 x bits / total
  buffered each slot inside the download window, plus the bonus max(0, window - t1) in the
  slot that completes the download, so the episode's return equals ``aadm_score`` of its log;
* the episode ends (``terminated``) when the mission's time is up (with ``return_home`` the
  engine has landed the UAV at home by then) or a recorded trace is used up;
* ``reset(seed=s)`` reproduces the episode: the scenario's seed (shadowing, fading) and, with
  a scenario generator, the drawn scenario come from the environment's seeded generator.

``scenario`` is a preset name, a TOML path, a :class:`~skymule.scenario.Scenario`, or a
callable ``rng -> Scenario`` that draws a new mission at every reset (randomised training, e.g.
:func:`skymule.experiments.layouts.random_autonomous_scenario`); every drawn scenario must have
the same number of sensors.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

import skymule.envs.observation as enc
from skymule.envs.vector import ENV_POLICY_NAME, REWARDS, EnvMissions, anchors_m, check_reward
from skymule.errors import SkymuleError
from skymule.metrics.flights import MissionLog
from skymule.policies.base import Observation
from skymule.rules.home import time_left_s
from skymule.scenario import Scenario, load_scenario
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission, build_mission

__all__ = ["ENV_POLICY_NAME", "REWARDS", "DataMuleEnv", "anchors_m", "observation_vector"]

ScenarioLike = str | Path | Scenario | Mission | Callable[[np.random.Generator], Scenario]


def uses_randomness(scenario: Scenario) -> bool:
    """True when the scenario's seed changes the mission (shadowing or fading)."""
    radio = scenario.radio
    return radio.shadowing_std_db > 0 or radio.fading != "none"


def observation_vector(
    mission: Mission, observation: Observation, position_m: np.ndarray | None = None
) -> np.ndarray:
    """(3 + 5N,) float32 encoding of an engine Observation (``position_m`` overrides)."""
    position = observation.position_m[:2] if position_m is None else position_m[:2]
    time_left = time_left_s(mission.n_slots, observation.slot, mission.slot_s)
    return enc.encode(
        np.asarray(position, float)[None],
        np.array([time_left]),
        observation.snr_db[None],
        observation.rate_bps[None],
        observation.remaining_bit[None],
        anchors_m(mission)[None],
    )[0]


def check_choice(serve: Any, heading: Any, n_sensors: int) -> tuple[int, int]:
    """(serve, heading) as ints; SkymuleError naming the value and what is allowed."""
    ok = all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in (serve, heading))
    if not ok or not (0 <= serve <= n_sensors and 0 <= heading < enc.N_HEADINGS):
        raise SkymuleError(
            f"action (serve={serve!r}, heading={heading!r}) is not allowed; allowed: serve "
            f"0 (none) or 1..{n_sensors} (sensor index + 1), heading 0 (stay) or "
            f"1..{enc.N_HEADINGS - 1}"
        )
    return int(serve), int(heading)


class DataMuleEnv(gym.Env[np.ndarray, Any]):
    """One data-mule mission per episode, on the engine core (see the module docstring).

    Args:
        scenario: preset name, TOML path, Scenario, or ``rng -> Scenario`` generator.
        move: "headings" (MultiDiscrete [N + 1, 9]) or "velocity" (Dict serve + velocity).
        reward: "mbit" (Mbit downloaded this slot) or "aadm" (AADM-score shaping).
        scaled: divide the observation by :func:`~skymule.envs.observation.scale_vector`
            (fields of order 1, for neural networks; ``rl:`` policies expect it).
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's attribute)

    def __init__(
        self, scenario: ScenarioLike = "paper-sim-autonomous", *, move: str = "headings",
        reward: str = "mbit", scaled: bool = False,
    ) -> None:  # fmt: skip
        if move not in enc.MOVES:
            raise SkymuleError(f"move = {move!r} is not allowed; allowed: {', '.join(enc.MOVES)}")
        self.move, self.reward_mode = move, check_reward(reward)
        self._generator = (
            None if isinstance(scenario, Mission) or not callable(scenario) else scenario
        )
        self._scenario: Scenario | None = None
        if isinstance(scenario, Mission):  # a built mission is used as it is (no reseeding)
            self._scenario, self._fixed_mission = None, scenario
            self.mission = scenario
        elif not callable(scenario):
            self._scenario = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
            self._fixed_mission = build_mission(self._scenario)
            self.mission = self._fixed_mission
        else:
            self.mission = build_mission(scenario(np.random.default_rng(0)))
        self.n_sensors = self.mission.n_sensors
        low, high = enc.observation_bounds(self.n_sensors)
        self._scale = enc.scale_vector(self.n_sensors) if scaled else np.ones_like(low)
        self.observation_space = spaces.Box(low / self._scale, high / self._scale, dtype=np.float32)
        if move == "headings":
            self.action_space: spaces.Space[Any] = spaces.MultiDiscrete(
                [self.n_sensors + 1, enc.N_HEADINGS]
            )
        else:
            self.action_space = spaces.Dict(
                {
                    "serve": spaces.Discrete(self.n_sensors + 1),
                    "velocity": spaces.Box(-1.0, 1.0, (2,), np.float32),
                }
            )
        self._core: EnvMissions | None = None
        self._done = False

    # --- episode ------------------------------------------------------------------------------

    def _draw_mission(self) -> Mission:
        if self._generator is not None:
            scenario = self._generator(self.np_random)
        else:
            if self._scenario is None or not uses_randomness(self._scenario):
                return self._fixed_mission
            scenario = self._scenario
        if uses_randomness(scenario):
            seed = int(self.np_random.integers(2**62))
            scenario = scenario.model_copy(update={"seed": seed})
        mission = build_mission(scenario)
        if mission.n_sensors != self.n_sensors:
            raise SkymuleError(
                f"scenario {scenario.name!r} has {mission.n_sensors} sensors; this environment "
                f"was built for {self.n_sensors} (every drawn scenario needs the same number)"
            )
        return mission

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: the mission from the start (a new one drawn from the generator,
        if any; ``seed`` makes it reproducible). Returns (observation, info)."""
        super().reset(seed=seed)
        self.mission = self._draw_mission()
        self._core = EnvMissions([self.mission], self.reward_mode, detail=True)
        self._done = False
        return self._core.encoded()[0] / self._scale, {"slot": 0}

    def _decode(self, action: Any) -> tuple[int, np.ndarray]:
        """(served sensor index or NO_SENSOR, (2,) displacement [m]) of a valid action."""
        step_m = self.mission.max_step_m
        if self.move == "headings":
            values = np.asarray(action).reshape(-1)
            if values.shape != (2,) or values.dtype.kind not in "iu":
                raise SkymuleError(
                    f"action {action!r} is not allowed; allowed: two integers (serve 0.."
                    f"{self.n_sensors}, heading 0..{enc.N_HEADINGS - 1})"
                )
            serve, heading = check_choice(values[0], values[1], self.n_sensors)
            return enc.serve_index(serve), enc.heading_step_m(np.array([heading]), step_m)[0]
        if not isinstance(action, dict) or set(action) != {"serve", "velocity"}:
            raise SkymuleError(
                f"action {action!r} is not allowed; allowed: {{'serve': 0..{self.n_sensors}, "
                "'velocity': (vx, vy) in [-1, 1]}"
            )
        velocity = np.asarray(action["velocity"], float)
        if velocity.shape != (2,) or not np.all(np.abs(velocity) <= 1.0):
            raise SkymuleError(
                f"action velocity {action['velocity']!r} is not allowed; allowed: (vx, vy) "
                "with each component in [-1, 1] (fractions of max_speed_mps)"
            )
        serve, _ = check_choice(np.asarray(action["serve"]).item(), 0, self.n_sensors)
        return enc.serve_index(serve), enc.velocity_step_m(velocity, step_m)

    def _running(self) -> EnvMissions:
        if self._core is None or self._done:
            raise SkymuleError("step() called before reset() or after the episode ended")
        return self._core

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One slot: serve and move as ``action`` says, by the engine's rules. Returns
        (observation, reward, terminated, truncated, info with the slot, the sensor served and
        the Mbit downloaded)."""
        core = self._running()
        sensor, move_m = self._decode(action)
        bits, reward = core.step(np.array([sensor]), move_m[None], np.ones(1, bool))
        slot = int(core.slot[0])
        self._done = core.engine.done
        if self._done:
            observation = self._terminal_observation()
        else:
            observation = core.encoded(core.observe())[0]
        info = {"slot": slot, "served": sensor, "downloaded_mbit": bits[0] / BITS_PER_MBIT}
        return observation / self._scale, float(reward[0]), self._done, False, info

    def _terminal_observation(self) -> np.ndarray:
        """The observation after the last slot: where the UAV ended, no time left."""
        assert self._core is not None
        mission, core = self.mission, self._core
        if mission.mode == "autonomous":
            return core.encoded(core.observe())[0]
        # a fixed path: the last slot's signal, where the UAV ended
        log = core.log()
        last = core.last.mission(0)
        final = Observation(
            mission.n_slots, log.end_position_m, last.snr_db, last.rate_bps, log.left_bit
        )
        return observation_vector(mission, final)

    def log(self) -> MissionLog:
        """The engine's mission log of the current episode (slots run so far)."""
        if self._core is None:
            raise SkymuleError("log() called before reset()")
        return self._core.log()
