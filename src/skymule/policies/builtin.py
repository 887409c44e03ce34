"""The paper's policies, batched: Greedy, HGAD and HGAD made robust to faults.

Each decides for B missions at once (``batched = True``; a single run is a batch of one) from
:class:`~skymule.policies.base.BatchObservation` arrays, by the rules of ``docs/contract.md``
whose one implementation is :mod:`skymule.rules.contract`:

* **Greedy** serves argmax SNR among servable sensors (ties: the lowest index) and never
  hovers; on an autonomous trajectory it also tours the hover points nearest-first (Alg. 1);
* **HGAD** (fixed trajectory) serves argmax rate (ties: higher SNR, lowest index) and hovers
  where the rate reaches its peak: :class:`contract.HoverState` and :func:`contract.hgad_update`
  (cooldown, trigger, budget min(Q_i / R*_i, max_hover_s)); on an autonomous trajectory it
  follows Alg. 2 (:class:`~skymule.policies.tours.HGADTours`);
* **hgad-robust** adds, on fixed paths, giving up a hover on a silent tower (``fail_slots``
  slots in a row in which the served sensor's buffer did not shrink; it then cools down) and
  choices on the mean of the last ``window_slots`` observed rates (0 for a sensor that reports
  nothing now); on autonomous ones the tours' robust rules. With ``window_slots = 1``,
  ``arrive_m = 0`` and no failed slots it is exactly HGAD.

Parameters may differ per mission (one value, or one per mission: a sweep over
``hover_threshold`` runs as one batch). On fixed paths Greedy and HGAD also have a compiled
twin (:meth:`slot_rule`): the engine then runs their rules inside its compiled loop
(:mod:`skymule.sim.compiled`), value for value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from skymule.policies.base import BatchAction, BatchObservation, MissionContext, stacked
from skymule.policies.tours import GreedyTours, HGADTours, TourGeometry
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR
from skymule.rules.defaults import HOVER_THRESHOLD, MAX_HOVER_S

Priority = Literal["initial", "remaining"]


@dataclass(frozen=True)
class SlotRule:
    """A built-in fixed-path policy's rule as the compiled loop runs it, per mission.

    Attributes:
        hgad: (B,) True for HGAD, False for Greedy.
        threshold_bps: (B, N) HGAD trigger thresholds gamma_i [bit/s].
        peak_rate_bps: (B, N) peak rates R*_i [bit/s].
        max_hover_s: (B,) longest hover [s].
    """

    hgad: np.ndarray
    threshold_bps: np.ndarray
    peak_rate_bps: np.ndarray
    max_hover_s: np.ndarray


def per_mission(value: float | Sequence[float] | np.ndarray, n_missions: int) -> np.ndarray:
    """(B,) a parameter given once or once per mission."""
    values = np.asarray(value, float)
    return np.array(np.broadcast_to(values, (n_missions,)), float)


def _mode(contexts: Sequence[MissionContext]) -> str:
    """The batch's trajectory mode (the engine runs one per batch; the first context tells,
    without making the others: sweeps run thousands of missions a batch)."""
    return contexts[0].mode if len(contexts) else "fixed"


def _goto(
    geometry: TourGeometry, serve: np.ndarray, goal: np.ndarray, target: np.ndarray
) -> BatchAction:
    return BatchAction(serve=serve, goto_m=geometry.goals_m(goal), target=target)


class Greedy:
    """Serve argmax SNR among sensors with data; never hover (autonomous: Alg. 1 tours)."""

    name = "greedy"
    batched = True

    def __init__(self) -> None:
        self._tours: GreedyTours | None = None
        self._geometry: TourGeometry | None = None
        self._shape = (0, 0)

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        """Fixed paths: no state. Autonomous: fresh tours."""
        self._shape = (len(contexts), len(contexts[0].sensor_names) if contexts else 0)
        self._tours = self._geometry = None
        if _mode(contexts) == "autonomous":
            self._geometry = TourGeometry.of(contexts)
            radius = np.array([c.visit_radius_m for c in contexts], float)
            self._tours = GreedyTours(self._geometry, radius)

    def slot_rule(self) -> SlotRule | None:
        """The compiled loop's parameters (fixed paths only)."""
        if self._tours is not None:
            return None
        b, n = self._shape
        return SlotRule(np.zeros(b, bool), np.zeros((b, n)), np.zeros((b, n)), np.zeros(b))

    def act(self, observation: BatchObservation) -> BatchAction:
        rate, snr = observation.rate_bps.T, observation.snr_db.T
        remaining = observation.remaining_bit.T
        if self._tours is None:
            return BatchAction(
                serve=contract.greedy_choice(snr, contract.servable(rate, remaining))
            )
        assert self._geometry is not None
        serve, goal, target = self._tours.act(
            observation.position_m[:, :2], snr, rate, remaining, observation.active
        )
        return _goto(self._geometry, serve, goal, target)


