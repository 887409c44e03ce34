"""``optimal-fixed``: the fixed-trajectory upper bound turned into a slot schedule.

An *offline* planner: it needs the whole signal along the path ahead of time (a recorded
trace, a propagation model or a fitted radio map all give it, as
``MissionContext.track_rate_bps``). In :meth:`OptimalFixed.reset` it solves
:func:`skymule.bounds.fixed_path_bound` with hovering allowed and rounds the time-shared
solution into whole slots that obey the slot contract:

0. *A coherent optimum*: the bound's LP is degenerate when buffers bind (many transit
   assignments drain them equally well) and its vertex may alternate sensors from sample to
   sample. :func:`coherent_solution` re-solves it for the same last sample with the bits held
   at the bound's value and :func:`contiguity_weights` (link near its best, sample near the
   sensor's best) as the objective: contiguous blocks, a sample split between sensors only
   where buffer caps make it pay.
1. *Where to pause*: the relaxed solution spends ``d[k]`` seconds at sample ``k``
   (``d[k] >= dt`` for every sample reached, ``sum d = T dt``). Each sample gets
   ``floor(d[k] / dt)`` slots and the slots left over go to the largest fractional parts
   (largest remainder), so the counts still add up to ``T``. A sample with ``c`` slots is
   ``c - 1`` hover slots and one moving slot; the last sample reached is held to the end.
2. *Whom to serve* (:func:`assign_slots`): slot by slot, on the planned rates, the previous
   slot's sensor while it has planned serve time left at this sample (``s[k, i]`` minus ``dt``
   per slot already given to it), else the one with the most left (sensors planned at the
   next sample last), among sensors with data; with no planned time left, the previous sensor
   if it has data, else the one delivering the most bits, ``min(R dt, Q)``.
3. *Fewer handovers* (post-passes on whole slots, none lowers the capped download
   ``sum_i min(Q_i, carried_i)``): :func:`merge_alternations` re-splits runs of blocks
   alternating between two sensors into two blocks; :func:`shift_boundaries` hands block-edge
   slots to a neighbouring sensor with data left where the owner fills its buffer anyway;
   :func:`drop_empty_slots` simulates ``y = min(R dt, Q)`` and gives any slot planned for an
   empty buffer to the previous sensor (else the most bits), so no slot is planned for an
   empty buffer and plan equals run.

At run time (:meth:`OptimalFixed.act`) it follows the schedule: hover as planned, serve the
planned sensor if it still has data and a link, otherwise the sensor with data that delivers
the most bits now. With the planned signal (no fading) the run equals the plan.

Rounding loses at most a fraction of a slot per sensor on hover time (at that sensor's best
rate) plus the splits of time-shared transit slots; ``tests/test_optimal_fixed.py`` checks
``bound - downloaded <= sum_i max_k R[k, i] dt`` on hand-built and random cases, that it is
never below HGAD on the fixed presets and that its handovers there stay within twice HGAD's
(paper-sim-fixed 5 vs 7, aadm-default 13 vs 9). ``max_hover_s`` does not apply: pauses are
not capped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from skymule.bounds.fixed import fixed_path_bound
from skymule.bounds.result import BoundResult
from skymule.errors import SkymuleError
from skymule.policies.base import Action, MissionContext, Observation
from skymule.rules.contract import served_bits

NO_SENSOR = -1
"""``SlotSchedule.serve`` value for a slot in which nobody is served."""

#: Planned serve time below this fraction of a slot counts as none left (LP round-off).
TIME_TOL = 1e-6

#: The coherent re-solve keeps the relaxation's bits to this relative tolerance.
LP_REL_TOL = 1e-9

#: Weight of "near the sensor's best sample" against the link-quality ratio (tie-break only).
CONTIGUITY_EPS = 1e-3

#: A boundary shift must gain more than this (bit).
GAIN_TOL_BIT = 1e-6


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


def contiguity_weights(rate_bps: np.ndarray) -> np.ndarray:
    """Tie-break preference for serving sensor ``i`` at sample ``k`` (dimensionless, >= 0).

    ``rate_bps`` is ``(K, N)`` (bit/s) over the samples reached. The weight is
    ``R[k, i] / max_k R[k, i]`` (how close the link is to its best along the path) plus
    ``CONTIGUITY_EPS`` times ``1 - |k - k*_i| / K`` (closer along the path to the sensor's best
    sample ``k*_i``), and 0 where ``R[k, i] = 0``. Both terms vary smoothly along the path, so
    the sensor that maximises a weighted weight changes only a few times: contiguous blocks.
    Returns ``(K, N)``.
    """
    rate = np.asarray(rate_bps, float)
    best = rate.max(axis=0)
    ratio = np.divide(rate, best, out=np.zeros_like(rate), where=best > 0)
    along = np.abs(np.arange(rate.shape[0])[:, None] - np.argmax(rate, axis=0)[None, :])
    return np.where(rate > 0, ratio + CONTIGUITY_EPS * (1.0 - along / rate.shape[0]), 0.0)


def coherent_solution(
    rate_bps: np.ndarray, buffers_bit: np.ndarray, slot_s: float, n_slots: int, relaxed: BoundResult
) -> tuple[np.ndarray, np.ndarray]:
    """Among the relaxation's optimal solutions, one that serves sensors in contiguous blocks.

    The bound's LP is highly degenerate when buffers bind (any transit assignment that drains
    them is optimal), and its vertex may alternate sensors from sample to sample. This re-solves
    the prefix LP of :func:`skymule.bounds.fixed_path_bound` for the same last sample
    ``L = relaxed.last_sample`` (one time-shared slot at each sample ``0..L``, plus
    ``(T - L - 1) dt`` of hover at each sensor's best sample) with the bits held at the
    relaxation's value (to ``LP_REL_TOL``) and :func:`contiguity_weights` as the objective. A
    vertex splits at most ``N + 2`` samples between sensors: only where buffer caps make it pay.

    Args:
        rate_bps: ``(K, N)`` rate at each track sample (bit/s).
        buffers_bit: ``(N,)`` initial buffers (bit).
        slot_s: slot length dt (s).
        n_slots: number of slots T.
        relaxed: the pause-anywhere bound for these inputs.

    Returns:
        ``(served_s (K, N), dwell_s (K,))`` like ``relaxed.served_time_s`` and
        ``relaxed.dwell_time_s`` (s); the relaxation's own solution if the LP fails.
    """
    rate = np.asarray(rate_bps, float)
    last = relaxed.last_sample
    pre = rate[: last + 1]
    k, n = pre.shape
    best, best_at = pre.max(axis=0), np.argmax(pre, axis=0)
    bits = float(np.sum(rate * relaxed.served_time_s))
    bit_rows = sp.hstack([sp.csr_array(pre.ravel()[None, :]), sp.csr_array(best[None, :])])
    a_buf = sp.csr_array(
        (pre.ravel(), (np.tile(np.arange(n), k), np.arange(k * n))), shape=(n, k * n)
    )
    a_ub = sp.vstack(
        [
            sp.hstack([sp.kron(sp.eye_array(k), np.ones((1, n))), sp.csr_array((k, n))]),
            sp.hstack([sp.csr_array((1, k * n)), np.ones((1, n))]),
            sp.hstack([a_buf, sp.diags_array(best)]),
            -bit_rows,
        ],
        format="csr",
    )
    b_ub = np.concatenate(
        [
            np.full(k, slot_s),
            [(n_slots - 1 - last) * slot_s],
            np.asarray(buffers_bit, float),
            [-(bits - LP_REL_TOL * max(bits, 1.0))],
        ]
    )
    weight = contiguity_weights(pre)
    hover_weight = weight[best_at, np.arange(n)]
    res = linprog(
        -np.concatenate([weight.ravel(), hover_weight]),
        A_ub=a_ub,
        b_ub=b_ub,
        bounds=(0, None),
        method="highs",
    )
    if res.status != 0:
        return relaxed.served_time_s, relaxed.dwell_time_s
    x = np.clip(res.x, 0.0, None)
    served = np.zeros_like(rate)
    served[:k] = np.reshape(x[: k * n], (k, n))
    np.add.at(served, (best_at, np.arange(n)), x[k * n :])
    dwell = np.zeros(rate.shape[0])
    dwell[:k] = slot_s
    np.add.at(dwell, best_at, x[k * n :])
    dwell[last] += n_slots * slot_s - dwell.sum()
    return served, dwell


def _slot_choice(
    left_s: np.ndarray, bits: np.ndarray, slot_s: float, previous: int, upcoming: np.ndarray
) -> int:
    """Sensor for one slot, sticky: keep the previous sensor while its planned time lasts.

    ``left_s`` (N,) planned serve time left at this sample (s); ``bits`` (N,) what each sensor
    would deliver this slot, ``min(R dt, Q)`` (bit); ``previous`` the sensor served in the
    slot before (or NO_SENSOR); ``upcoming`` (N,) bool, planned at the next sample. Order:
    the previous sensor if it has planned time here; else the one with the most planned time
    left, sensors planned at the next sample last (so their block carries on there); else,
    with no planned time left, the previous sensor if it has data, then the most bits now.
    Returns NO_SENSOR when no sensor would deliver anything.
    """
    useful = bits > 0
    if not useful.any():
        return NO_SENSOR
    keep = previous != NO_SENSOR and bool(useful[previous])
    planned = useful & (left_s > TIME_TOL * slot_s)
    if keep and planned[previous]:
        return previous
    if planned.any():
        pool = planned & ~upcoming if (planned & ~upcoming).any() else planned
        return int(np.argmax(np.where(pool, left_s, -np.inf)))
    if keep:
        return previous
    return int(np.argmax(np.where(useful, bits, -np.inf)))


def assign_slots(
    rate_bps: np.ndarray,
    buffers_bit: np.ndarray,
    slot_s: float,
    sample: np.ndarray,
    served_s: np.ndarray,
) -> np.ndarray:
    """Round planned serve times into one sensor per slot (:func:`_slot_choice`), simulated.

    Args:
        rate_bps: ``(K, N)`` planned rate at each sample (bit/s).
        buffers_bit: ``(N,)`` initial buffers (bit).
        slot_s: slot length dt (s).
        sample: ``(T,)`` sample of each slot (non-decreasing).
        served_s: ``(K, N)`` planned serve time per sample and sensor (s).

    Returns:
        ``(T,)`` sensor per slot or NO_SENSOR; no slot goes to an empty buffer.
    """
    rate = np.asarray(rate_bps, float)
    remaining = np.asarray(buffers_bit, float).copy()
    planned_at = served_s > TIME_TOL * slot_s
    planned_at = np.vstack([planned_at, np.zeros((1, rate.shape[1]), bool)])
    serve = np.full(sample.size, NO_SENSOR, dtype=np.int64)
    previous = NO_SENSOR
    left_s = served_s[0].copy()
    for t, k in enumerate(sample.tolist()):
        if t > 0 and k != sample[t - 1]:
            left_s = served_s[k].copy()
        bits = served_bits(rate[k], remaining, slot_s)
        i = _slot_choice(left_s, bits, slot_s, previous, planned_at[k + 1])
        if i != NO_SENSOR:
            remaining[i] -= bits[i]
            left_s[i] -= slot_s
            serve[t] = previous = i
    return serve


def _raw_bits(serve: np.ndarray, slot_bit: np.ndarray) -> np.ndarray:
    """(N,) bits each sensor's slots could carry, ignoring buffers: sum of ``R dt`` (bit)."""
    active = serve != NO_SENSOR
    n = slot_bit.shape[1]
    return np.bincount(serve[active], slot_bit[active, serve[active]], minlength=n)


def shift_boundaries(
    serve: np.ndarray, slot_rate_bps: np.ndarray, slot_s: float, buffers_bit: np.ndarray
) -> np.ndarray:
    """Give block-edge slots to a neighbouring sensor with data left, where that costs nothing.

    A slot ``t`` serving ``j`` next to a slot serving ``i`` moves to ``i`` when ``j`` still
    fills its buffer without it (its slots carry at least ``Q_j + R[t, j] dt``) and ``i`` has
    data left; the move with the largest gain ``min(R[t, i] dt, Q_i - carried_i)`` first, until
    none gains. Handovers never increase (``t`` joins the neighbouring block).

    Args:
        serve: ``(T,)`` sensor per slot or NO_SENSOR.
        slot_rate_bps: ``(T, N)`` planned rate of sensor ``i`` in slot ``t`` (bit/s).
        slot_s: slot length dt (s).
        buffers_bit: ``(N,)`` initial buffers (bit).

    Returns:
        A new ``(T,)`` serve array.
    """
    slot_bit = slot_rate_bps * slot_s
    serve = serve.copy()
    buf = np.asarray(buffers_bit, float)
    t_all = np.arange(serve.size)
    for _ in range(serve.size):
        carried = _raw_bits(serve, slot_bit)
        short = np.clip(buf - carried, 0.0, None)
        surplus = np.append(carried - buf, np.inf)  # index NO_SENSOR (-1): an idle slot
        own = np.where(serve != NO_SENSOR, slot_bit[t_all, serve], 0.0)
        free = surplus[serve] >= own
        best_gain, best_t, best_i = 0.0, -1, NO_SENSOR
        for offset in (-1, 1):
            nbr = np.full(serve.size, NO_SENSOR)
            src = t_all + offset
            ok = (src >= 0) & (src < serve.size)
            nbr[ok] = serve[src[ok]]
            valid = free & (nbr != NO_SENSOR) & (nbr != serve)
            gain = served_bits(slot_rate_bps[t_all, nbr], short[nbr], slot_s)
            gain = np.where(valid, gain, 0.0)
            t = int(np.argmax(gain))
            if gain[t] > best_gain:
                best_gain, best_t, best_i = float(gain[t]), t, int(nbr[t])
        if best_gain <= GAIN_TOL_BIT:
            break
        serve[best_t] = best_i
    return serve


def _blocks(serve: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of equal entries: ``(start (B,), stop (B,), sensor (B,))`` (slot indices)."""
    start = np.flatnonzero(np.diff(serve, prepend=serve[0] - 1) != 0)
    stop = np.append(start[1:], serve.size)
    return start, stop, serve[start]


def _best_cut(
    window_bit: np.ndarray, outside_bit: np.ndarray, buffers_bit: np.ndarray
) -> tuple[float, int]:
    """Best split of a window into a block of sensor 0 then a block of sensor 1.

    ``window_bit`` is ``(W, 2)``: ``R dt`` of the two sensors in each window slot (bit);
    ``outside_bit`` ``(2,)`` what their slots outside the window carry, ``buffers_bit`` ``(2,)``.
    Returns ``(delivered bit, cut)``: slots ``[0, cut)`` serve sensor 0 and the rest sensor 1;
    among equal totals the cut leaving both sensors the most spare bits.
    """
    first = outside_bit[0] + np.concatenate([[0.0], np.cumsum(window_bit[:, 0])])
    second = outside_bit[1] + np.concatenate([np.cumsum(window_bit[::-1, 1])[::-1], [0.0]])
    delivered = np.minimum(first, buffers_bit[0]) + np.minimum(second, buffers_bit[1])
    spare = np.minimum(first - buffers_bit[0], second - buffers_bit[1])
    top = delivered >= delivered.max() - GAIN_TOL_BIT
    cut = int(np.argmax(np.where(top, spare, -np.inf)))
    return float(delivered[cut]), cut


def _alternating_windows(who: np.ndarray) -> list[tuple[int, int]]:
    """Block ranges ``[first, last]`` (``last - first >= 2``) alternating between two sensors.

    ``who`` is ``(B,)``, the sensor of each block. Longest windows first (they merge most).
    """
    triple = (who[2:] == who[:-2]) & (who[:-2] != NO_SENSOR) & (who[1:-1] != NO_SENSOR)
    windows = []
    for first in np.flatnonzero(triple).tolist():
        last = first + 2
        while last < who.size and triple[last - 2]:
            windows += [(first, last)]
            last += 1
    return sorted(windows, key=lambda w: w[0] - w[1])


def _merge_window(
    serve: np.ndarray,
    slot_bit: np.ndarray,
    buffers_bit: np.ndarray,
    lo: int,
    hi: int,
    pair: np.ndarray,
) -> np.ndarray | None:
    """Slots ``[lo, hi)`` re-split into two blocks of the ``(2,)`` ``pair``, or None if it loses.

    Both orders are tried (:func:`_best_cut`); the result keeps the pair's capped download
    ``min(Q, carried)`` (to ``GAIN_TOL_BIT``).
    """
    carried = _raw_bits(serve, slot_bit)[pair]
    window = slot_bit[lo:hi][:, pair]
    inside = np.array([window[serve[lo:hi] == i, j].sum() for j, i in enumerate(pair)])
    now = float(np.minimum(carried, buffers_bit[pair]).sum())
    best = None
    for order in (np.array([0, 1]), np.array([1, 0])):
        got, cut = _best_cut(window[:, order], (carried - inside)[order], buffers_bit[pair][order])
        if got >= now - GAIN_TOL_BIT and (best is None or got > best[0]):
            best = (got, cut, pair[order])
    if best is None:
        return None
    merged = serve.copy()
    merged[lo : lo + best[1]] = best[2][0]
    merged[lo + best[1] : hi] = best[2][1]
    return merged


def merge_alternations(
    serve: np.ndarray, slot_bit: np.ndarray, buffers_bit: np.ndarray
) -> np.ndarray:
    """Merge runs of blocks alternating between two sensors into at most two blocks.

    A window of at least three blocks alternating ``A B A ...`` (longest first) is re-split at
    one cut into ``A...A B...B`` or ``B...B A...A`` (both orders, every cut, via cumulative
    sums); the best split replaces the window when the two sensors' capped download
    ``min(Q, carried)`` does not drop. Repeats until no window merges; each merge removes at
    least one handover, so it ends.

    Args:
        serve: ``(T,)`` sensor per slot or NO_SENSOR.
        slot_bit: ``(T, N)`` bits sensor ``i`` could deliver in slot ``t``, ``R dt`` (bit).
        buffers_bit: ``(N,)`` initial buffers (bit).

    Returns:
        A new ``(T,)`` serve array.
    """
    serve = serve.copy()
    buf = np.asarray(buffers_bit, float)
    while True:
        start, stop, who = _blocks(serve)
        for first, last in _alternating_windows(who):
            lo, hi = int(start[first]), int(stop[last])
            merged = _merge_window(serve, slot_bit, buf, lo, hi, who[first : first + 2])
            if merged is not None:
                serve = merged
                break
        else:
            return serve


def drop_empty_slots(
    serve: np.ndarray, slot_rate_bps: np.ndarray, slot_s: float, buffers_bit: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate ``y = min(R dt, Q)``; a slot planned for an empty buffer goes elsewhere.

    Such a slot serves the previous slot's sensor if it has data, else the sensor with data
    delivering the most bits, else nobody. Returns ``(serve (T,), remaining (N,) bit)``.
    """
    serve = serve.copy()
    remaining = np.asarray(buffers_bit, float).copy()
    previous = NO_SENSOR
    for t in range(serve.size):
        bits = served_bits(slot_rate_bps[t], remaining, slot_s)
        i = int(serve[t])
        if i == NO_SENSOR or bits[i] <= 0:
            keep = previous != NO_SENSOR and bits[previous] > 0
            i = previous if keep else int(np.argmax(bits)) if np.any(bits > 0) else NO_SENSOR
        serve[t] = i
        if i != NO_SENSOR:
            remaining[i] -= bits[i]
            previous = i
    return serve, remaining


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
    served_s, dwell_s = coherent_solution(rate, buffers_bit, slot_s, n_slots, relaxed)
    counts = slot_counts(dwell_s, slot_s, n_slots)
    last = int(np.flatnonzero(counts)[-1])
    sample = np.repeat(np.arange(rate.shape[0]), counts)
    # a slot moves on only when it is the last one at its sample (and not at the end)
    moves = np.zeros(n_slots, dtype=bool)
    moves[np.cumsum(counts)[:last] - 1] = True
    slot_rate = rate[sample]
    serve = assign_slots(rate, buffers_bit, slot_s, sample, served_s)
    serve = merge_alternations(serve, slot_rate * slot_s, buffers_bit)
    serve = shift_boundaries(serve, slot_rate, slot_s, buffers_bit)
    serve, remaining = drop_empty_slots(serve, slot_rate, slot_s, buffers_bit)
    return SlotSchedule(
        serve=serve,
        hover=~moves,
        sample=sample,
        planned_bit=float(np.sum(buffers_bit) - remaining.sum()),
        bound_bit=relaxed.upper_bound_bit,
    )


def most_bits_choice(observation: Observation, slot_s: float) -> int | None:
    """Sensor with data delivering the most bits now, ``min(R dt, Q)``; None if none does.

    Deliberately not HGAD's choice (:func:`skymule.rules.contract.hgad_choice`, the best
    rate): off its plan, the schedule takes the most bits this slot, so a nearly empty buffer
    on the best link loses to a full one on a slightly worse link
    (``tests/test_optimal_fixed.py::test_off_plan_choice_takes_the_most_bits_not_hgads``).
    """
    bits = served_bits(observation.rate_bps, observation.remaining_bit, slot_s)
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
