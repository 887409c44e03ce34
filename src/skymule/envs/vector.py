"""Many autonomous missions stepped at once: a Gymnasium ``VectorEnv`` that is the engine.

Each of the B sub-environments is one mission, a column of the autonomous engine
(:class:`~skymule.sim.autonomous.AutonomousEngine`); a step is one slot of every
mission: the served sensor delivers min(R dt, Q) bits, the UAV flies toward the heading's
point inside the fence, home in time, under the mission's faults, all by the engine's rules.
Nothing here restates them: :class:`EnvMissions` only turns actions into the engine's
:class:`~skymule.policies.base.BatchAction` and the engine's observations into the
encodings of ``skymule/DataMule-v0`` (:mod:`skymule.envs.observation`); the AADM reward is
:func:`skymule.aadm.score.slot_rewards`. The single environment
(:class:`~skymule.envs.datamule.DataMuleEnv`) is the same core with B = 1.

What it supports: autonomous missions sharing one geofence and sensor count; everything else
may differ per mission (sensors, buffers, home, signal, rates, speed, altitude, duration,
return home, faults). ``tests/test_vector_env.py`` runs single environments and this one side
by side and requires the same observations, rewards, terminations and positions.

Shadowing, fading and fault draws are those of each built :class:`~skymule.world.Mission`
(drawn once from its scenario's seed) in every episode: ``reset(seed=...)`` does not redraw
them, as :class:`DataMuleEnv` given that built Mission.

Autoreset follows Gymnasium's ``NEXT_STEP`` mode: the step after an episode ends resets that
mission (its action is ignored) and returns its first observation with reward 0.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

import skymule.envs.observation as enc
from skymule.errors import SkymuleError
from skymule.metrics.flights import MissionLog
from skymule.policies.base import BatchAction, BatchObservation
from skymule.rules.contract import NO_SENSOR
from skymule.rules.home import time_left_s
from skymule.rules.score import slot_rewards
from skymule.scenario import Scenario, load_scenario
from skymule.units import BITS_PER_MBIT
from skymule.world import Mission, build_mission

__all__ = ["DataMuleVectorEnv"]

REWARDS = ("mbit", "aadm")


def check_reward(reward: str) -> str:
    """``reward`` if it is one of :data:`REWARDS`, else the one-line SkymuleError."""
    if reward not in REWARDS:
        raise SkymuleError(f"reward = {reward!r} is not allowed; allowed: {', '.join(REWARDS)}")
    return reward


#: Policy name written into the logs of environment episodes.
ENV_POLICY_NAME = "env"


def anchors_m(mission: Mission) -> np.ndarray:
    """(N, 2) where each sensor is served from: hover points (autonomous) or sensor positions."""
    if mission.mode == "autonomous" and mission.hover_points_m is not None:
        return np.asarray(mission.hover_points_m, float)
    return np.asarray(mission.sensor_m, float)[:, :2]


class EnvMissions:
    """B missions of an environment on the engine: actions in, encoded observations and
    rewards out (autonomous missions restart one by one; a fixed one is B = 1).

    Args:
        missions: one Mission per sub-environment (one mode, fence and sensor count).
        reward: "mbit" (Mbit downloaded this slot) or "aadm" (AADM-score shaping).
        engine: path queries "auto", "numpy" or "compiled" (the same steps either way).
        detail: keep the per-slot detail for :meth:`log`.
    """

    def __init__(
        self, missions: Sequence[Mission], reward: str, engine: str = "auto", detail: bool = False
    ) -> None:
        from skymule.sim.autonomous import AutonomousEngine
        from skymule.sim.fixed import FixedEngine

        self.missions = tuple(missions)
        self.reward_mode = check_reward(reward)
        self.autonomous = missions[0].mode == "autonomous"
        self.engine: AutonomousEngine | FixedEngine
        if self.autonomous:
            self.engine = AutonomousEngine(missions, detail=detail, engine=engine)
        else:
            if len(missions) != 1:
                raise SkymuleError("a fixed-trajectory environment runs one mission (B = 1)")
            self.engine = FixedEngine(missions, detail=detail)
        self.engine_choice = engine
        self._anchors = np.array([anchors_m(m) for m in missions], float)
        self._n_slots = np.array([m.n_slots for m in missions], np.int64)
        self._slot_s = np.array([m.slot_s for m in missions], float)
        self._step_m = np.array([m.max_step_m for m in missions], float)
        self._window_s = np.array([m.score_window_s for m in missions], float)
        self._total_bit = np.array([m.buffers_bit.sum() for m in missions], float)
        self._counted = np.zeros(len(missions))
        self._completed = np.zeros(len(missions), bool)
        self.last: BatchObservation = self.engine.observe()

    @property
    def slot(self) -> np.ndarray:
        """(B,) each mission's current slot."""
        engine = self.engine
        return engine.slot if isinstance(engine.slot, np.ndarray) else np.full(1, engine.slot)

    def encoded(self, observation: BatchObservation | None = None) -> np.ndarray:
        """(B, 3 + 5N) the encoded observation (the last one by default)."""
        seen = self.last if observation is None else observation
        time_left = time_left_s(self._n_slots, seen.slot, self._slot_s)
        return enc.encode(
            seen.position_m[:, :2], time_left, seen.snr_db, seen.rate_bps, seen.remaining_bit,
            self._anchors,
        )  # fmt: skip

    def step(
        self, sensor: np.ndarray, move_m: np.ndarray, live: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One slot of the ``live`` missions: ``sensor`` (B,) to serve (NO_SENSOR: none),
        ``move_m`` (B, 2) the displacement asked for (0: stay; fixed paths: 0 hovers, any
        other advances). Returns (bits (B,), reward (B,))."""
        before = self.slot.copy()
        serve = np.where(live, sensor, NO_SENSOR)
        stay = ~np.any(move_m != 0, axis=1)
        if self.autonomous:
            goto = self.last.position_m[:, :2] + move_m
            goto[stay] = np.nan
            action = BatchAction(serve=serve, goto_m=goto)
        else:
            action = BatchAction(serve=serve, hover=stay)
        bits = self.engine.step(action, ENV_POLICY_NAME) * live
        slots_run = np.where(live, before + 1, before)
        return bits, self._reward(bits, slots_run, live)

    def observe(self) -> BatchObservation:
        """Observe every mission (those that ended: where they ended, after their last slot)."""
        engine = self.engine
        if self.autonomous:
            self.last = engine.observe(every=True)  # type: ignore[call-arg]
        elif not engine.done:
            self.last = engine.observe()
        return self.last

    def restart(self, which: np.ndarray) -> None:
        """The missions ``which`` (mask) start again (autonomous)."""
        from skymule.sim.autonomous import AutonomousEngine

        assert isinstance(self.engine, AutonomousEngine)
        self.engine.restart(which)
        self._counted[which] = 0.0
        self._completed[which] = False

    def _reward(self, bits: np.ndarray, slots_run: np.ndarray, live: np.ndarray) -> np.ndarray:
        if self.reward_mode == "mbit":
            return bits / BITS_PER_MBIT
        return slot_rewards(
            bits, slots_run, live, self._slot_s, self._total_bit, self._window_s,
            self._counted, self._completed,
        )  # fmt: skip

    def log(self) -> MissionLog:
        """The engine's log of mission 0 (B = 1: the episode so far)."""
        return self.engine.record([ENV_POLICY_NAME] * len(self.missions)).mission(0)


class DataMuleVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """B autonomous missions stepped together (see the module docstring for what it supports).

    Args:
        missions: Missions, Scenarios, preset names or paths; one sub-environment each.
        reward: "mbit" or "aadm" (as in :class:`~skymule.envs.datamule.DataMuleEnv`).
        engine: path queries "auto" (compiled when numba is installed), "numpy" or
            "compiled"; the same steps either way.
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(
        self,
        missions: Sequence[Mission | Scenario | str],
        *,
        reward: str = "mbit",
        engine: str = "auto",
    ) -> None:
        if not missions:
            raise SkymuleError("vector env: give at least one mission")
        check_reward(reward)
        built = [m if isinstance(m, Mission) else _build(m) for m in missions]
        for index, mission in enumerate(built):
            if mission.mode != "autonomous":
                raise SkymuleError(
                    f"vector env: mission {index} ({mission.scenario.name!r}) is not supported: "
                    "it is not autonomous (trajectory.mode = 'fixed'; use DataMuleEnv)"
                )
        sizes = [m.n_sensors for m in built]
        if any(size != sizes[0] for size in sizes):
            raise SkymuleError(
                f"vector env: missions have {sorted(set(sizes))} sensors; all missions must "
                f"have the same number (the observation's size)"
            )
        self.missions = tuple(built)
        self.reward_mode = reward
        self._engine_choice = engine
        self.num_envs = len(built)
        self.n_sensors = sizes[0]
        low, high = enc.observation_bounds(self.n_sensors)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.MultiDiscrete([self.n_sensors + 1, enc.N_HEADINGS])
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._step_m = np.array([m.max_step_m for m in built], float)
        self._core = EnvMissions(built, reward, engine)
        self._needs_reset = np.zeros(self.num_envs, bool)

    @property
    def position_m(self) -> np.ndarray:
        """(B, 2) every UAV's position [m]."""
        return self._core.engine.position.copy()  # type: ignore[union-attr]

    @property
    def slot(self) -> np.ndarray:
        """(B,) every mission's current slot."""
        return self._core.slot.copy()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every mission again at home with full buffers; ((B, 3 + 5N) observations,
        info). The missions are built already, so ``seed`` changes nothing."""
        super().reset(seed=seed)  # the missions are deterministic: the seed changes nothing
        self._core.restart(np.ones(self.num_envs, bool))
        self._needs_reset[:] = False
        self._core.observe()
        return self._core.encoded(), {}

    def _check(self, actions: np.ndarray) -> np.ndarray:
        values = np.asarray(actions)
        if values.shape != (self.num_envs, 2) or values.dtype.kind not in "iu":
            raise SkymuleError(
                f"vector env: actions of shape {values.shape} and dtype {values.dtype}; allowed: "
                f"integers of shape ({self.num_envs}, 2) (serve, heading)"
            )
        bad = (values[:, 0] < 0) | (values[:, 0] > self.n_sensors)
        bad |= (values[:, 1] < 0) | (values[:, 1] >= enc.N_HEADINGS)
        if bad.any():
            index = int(np.argmax(bad))
            raise SkymuleError(
                f"vector env: action {values[index].tolist()} of mission {index} is not allowed; "
                f"allowed: serve 0 (none) or 1..{self.n_sensors}, heading 0..{enc.N_HEADINGS - 1}"
            )
        return values.astype(np.int64)

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One slot of every mission: ``actions`` (B, 2) (serve 0 = none or sensor + 1,
        heading). Returns (observations, rewards, terminated, truncated, info), each (B, ...);
        an ended mission restarts on the next step (``NEXT_STEP`` autoreset)."""
        values = self._check(actions)
        restart = self._needs_reset.copy()
        live = ~restart
        move = enc.heading_step_m(values[:, 1], self._step_m)
        _, reward = self._core.step(values[:, 0] - 1, move, live)
        terminated = live & (self._core.slot >= self._core._n_slots)
        if restart.any():
            self._core.restart(restart)
        self._needs_reset = terminated
        self._core.observe()
        truncated = np.zeros(self.num_envs, bool)
        return self._core.encoded(), reward, terminated, truncated, {}


def _build(spec: Scenario | str) -> Mission:
    return build_mission(spec if isinstance(spec, Scenario) else load_scenario(spec))
