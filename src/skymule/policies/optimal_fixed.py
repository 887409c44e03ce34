"""``optimal-fixed``: the fixed-trajectory upper bound turned into a slot schedule.

An *offline* planner: it needs the whole signal along the path ahead of time (a recorded
trace, a propagation model or a fitted radio map all give it, as
``MissionContext.track_rate_bps``). In :meth:`OptimalFixed.reset` it solves
:func:`skymule.bounds.fixed_path_bound` with hovering allowed and rounds the time-shared
solution into whole slots that obey the slot contract:

1. *Where to pause*: the relaxed solution spends ``d[k]`` seconds at sample ``k``
   (``d[k] >= dt`` for every sample reached, ``sum d = T dt``). Each sample gets
   ``floor(d[k] / dt)`` slots and the slots left over go to the largest fractional parts
   (largest remainder), so the counts still add up to ``T``. A sample with ``c`` slots is
   ``c - 1`` hover slots and one moving slot; the last sample reached is held to the end.
2. *Whom to serve*: slot by slot, on the planned rates, the sensor with the most planned
   serve time left at this sample (``s[k, i]`` minus ``dt`` per slot already given to it)
   among sensors with data; when no planned time is left, the sensor that delivers the most
   bits this slot, ``min(R dt, Q)``. The schedule is simulated with ``y = min(R dt, Q)`` as it
   is built, so no slot is planned for an empty buffer.

At run time (:meth:`OptimalFixed.act`) it follows the schedule: hover as planned, serve the
planned sensor if it still has data and a link, otherwise the sensor with data that delivers
the most bits now. With the planned signal (no fading) the run equals the plan.

Rounding loses at most a fraction of a slot per sensor on hover time (at that sensor's best
rate) plus the splits of time-shared transit slots; ``tests/test_optimal_fixed.py`` checks
``bound - downloaded <= sum_i max_k R[k, i] dt`` on hand-built cases and that it is never
below HGAD on the fixed presets. ``max_hover_s`` does not apply: pauses are not capped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymule.bounds import fixed_path_bound
from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation

NO_SENSOR = -1
"""``SlotSchedule.serve`` value for a slot in which nobody is served."""

#: Planned serve time below this fraction of a slot counts as none left (LP round-off).
TIME_TOL = 1e-6


@dataclass(frozen=True)
class SlotSchedule:
    """A whole-slot plan for one fixed-trajectory mission.

    Attributes:
        serve: (T,) sensor to serve in slot t, or NO_SENSOR.
        hover: (T,) True where the UAV stays at its sample after slot t.
        sample: (T,) track sample the UAV is at in slot t.
        planned_bit: bits the plan downloads on the planned rates (bit).
        bound_bit: the relaxation's upper bound it was rounded from (bit).
    """

    serve: np.ndarray
    hover: np.ndarray
    sample: np.ndarray
    planned_bit: float
    bound_bit: float


def slot_counts(dwell_s: np.ndarray, slot_s: float, n_slots: int) -> np.ndarray:
    """Whole slots per sample from relaxed dwell times (largest remainder).

    Args:
        dwell_s: (K,) seconds at each sample, summing to ``n_slots * slot_s``; every sample
            reached has at least ``slot_s``.
        slot_s: slot length dt (s).
        n_slots: number of slots T.

    Returns:
        (K,) int slot counts summing to ``n_slots``; every sample with ``dwell >= dt`` (up to
        round-off) gets at least one.
    """
    exact = np.asarray(dwell_s, float) / slot_s
    counts = np.floor(exact + TIME_TOL).astype(np.int64)
    short = n_slots - int(counts.sum())
    if short > 0:  # only samples the relaxation reaches get extra slots
        order = np.argsort(-np.where(exact > 0, exact - counts, -np.inf), kind="stable")
        counts[order[:short]] += 1
    elif short < 0:  # round-off only: take back from the largest counts beyond one slot
        for k in np.argsort(-counts, kind="stable")[:-short]:
            counts[k] -= 1
    return counts


def _slot_choice(left_s: np.ndarray, bits: np.ndarray, slot_s: float) -> int:
    """Sensor for one slot: most planned time left, else most bits now; NO_SENSOR if none.

    ``left_s`` (N,) planned serve time left at this sample (s); ``bits`` (N,) what each
    sensor would deliver this slot, ``min(R dt, Q)`` (bit).
    """
    useful = bits > 0
    if not useful.any():
        return NO_SENSOR
    planned = np.where(useful, left_s, -np.inf)
    best = int(np.argmax(planned))
    if planned[best] > TIME_TOL * slot_s:
        return best
    return int(np.argmax(np.where(useful, bits, -np.inf)))


def plan_schedule(
    rate_bps: np.ndarray, buffers_bit: np.ndarray, slot_s: float, n_slots: int
) -> SlotSchedule:
    """Round the pause-anywhere relaxation into a whole-slot schedule (module docstring).

    Args:
        rate_bps: (K, N) planned rate at each track sample (bit/s).
        buffers_bit: (N,) initial buffers (bit).
        slot_s: slot length dt (s).
        n_slots: number of slots T.
    """
    rate = np.asarray(rate_bps, float)
    relaxed = fixed_path_bound(rate, buffers_bit, slot_s, n_slots, hover_allowed=True)
    counts = slot_counts(relaxed.dwell_time_s, slot_s, n_slots)
    last = int(np.flatnonzero(counts)[-1])
    remaining = np.asarray(buffers_bit, float).copy()
    sample = np.repeat(np.arange(rate.shape[0]), counts)
    serve = np.full(n_slots, NO_SENSOR, dtype=np.int64)
    # a slot moves on only when it is the last one at its sample (and not at the end)
    moves = np.zeros(n_slots, dtype=bool)
    moves[np.cumsum(counts)[:last] - 1] = True
    left_s = relaxed.served_time_s[0].copy()
    for t in range(n_slots):
        k = int(sample[t])
        if t > 0 and k != sample[t - 1]:
            left_s = relaxed.served_time_s[k].copy()
        bits = np.minimum(rate[k] * slot_s, remaining)
        i = _slot_choice(left_s, bits, slot_s)
        if i != NO_SENSOR:
            remaining[i] -= bits[i]
            left_s[i] -= slot_s
            serve[t] = i
    return SlotSchedule(
        serve=serve,
        hover=~moves,
        sample=sample,
        planned_bit=float(np.sum(buffers_bit) - remaining.sum()),
        bound_bit=relaxed.upper_bound_bit,
    )


def most_bits_choice(observation: Observation, slot_s: float) -> int | None:
    """Sensor with data delivering the most bits now, ``min(R dt, Q)``; None if none does."""
    bits = np.minimum(observation.rate_bps * slot_s, observation.remaining_bit)
    if not np.any(bits > 0):
        return None
    return int(np.argmax(bits))


class OptimalFixed:
    """Offline planner: follow the rounded fixed-path bound (see the module docstring)."""

    name = "optimal-fixed"

    def __init__(self) -> None:
        self._slot_s = 1.0
        self._schedule: SlotSchedule | None = None

    @property
    def schedule(self) -> SlotSchedule | None:
        """The plan made in :meth:`reset` (None before)."""
        return self._schedule

    def reset(self, context: MissionContext) -> None:
        if context.mode != "fixed" or context.track_rate_bps is None:
            raise SkymuleError(
                f"policy 'optimal-fixed' plans along a fixed path: trajectory.mode = "
                f"{context.mode!r} gives it no track signal; use trajectory.mode = 'fixed'"
            )
        self._slot_s = context.slot_s
        self._schedule = plan_schedule(
            context.track_rate_bps, context.buffers_bit, context.slot_s, context.n_slots
        )

    def act(self, observation: Observation) -> Action:
        if self._schedule is None:
            raise RuntimeError("OptimalFixed.act before reset")
        t = observation.slot
        if t >= self._schedule.serve.size:
            return Action(serve=most_bits_choice(observation, self._slot_s), hover=True)
        planned = int(self._schedule.serve[t])
        hover = bool(self._schedule.hover[t])
        has_link = (
            planned != NO_SENSOR
            and observation.remaining_bit[planned] > 0
            and observation.rate_bps[planned] > 0
        )
        serve = planned if has_link else most_bits_choice(observation, self._slot_s)
        return Action(serve=serve, hover=hover)