class HGAD:
    """Hover where the rate reaches its peak (module docstring); parameters per mission."""

    name = "hgad"
    batched = True

    def __init__(
        self,
        hover_threshold: float | Sequence[float] | np.ndarray = HOVER_THRESHOLD,
        max_hover_s: float | Sequence[float] | np.ndarray = MAX_HOVER_S,
        priority: Priority | Sequence[Priority] = "initial",
    ) -> None:
        self.hover_threshold = hover_threshold
        self.max_hover_s = max_hover_s
        self.priority = priority
        self._tours: HGADTours | None = None
        self._geometry: TourGeometry | None = None
        self._state = contract.HoverState.start(0, 0)
        self._peak = np.zeros(0)
        self._threshold = np.zeros(0)
        self._max_hover = np.zeros(0)
        self._slot_s = np.zeros(0)

    def _robust_tours(self, contexts: Sequence[MissionContext]) -> tuple[np.ndarray, np.ndarray]:
        """(B,) ``fail_slots`` (0: never) and ``arrive_m`` of the tours (plain HGAD: none)."""
        n = len(contexts)
        return np.zeros(n, np.int64), np.zeros(n)

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        n_missions = len(contexts)
        self._slot_s = np.asarray(stacked(contexts, "slot_s"), float)
        self._max_hover = per_mission(self.max_hover_s, n_missions)
        peak = np.asarray(stacked(contexts, "peak_rate_bps"), float).reshape(n_missions, -1)
        self._tours = self._geometry = None
        if _mode(contexts) == "autonomous":
            self._geometry = TourGeometry.of(contexts)
            priority = np.broadcast_to(np.asarray(self.priority, object), (n_missions,))
            buffers = np.asarray(stacked(contexts, "buffers_bit"), float).reshape(n_missions, -1)
            self._tours = HGADTours(
                self._geometry,
                np.ascontiguousarray(peak.T),
                np.ascontiguousarray(buffers.T),
                self._slot_s,
                self._max_hover,
                priority == "initial",
                *self._robust_tours(contexts),
            )
            return
        # (B, N) as the compiled loop reads them; flat (N * B) for contract.hgad_update
        self._peak_rows = peak
        self._threshold_rows = per_mission(self.hover_threshold, n_missions)[:, None] * peak
        self._peak = np.ascontiguousarray(peak.T).ravel()
        self._threshold = np.ascontiguousarray(self._threshold_rows.T).ravel()
        self._state = contract.HoverState.start(peak.shape[1], n_missions)

    def slot_rule(self) -> SlotRule | None:
        """The compiled loop's parameters (fixed paths only)."""
        if self._tours is not None:
            return None
        hgad = np.ones(self._slot_s.shape[0], bool)
        return SlotRule(hgad, self._threshold_rows, self._peak_rows, self._max_hover)

    def _fixed(self, observation: BatchObservation, rate: np.ndarray) -> BatchAction:
        """One slot on fixed paths: the choice, the hover state, the hover flags."""
        snr, remaining = observation.snr_db.T, observation.remaining_bit.T
        state = self._state
        choice = contract.hgad_choice(rate, snr, contract.servable(rate, remaining))
        sensor = contract.hover_sensor_or(state, choice)
        active = observation.active
        sensor[~active] = NO_SENSOR
        cell = contract.cells(sensor)
        left = remaining.reshape(-1).take(cell)
        rate_served = rate.reshape(-1).take(cell)
        bits = contract.served_bits(rate_served, left, self._slot_s)
        bits[sensor < 0] = 0.0
        hover = contract.hgad_update(
            state,
            sensor=sensor,
            cell=cell,
            rate_bps=rate,
            rate_served_bps=rate_served,
            left_after_bit=left - bits,
            threshold_bps=self._threshold,
            peak_rate_bps=self._peak,
            max_hover_s=self._max_hover,
            slot_s=self._slot_s,
            active=active,
        )
        return BatchAction(serve=sensor, hover=hover)

    def act(self, observation: BatchObservation) -> BatchAction:
        rate = np.ascontiguousarray(observation.rate_bps.T)
        if self._tours is None:
            return self._fixed(observation, rate)
        assert self._geometry is not None
        serve, goal, target = self._tours.act(
            observation.position_m[:, :2],
            observation.snr_db.T,
            rate,
            observation.remaining_bit.T,
            observation.active,
        )
        return _goto(self._geometry, serve, goal, target)


