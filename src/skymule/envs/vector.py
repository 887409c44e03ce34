"""Many autonomous missions stepped at once: a Gymnasium ``VectorEnv`` over numpy arrays.

Each of the B sub-environments is one mission; a step runs one slot of all of them with array
operations over missions x sensors: the served bits come from the slot contract
(:func:`skymule.sim.contract.served_bits`), the SNR from the mission's own path-loss model and
link budget, the rates from its rate table. The observation and action encodings are those of
``skymule/DataMule-v0`` (:mod:`skymule.envs.observation`, ``move="headings"``).

What it supports exactly, and nothing else (:func:`unsupported_reason` says why a mission is
refused): autonomous missions whose geofence is **convex** (or absent), whose signal is a
``fspl`` or ``log-distance`` model without shadowing or fading, sharing one fence, radio, rate
table and sensor count (positions, buffers, home, speed, altitude, duration and return home
may differ). In a convex fence the shortest in-fence path is the straight line, so the
engine's navigation reduces to: a goal outside the fence moves to the nearest point of the
fence; the UAV flies straight toward it, at most ``max_speed_mps * slot_s``; with
``return_home`` it turns home whenever the straight-line distance home would exceed the time
left. These are the rules of :class:`~skymule.sim.autonomous.AutonomousFlight` for such fences
and the tests check that single environments and this one agree step for step. Concave fences
(Lake Wheeler's own) need the navigator's visibility graph: use :class:`DataMuleEnv` there.

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
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

import skymule.envs.observation as enc
from skymule.aadm.score import COMPLETE_RTOL
from skymule.envs.datamule import REWARDS, anchors_m
from skymule.errors import SkymuleError
from skymule.radio.pathloss import FreeSpace, LogDistance
from skymule.radio.sources import ModelSource
from skymule.scenario import Scenario, load_scenario
from skymule.sim import contract
from skymule.sim.autonomous import FEASIBILITY_SLACK_M
from skymule.world import Mission, build_mission

#: A goal within this distance [m] outside the fence counts as inside (the engine's tolerance).
FENCE_TOLERANCE_M = 1e-6


def _fence(mission: Mission) -> Polygon:
    assert mission.navigator is not None
    return mission.navigator.fence


def unsupported_reason(mission: Mission) -> str | None:
    """Why the vector env cannot step ``mission`` exactly (None when it can)."""
    if mission.mode != "autonomous" or mission.navigator is None:
        return "it is not autonomous (trajectory.mode = 'fixed')"
    source = mission.source
    if not isinstance(source, ModelSource) or type(source.pathloss) not in (FreeSpace, LogDistance):
        return "its signal is not an fspl / log-distance model without shadowing"
    if mission.fading_db is not None:
        return "it has per-slot fading"
    fence = _fence(mission)
    if fence.interiors or fence.convex_hull.area - fence.area > 1e-6 * fence.area:
        return "its geofence is not convex (use DataMuleEnv: it navigates around corners)"
    return None


def _same(missions: Sequence[Mission], what: str, values: list[Any]) -> None:
    if any(value != values[0] for value in values[1:]):
        raise SkymuleError(
            f"vector env: missions differ in {what}; all missions must share it "
            f"(first: {values[0]!r})"
        )


class DataMuleVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """B autonomous missions stepped together (see the module docstring for what it supports).

    Args:
        missions: Missions, Scenarios, preset names or paths; one sub-environment each.
        reward: "mbit" or "aadm" (as in :class:`~skymule.envs.datamule.DataMuleEnv`).
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(
        self, missions: Sequence[Mission | Scenario | str], *, reward: str = "mbit"
    ) -> None:
        if not missions:
            raise SkymuleError("vector env: give at least one mission")
        if reward not in REWARDS:
            raise SkymuleError(f"reward = {reward!r} is not allowed; allowed: {', '.join(REWARDS)}")
        built = [m if isinstance(m, Mission) else _build(m) for m in missions]
        for index, mission in enumerate(built):
            reason = unsupported_reason(mission)
            if reason is not None:
                raise SkymuleError(
                    f"vector env: mission {index} ({mission.scenario.name!r}) is not supported: "
                    f"{reason}"
                )
        sources = [m.source for m in built]
        _same(built, "number of sensors", [m.n_sensors for m in built])
        _same(built, "path-loss model", [s.pathloss for s in sources if isinstance(s, ModelSource)])
        _same(built, "link budget", [s.budget for s in sources if isinstance(s, ModelSource)])
        _same(built, "rate table", [(m.rate_table, m.bandwidth_hz) for m in built])
        _same(built, "geofence", [_fence(m).wkb for m in built])
        self.missions = tuple(built)
        self.reward_mode = reward
        first = built[0]
        assert isinstance(first.source, ModelSource)
        self._pathloss, self._budget = first.source.pathloss, first.source.budget
        self.num_envs = len(built)
        self.n_sensors = first.n_sensors
        low, high = enc.observation_bounds(self.n_sensors)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.MultiDiscrete([self.n_sensors + 1, enc.N_HEADINGS])
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        # per-mission constants
        self._home = np.array([m.home_m for m in built], float)
        self._buffers = np.array([m.buffers_bit for m in built], float)
        self._total = self._buffers.sum(axis=1)
        self._sensor = np.array([m.sensor_m for m in built], float)
        self._anchors = np.array([anchors_m(m) for m in built], float)
        self._n_slots = np.array([m.n_slots for m in built])
        self._slot_s = np.array([m.slot_s for m in built], float)
        self._step_m = np.array([m.max_step_m for m in built], float)
        self._altitude = np.array([m.altitude_m for m in built], float)
        self._return_home = np.array([m.return_home for m in built], bool)
        ring = np.asarray(orient(_fence(first), sign=1.0).exterior.coords)[:-1]
        self._edge_a, self._edge_d = ring, np.roll(ring, -1, axis=0) - ring
        self._edge_len = np.hypot(self._edge_d[:, 0], self._edge_d[:, 1])
        # state
        self.position_m = self._home.copy()
        self.slot = np.zeros(self.num_envs, np.int64)
        self.remaining_bit = self._buffers.copy()
        self._completed = np.zeros(self.num_envs, bool)
        self._counted_bit = np.zeros(self.num_envs)
        self._window_s = np.array([m.score_window_s for m in built], float)
        self._needs_reset = np.zeros(self.num_envs, bool)
        self._snr = np.zeros((self.num_envs, self.n_sensors))
        self._rate = np.zeros((self.num_envs, self.n_sensors))

    # --- physics --------------------------------------------------------------------------------

    def _link(self, position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, N) SNR [dB] and rate [bit/s] at ``position_m`` (B, 2), as the source computes.

        The models depend on the UAV-sensor difference vector only, so evaluating them at the
        differences against a sensor at the origin gives the same numbers per pair.
        """
        batch, n = self.num_envs, self.n_sensors
        diff = np.empty((batch, n, 3))
        diff[..., :2] = position_m[:, None, :] - self._sensor[..., :2]
        diff[..., 2] = self._altitude[:, None] - self._sensor[..., 2]
        loss = self._pathloss.loss_db(diff.reshape(-1, 3), np.zeros((1, 3)))
        snr = self._budget.snr_db(loss).reshape(batch, n)
        return snr, self.missions[0].rate_bps(snr)

    def _legal_goal(self, goal: np.ndarray) -> np.ndarray:
        """Goals outside the (convex) fence replaced by the nearest point of the fence."""
        rel = goal[:, None, :] - self._edge_a[None]  # (B, K, 2)
        d = self._edge_d[None]
        cross = (d[..., 0] * rel[..., 1] - d[..., 1] * rel[..., 0]) / self._edge_len
        inside = np.all(cross >= -FENCE_TOLERANCE_M, axis=1)
        if inside.all():
            return goal
        t = np.clip(np.sum(rel * d, axis=2) / self._edge_len**2, 0.0, 1.0)
        nearest = self._edge_a[None] + t[..., None] * d  # (B, K, 2)
        dist = np.hypot(*(nearest - goal[:, None, :]).transpose(2, 0, 1))
        best = nearest[np.arange(len(goal)), np.argmin(dist, axis=1)]
        return np.where(inside[:, None], goal, best)

    @staticmethod
    def _advance(start: np.ndarray, goal: np.ndarray, step_m: np.ndarray) -> np.ndarray:
        """Straight toward ``goal``, at most ``step_m``; exactly ``goal`` when within reach."""
        delta = goal - start
        seg = np.hypot(delta[:, 0], delta[:, 1])
        short = step_m < seg
        fraction = np.where(short, step_m / np.where(short, seg, 1.0), 1.0)
        return np.where(short[:, None], start + fraction[:, None] * delta, goal)

    def _move(self, heading: np.ndarray) -> np.ndarray:
        position, step = self.position_m, self._step_m
        goal = self._legal_goal(position + enc.heading_step_m(heading, step))
        goal = np.where((heading == 0)[:, None], position, goal)
        moved = self._advance(position, goal, step)
        budget = (self._n_slots - self.slot - 1) * step + FEASIBILITY_SLACK_M
        to_home = self._home - position
        near_limit = np.hypot(to_home[:, 0], to_home[:, 1]) + step > budget
        after = self._home - moved
        override = self._return_home & near_limit & (np.hypot(after[:, 0], after[:, 1]) > budget)
        if override.any():
            moved = np.where(override[:, None], self._advance(position, self._home, step), moved)
        return moved

    # --- gymnasium API --------------------------------------------------------------------------

    def _observe(self) -> np.ndarray:
        time_left = (self._n_slots - self.slot) * self._slot_s
        return enc.encode(
            self.position_m, time_left, self._snr, self._rate, self.remaining_bit, self._anchors
        )

    def _restart(self, which: np.ndarray) -> None:
        self.position_m[which] = self._home[which]
        self.slot[which] = 0
        self.remaining_bit[which] = self._buffers[which]
        self._completed[which] = False
        self._counted_bit[which] = 0.0
        self._needs_reset[which] = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)  # the missions are deterministic: the seed changes nothing
        self._restart(np.ones(self.num_envs, bool))
        self._snr, self._rate = self._link(self.position_m)
        return self._observe(), {}

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
        values = self._check(actions)
        restart = self._needs_reset.copy()
        live = ~restart
        sensor = values[:, 0] - 1
        serving = live & (sensor >= 0)
        rows, cols = np.flatnonzero(serving), sensor[serving]
        bits = np.zeros(self.num_envs)
        bits[rows] = contract.served_bits(
            self._rate[rows, cols], self.remaining_bit[rows, cols], self._slot_s[rows]
        )
        self.remaining_bit[rows, cols] -= bits[rows]
        moved = self._move(np.where(live, values[:, 1], 0))
        self.position_m = np.where(live[:, None], moved, self.position_m)
        self.slot += live
        terminated = live & (self.slot >= self._n_slots)
        reward = self._reward(bits, live, terminated)
        self._restart(restart)
        self._needs_reset = terminated
        self._snr, self._rate = self._link(self.position_m)
        truncated = np.zeros(self.num_envs, bool)
        return self._observe(), reward, terminated, truncated, {}

    def _reward(self, bits: np.ndarray, live: np.ndarray, terminated: np.ndarray) -> np.ndarray:
        if self.reward_mode == "mbit":
            return bits / enc.BITS_PER_MBIT
        # the AADM score in force (skymule.aadm.score), spread over the episode as in DataMuleEnv
        total, window = self._total, self._window_s
        counted = live & ((self.slot - 1) * self._slot_s < window - 1e-9)
        got = np.where(counted, bits, 0.0)
        self._counted_bit += got
        has = total > 0
        reward = np.where(has, 100.0 * got / np.where(has, total, 1.0), 0.0)
        first = live & (self.slot == 1) & ~has  # nothing to download: complete at once
        reward = np.where(first, 100.0 + window, reward)
        emptied = counted & ~self._completed & has
        emptied &= self._counted_bit >= total * (1.0 - COMPLETE_RTOL)
        self._completed |= emptied
        bonus = np.maximum(0.0, window - self.slot * self._slot_s)
        return reward + np.where(emptied, bonus, 0.0)


def _build(spec: Scenario | str) -> Mission:
    return build_mission(spec if isinstance(spec, Scenario) else load_scenario(spec))
