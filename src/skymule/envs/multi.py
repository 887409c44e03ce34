"""A PettingZoo ``ParallelEnv`` for several UAVs (``pip install 'skymule[marl]'``).

Any scenario with ``[[uavs]]`` (or any scenario at all: one agent) becomes an environment
whose agents are the UAVs, stepped by the fleet engine (:mod:`skymule.sim.fleet`): the same
slot contract, shared buffers, geofence, speed cap and return home as ``skymule run``.

Per agent, every slot (one slot = one step):

* **observation** -- ``Box`` float32 of shape ``(4 + 3 N,)``: own position x, y, z [m] (local
  east/north/up), time left [s], then per sensor its SNR [dB] (-inf: no link, sent as
  ``NO_LINK_DB``), its rate [Mbit/s] and the data left in its buffer [Mbit] (shared by all
  UAVs);
* **action** -- ``MultiDiscrete([N + 1, H + 1])``: the sensor to serve (``N``: none), and a
  heading, one of ``H`` directions evenly spaced counter-clockwise from east (``H``: stay) at
  full speed; the engine keeps the UAV in the fence and brings it home in time. Autonomous
  scenarios only (fixed paths have no move to choose);
* **reward** -- Mbit this UAV downloaded in the slot (a UAV that loses a sensor to another gets
  0; ``infos[agent]["lost"]`` says so);
* the episode ends for all agents after the mission's last slot (``terminations``); it is
  never truncated.

``reset(seed=s)`` rebuilds the mission with scenario seed ``s`` (shadowing and fading draws),
so the same seed and the same actions give the same episode.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from skymule.errors import SkymuleError
from skymule.policies.base import BatchAction, Observation
from skymule.rules.home import time_left_s
from skymule.scenario import Scenario, load_scenario
from skymule.sim.autonomous import AutonomousEngine
from skymule.sim.fleet import Fleet, build_fleet
from skymule.units import BITS_PER_MBIT

__all__ = ["DataMuleParallelEnv"]

#: SNR sent for "no link" (-inf) [dB]: below every rate table's lowest entry.
NO_LINK_DB = -100.0

#: Default number of headings.
HEADINGS = 8


class DataMuleParallelEnv(ParallelEnv[str, np.ndarray, np.ndarray]):
    """Several UAVs on one data-mule mission (module docstring for spaces and rewards)."""

    metadata: ClassVar[dict[str, Any]] = {"name": "skymule_datamule_v0", "render_modes": []}

    def __init__(self, scenario: str | Scenario, headings: int = HEADINGS) -> None:
        self.scenario = load_scenario(scenario) if isinstance(scenario, str) else scenario
        if headings < 1:
            raise SkymuleError(f"headings = {headings}: allowed: 1 or more")
        self.headings = headings
        self._fleet = build_fleet(self.scenario)
        if self._fleet.mode != "autonomous":
            raise SkymuleError(
                "DataMuleParallelEnv: trajectory.mode = 'fixed'; the agents steer, so it needs "
                "trajectory.mode = 'autonomous'"
            )
        self.possible_agents = list(self._fleet.names)
        self.agents: list[str] = []
        self._flight: AutonomousEngine | None = None
        self._seen: tuple[Observation, ...] = ()
        n = self._fleet.missions[0].n_sensors
        self._n_sensors = n
        self._observation_space = spaces.Box(-np.inf, np.inf, (4 + 3 * n,), np.float32)
        self._action_space = spaces.MultiDiscrete([n + 1, headings + 1])

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        # the same object every call (PettingZoo's API rule: seeding a space must stick)
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        return self._action_space

    def _encode(self, observation: Observation, fleet: Fleet) -> np.ndarray:
        mission = fleet.missions[0]
        left_s = time_left_s(mission.n_slots, observation.slot, mission.slot_s)
        snr = np.where(np.isfinite(observation.snr_db), observation.snr_db, NO_LINK_DB)
        return np.concatenate(
            [
                observation.position_m,
                [left_s],
                snr,
                observation.rate_bps / BITS_PER_MBIT,
                observation.remaining_bit / BITS_PER_MBIT,
            ]
        ).astype(np.float32)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Start the fleet mission again; (observations, infos) per agent (UAV)."""
        if seed is not None and seed != self._fleet.scenario.seed:
            self._fleet = build_fleet(self.scenario.model_copy(update={"seed": int(seed)}))
        fleet = np.zeros(self._fleet.size, np.int64)
        self._flight = AutonomousEngine(list(self._fleet.missions), fleet, detail=False)
        self.agents = list(self.possible_agents)
        self._seen = self._flight.observe().missions()
        observations = {
            a: self._encode(o, self._fleet) for a, o in zip(self.agents, self._seen, strict=True)
        }
        return observations, {a: {} for a in self.agents}

    def _action(self, agent: str, index: int, value: Any) -> tuple[int, np.ndarray]:
        """(sensor or -1, goal (2,) [m] or NaN to stay) of one UAV's action."""
        chosen = np.asarray(value)
        if chosen.shape != (2,) or not self._action_space.contains(chosen.astype(np.int64)):
            raise SkymuleError(
                f"action for UAV {agent!r} = {value!r}; allowed: [sensor 0..{self._n_sensors} "
                f"({self._n_sensors} = none), heading 0..{self.headings} ({self.headings} = stay)]"
            )
        sensor, heading = int(chosen[0]), int(chosen[1])
        serve = -1 if sensor == self._n_sensors else sensor
        if heading == self.headings:
            return serve, np.full(2, np.nan)
        here = self._seen[index].position_m
        angle = 2 * math.pi * heading / self.headings
        step = self._fleet.missions[index].max_step_m
        goal = (float(here[0]) + step * math.cos(angle), float(here[1]) + step * math.sin(angle))
        return serve, np.array(goal)

    def step(
        self, actions: dict[str, np.ndarray]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        """One slot of every UAV: each agent's (serve, heading), conflicts settled by the
        engine (the higher rate wins a sensor). Returns observations, rewards, terminations,
        truncations and infos, per agent."""
        flight = self._flight
        if flight is None or not self.agents:
            raise SkymuleError("step() after the episode ended: call reset() first")
        unknown = sorted(set(actions) - set(self.agents))
        if unknown:
            raise SkymuleError(f"actions for unknown UAVs {unknown}; agents: {self.agents}")
        stay = np.array([self._n_sensors, self.headings])
        chosen = [
            self._action(a, k, actions.get(a, stay)) for k, a in enumerate(self.possible_agents)
        ]
        serve = np.array([c[0] for c in chosen], np.int64)
        goto = np.array([c[1] for c in chosen], float)
        bits = flight.step(BatchAction(serve=serve, goto_m=goto), "agents")
        lost = flight.last_lost
        agents = list(self.agents)
        rewards = {a: float(b) / BITS_PER_MBIT for a, b in zip(agents, bits, strict=True)}
        infos = {a: {"lost": bool(lost[k])} for k, a in enumerate(agents)}
        done = flight.done
        if not done:
            self._seen = flight.observe().missions()
        observations = {
            a: self._encode(o, self._fleet) for a, o in zip(agents, self._seen, strict=True)
        }
        terminations = dict.fromkeys(agents, done)
        truncations = dict.fromkeys(agents, False)
        if done:
            self.agents = []
        return observations, rewards, terminations, truncations, infos
