"""Many autonomous missions stepped at once: a Gymnasium ``VectorEnv`` over numpy arrays.

Each of the B sub-environments is one mission; a step runs one slot of all of them with array
operations over missions x sensors, by the rules of the single environment's engine
(:func:`skymule.sim.autonomous.next_position` and :mod:`skymule.sim.contract`), value for
value. The observation and action encodings are those of ``skymule/DataMule-v0``
(:mod:`skymule.envs.observation`, ``move="headings"``). Every step:

1. the served sensor delivers min(R dt, Q) bits (:func:`skymule.sim.contract.served_bits`);
2. the heading's goal is made legal (:func:`~skymule.sim.autonomous.legal_goals`, the engine's
   :func:`~skymule.sim.autonomous.legal_goal` vectorised: kept where the fence covers it, else
   the nearest point of the fence) and the UAV flies at most ``max_step_m`` along the
   shortest in-fence path toward it (:meth:`~skymule.flight.navigation.Navigator.steps`,
   concave fences included; with numba, :class:`~skymule.sim.batch_paths.CompiledPaths`,
   the same floats);
3. with ``return_home`` the goal is overridden by home where the engine overrides it
   (:class:`HomeRule`: each mission at its own slot);
4. SNR and rates at the new positions (:class:`~skymule.sim.batch_signal.BatchSignal`): each
   mission's own signal source (any path-loss model, link budget, altitude, shadowing, radio
   maps), its per-slot fading at its own slot, and its rate table.

What it supports (:func:`unsupported_reason` says why a mission is refused): autonomous
missions without faults (``[[faults]]`` need the engine: use :class:`DataMuleEnv`), sharing
one geofence (missions built separately on the same fence are grouped by its geometry) and
the sensor count; everything else may differ per mission (sensors, buffers, home, signal,
rates, speed, altitude, duration, return home). ``tests/test_vector_env.py`` runs single
environments and this one side by side and requires the same observations, rewards,
terminations and positions at every step.

Shadowing and fading are those of each built :class:`~skymule.world.Mission` (drawn once from
its scenario's seed) in every episode: ``reset(seed=...)`` does not redraw them, as
:class:`DataMuleEnv` given that built Mission (given a scenario, the single environment
redraws them at each reset).

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
from skymule.aadm.score import COMPLETE_RTOL
from skymule.envs.datamule import REWARDS, anchors_m
from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator
from skymule.scenario import Scenario, load_scenario
from skymule.sim import batch_paths, contract
from skymule.sim.autonomous import FEASIBILITY_SLACK_M, legal_goals
from skymule.sim.batch import Engine
from skymule.sim.batch_home import BOUND_SLACK_M
from skymule.sim.batch_paths import Paths, Sight
from skymule.sim.batch_signal import BatchSignal
from skymule.world import Mission, build_mission


def unsupported_reason(mission: Mission) -> str | None:
    """Why the vector env cannot step ``mission`` exactly (None when it can)."""
    if mission.mode != "autonomous" or mission.navigator is None or mission.home_m is None:
        return "it is not autonomous (trajectory.mode = 'fixed')"
    if mission.source is None:
        return "it has no signal source"
    if mission.faults is not None:
        return "it has faults ([[faults]]; use DataMuleEnv: the engine applies them)"
    return None


class HomeRule:
    """The engine's return-home override for B missions, each at its own slot.

    :func:`~skymule.sim.autonomous.next_position` steps toward home instead of the goal when
    d(position) + step > budget and d(moved) > budget, with d the in-fence distance home and
    budget = (T - t - 1) step + FEASIBILITY_SLACK_M. The same test, the same floats, but d is
    computed only where it may bind: ``bound`` is an upper bound on d(position) (0 at home,
    exact where last computed, plus one step per slot: no slot takes the UAV farther), the
    straight line a lower bound on d(moved), and d(moved) of a UAV that ends the slot there
    is the next slot's d(position) (the same query).
    """

    def __init__(self, paths: Paths, missions: Sequence[Mission], home_m: np.ndarray) -> None:
        self._paths = paths
        self._home = home_m
        self._sight: Sight = paths.sights(home_m)
        self._step = np.array([m.max_step_m for m in missions], float)
        self._n_slots = np.array([m.n_slots for m in missions], np.int64)
        self.on = np.array([m.return_home for m in missions], bool)
        self._bound = np.zeros(len(missions))
        self._exact = np.full(len(missions), np.nan)

    def restart(self, which: np.ndarray) -> None:
        """The missions ``which`` (mask) start again at home."""
        self._bound[which] = 0.0
        self._exact[which] = np.nan

    def _distances(self, rows: np.ndarray, points: np.ndarray) -> np.ndarray:
        sight = (self._sight[0][rows], self._sight[1][rows])
        return self._paths.travel_distances(points, self._home[rows], sight, checked=False)

    def apply(
        self, slot: np.ndarray, position: np.ndarray, moved: np.ndarray, live: np.ndarray
    ) -> None:
        """Override ``moved`` (B, 2) in place where the engine would, for the ``live`` missions
        (mask) at ``slot`` (B,) starting from ``position`` (B, 2)."""
        step = self._step
        budget = (self._n_slots - slot - 1) * step + FEASIBILITY_SLACK_M
        check = np.flatnonzero(self.on & live & ~(self._bound + step < budget - BOUND_SLACK_M))
        now = self._exact[check]
        self._exact[:] = np.nan  # every UAV moves on
        ask = np.isnan(now)
        if ask.any():
            now[ask] = self._distances(check[ask], position[check[ask]])
        self._bound[check] = now
        self._bound += step
        near = check[now + step[check] > budget[check]]
        if not near.size:
            return
        limit = budget[near]
        after = np.full(near.size, np.inf)  # the straight line decides where it clears the budget
        beeline = np.hypot(
            moved[near, 0] - self._home[near, 0], moved[near, 1] - self._home[near, 1]
        )
        ask = beeline <= limit + BOUND_SLACK_M
        if ask.any():
            after[ask] = self._distances(near[ask], moved[near[ask]])
        back = after > limit
        self._exact[near[~back]] = after[~back]
        rows = near[back]
        if rows.size:
            sight = (self._sight[0][rows], self._sight[1][rows])
            moved[rows] = self._paths.steps(
                position[rows], self._home[rows], step[rows], sight, checked=False
            )


def _same_fence(missions: Sequence[Mission]) -> Navigator:
    """The navigator of the missions' one geofence (SkymuleError if they differ)."""
    navigators = [m.navigator for m in missions if m.navigator is not None]
    keys = [nav.fence_key for nav in navigators]
    for index, key in enumerate(keys):
        if key != keys[0]:
            raise SkymuleError(
                f"vector env: mission {index} ({missions[index].scenario.name!r}) has another "
                "geofence than mission 0; all missions must share one fence"
            )
    return navigators[0]


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
        engine: Engine = "auto",
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
        sizes = [m.n_sensors for m in built]
        if any(size != sizes[0] for size in sizes):
            raise SkymuleError(
                f"vector env: missions have {sorted(set(sizes))} sensors; all missions must "
                f"have the same number (the observation's size)"
            )
        self._navigator = _same_fence(built)
        self._paths = batch_paths.path_queries(self._navigator, engine, "vector env: ")
        self.missions = tuple(built)
        self.reward_mode = reward
        self.num_envs = len(built)
        self.n_sensors = sizes[0]
        low, high = enc.observation_bounds(self.n_sensors)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.MultiDiscrete([self.n_sensors + 1, enc.N_HEADINGS])
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        # per-mission constants
        self._home = np.array([m.home_m for m in built], float)
        self._buffers = np.array([m.buffers_bit for m in built], float)
        self._total = self._buffers.sum(axis=1)
        self._anchors = np.array([anchors_m(m) for m in built], float)
        self._n_slots = np.array([m.n_slots for m in built])
        self._slot_s = np.array([m.slot_s for m in built], float)
        self._step_m = np.array([m.max_step_m for m in built], float)
        self._window_s = np.array([m.score_window_s for m in built], float)
        # slots that may serve (the download window, ``Mission.window_slots``)
        self._serve_slots = np.array(
            [m.n_slots if m.window_slots is None else m.window_slots for m in built], np.int64
        )
        self._signal = BatchSignal(built, self.n_sensors)
        self._home_rule = HomeRule(self._paths, built, self._home)
        # state
        self.position_m = self._home.copy()
        self.slot = np.zeros(self.num_envs, np.int64)
        self.remaining_bit = self._buffers.copy()
        self._completed = np.zeros(self.num_envs, bool)
        self._counted_bit = np.zeros(self.num_envs)
        self._needs_reset = np.zeros(self.num_envs, bool)
        self._snr = np.zeros((self.num_envs, self.n_sensors))
        self._rate = np.zeros((self.num_envs, self.n_sensors))

    # --- physics --------------------------------------------------------------------------------

    def _link(self) -> None:
        """SNR [dB] and rates [bit/s] (B, N) at the positions, each mission at its slot."""
        snr = self._signal.snr_db(self.position_m, self.slot)
        self._snr, self._rate = snr.T, self._signal.rate_bps(snr).T

    def _move(self, heading: np.ndarray, live: np.ndarray) -> np.ndarray:
        """Where the live missions' UAVs end this slot (the others stay)."""
        position, step = self.position_m, self._step_m
        moved = position.copy()
        rows = np.flatnonzero(live & (heading != 0))  # heading 0: stay (no goal)
        goal = legal_goals(
            self._navigator, position[rows] + enc.heading_step_m(heading[rows], step[rows])
        )
        # a step toward the position itself stays put: ask only for the others
        away = (goal[:, 0] != position[rows, 0]) | (goal[:, 1] != position[rows, 1])
        rows, goal = rows[away], goal[away]
        if rows.size:
            # positions and legal goals are inside the fence by construction
            moved[rows] = self._paths.steps(position[rows], goal, step[rows], checked=False)
        self._home_rule.apply(self.slot, position, moved, live)
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
        self._home_rule.restart(which)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)  # the missions are deterministic: the seed changes nothing
        self._restart(np.ones(self.num_envs, bool))
        self._link()
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
        serving = live & (sensor >= 0) & (self.slot < self._serve_slots)  # window open
        rows, cols = np.flatnonzero(serving), sensor[serving]
        bits = np.zeros(self.num_envs)
        bits[rows] = contract.served_bits(
            self._rate[rows, cols], self.remaining_bit[rows, cols], self._slot_s[rows]
        )
        self.remaining_bit[rows, cols] -= bits[rows]
        self.position_m = self._move(values[:, 1], live)
        self.slot += live
        terminated = live & (self.slot >= self._n_slots)
        reward = self._reward(bits, live, terminated)
        self._restart(restart)
        self._needs_reset = terminated
        self._link()
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