class RobustHGAD(HGAD):
    """HGAD that survives faults (module docstring): silent towers, noisy SNR, GPS error."""

    name = "hgad-robust"

    def __init__(
        self,
        hover_threshold: float | Sequence[float] | np.ndarray = HOVER_THRESHOLD,
        max_hover_s: float | Sequence[float] | np.ndarray = MAX_HOVER_S,
        fail_slots: int | Sequence[int] | np.ndarray = 3,
        window_slots: int = 2,
        arrive_m: float | Sequence[float] | np.ndarray = 10.0,
        priority: Priority | Sequence[Priority] = "initial",
    ) -> None:
        super().__init__(hover_threshold, max_hover_s, priority)
        self.fail_slots = fail_slots
        self.window_slots = window_slots
        self.arrive_m = arrive_m
        self._recent: list[np.ndarray] = []
        self._last = np.zeros(0, np.int64)  # sensor served last slot (NO_SENSOR: none)
        self._before = np.zeros(0)  # its buffer at the start of that slot
        self._fails = np.zeros(0, np.int64)
        self._limit = np.zeros(0, np.int64)

    def _robust_tours(self, contexts: Sequence[MissionContext]) -> tuple[np.ndarray, np.ndarray]:
        n = len(contexts)
        return per_mission(self.fail_slots, n).astype(np.int64), per_mission(self.arrive_m, n)

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        super().reset(contexts)
        n = len(contexts)
        self._recent = []
        self._last = np.full(n, NO_SENSOR, np.int64)
        self._before = np.zeros(n)
        self._fails = np.zeros(n, np.int64)
        self._limit = per_mission(self.fail_slots, n).astype(np.int64)

    def slot_rule(self) -> SlotRule | None:
        return None  # its own rules have no compiled twin

    def act(self, observation: BatchObservation) -> BatchAction:
        if self._tours is not None:
            return super().act(observation)
        remaining = observation.remaining_bit.T
        columns = np.arange(observation.size)
        # a slot failed when the sensor served last slot kept its buffer (nothing arrived)
        served_last = self._last >= 0
        kept = remaining.reshape(-1).take(contract.cells(self._last, columns)) >= self._before
        self._fails = np.where(served_last & kept, self._fails + 1, 0)
        state = self._state
        silent = (state.sensor >= 0) & (self._fails >= self._limit)
        if silent.any():  # the tower went silent: give up the hover; it cools down
            contract.end_hover(state, contract.cells(state.sensor, columns), silent)
            self._fails[silent] = 0
        rate = np.ascontiguousarray(observation.rate_bps.T)
        self._recent = [*self._recent, rate][-self.window_slots :]
        smoothed = np.where(rate > 0, np.mean(self._recent, axis=0), 0.0)
        action = self._fixed(observation, smoothed)
        serve = action.serve
        switched = (self._last >= 0) & (self._last != serve)
        self._fails[switched] = 0
        self._fails[serve < 0] = 0
        self._last = serve.copy()
        self._before = remaining.reshape(-1).take(contract.cells(serve, columns))
        return action
