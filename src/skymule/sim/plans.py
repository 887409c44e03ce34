"""The planner's look-ahead, batched: predicted outcome of many candidate tours in one call.

The planner (:mod:`skymule.policies.planner`) ranks candidate tours and tunes their hover
times by simulating each on its predicted rates. :func:`simulate_plans` runs a batch of P
plans; with numba installed (``pip install skymule[fast]``) it is compiled, else the same
function runs as plain Python. Served bits come from :func:`skymule.rules.contract.served_bits`.

A plan visits hover points in ``order``, staying ``extra`` slots at each, then (with return
home) flies home; every slot the UAV serves the sensor it is staying at while that one has
data, else the highest predicted rate among sensors with data. Legs are given as tables: a
leg u takes ``leg_slots[u]`` slots, and its ``leg_slots[u] - 1`` in-between points have
predicted rates ``leg_rates[leg_row[u]:]`` (none when ``leg_has_rates[u]`` is False: nothing
is served there).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np

from skymule.rules import contract
from skymule.sim import compiled


def simulate_plans(
    slot: int,
    n_slots: int,
    slot_s: float,
    return_home: bool,
    remaining: np.ndarray,
    start_rates: np.ndarray,
    hover_rates: np.ndarray,
    home_rates: np.ndarray,
    leg_slots: np.ndarray,
    leg_has_rates: np.ndarray,
    leg_row: np.ndarray,
    leg_rates: np.ndarray,
    order: np.ndarray,
    extra: np.ndarray,
    start: np.ndarray,
    length: np.ndarray,
    legs: np.ndarray,
    bits_out: np.ndarray,
    done_out: np.ndarray,
    arrival_out: np.ndarray,
) -> None:
    """Predicted bits, done slot and buffer at each arrival of every plan (see module doc).

    Rates: ``start_rates`` (N,) where the UAV is, ``hover_rates`` (N, N) at hover point j (row),
    ``home_rates`` (N,) at home. Outputs: ``bits_out`` (P,), ``done_out`` (P,), ``arrival_out``
    (S,) (0 for stops not reached).
    """
    n = remaining.shape[0]
    q = np.empty(n)
    none = -1
    for p in range(start.shape[0]):
        q[:] = remaining
        total = 0.0
        done = n_slots
        if not has_data(q):
            done = slot
        t = slot
        departing = start_rates
        prefer = none
        leg = start[p] + p
        for pos in range(start[p], start[p] + length[p]):
            arrival_out[pos] = 0.0
        for pos in range(start[p], start[p] + length[p]):
            j = order[pos]
            u = legs[leg]
            leg += 1
            if leg_slots[u] > 0:
                if t >= n_slots:
                    break
                t, total, done = fly_leg(
                    q, departing, prefer, leg_rates, leg_row[u], leg_has_rates[u], leg_slots[u],
                    none, slot_s, t, n_slots, total, done,
                )  # fmt: skip
            arrival_out[pos] = q[j]
            stay = extra[pos]
            departing = hover_rates[j]
            prefer = j
            while t < n_slots and stay > 0 and q[j] > 0:
                total, done = serve(q, hover_rates[j], j, slot_s, t, n_slots, total, done)
                stay -= 1
                t += 1
                if q[j] <= 0:  # emptied while staying: that slot was the departure slot
                    departing = np.zeros(n)
                    t -= 1
                    break
        u = legs[start[p] + p + length[p]]  # the leg home from the last stop reached
        final = departing
        if return_home and leg_slots[u] > 0:
            if t < n_slots:
                t, total, done = fly_leg(
                    q, departing, prefer, leg_rates, leg_row[u], leg_has_rates[u], leg_slots[u],
                    none, slot_s, t, n_slots, total, done,
                )  # fmt: skip
            final = home_rates
        while t < n_slots and has_data(q) and final.max() > 0:
            total, done = serve(q, final, none, slot_s, t, n_slots, total, done)
            t += 1
        bits_out[p] = total
        done_out[p] = done


def has_data(q: np.ndarray) -> bool:
    """True if any buffer holds data (a loop: numba compiles no generator in ``any``)."""
    for i in range(q.shape[0]):  # noqa: SIM110
        if q[i] > 0:
            return True
    return False


def serve(
    q: np.ndarray,
    rates: np.ndarray,
    prefer: int,
    slot_s: float,
    t: int,
    n_slots: int,
    total: float,
    done: int,
) -> tuple[float, int]:
    """One predicted slot: serve ``prefer`` while it has data, else the best rate with data,
    ties to the lowest index (:func:`skymule.rules.contract.rate_choice` for one flight, its
    compiled twin: ``tests/test_plans.py::test_serve_picks_as_rate_choice``).

    Updates ``q``; returns the new (bits so far, done slot).
    """
    if prefer >= 0 and q[prefer] > 0:
        i = prefer
    else:
        # np.argmax of where(q > 0, rates, -1): the first maximum, or the first NaN
        i = 0
        best = rates[0] if q[0] > 0 else -1.0
        if best == best:
            for k in range(1, q.shape[0]):
                value = rates[k] if q[k] > 0 else -1.0
                if value != value:
                    i = k
                    break
                if value > best:
                    i, best = k, value
        best = rates[i] if q[i] > 0 else -1.0
        if best <= 0:
            return total, done
    got = contract.served_bits(rates[i], q[i], slot_s)
    q[i] -= got
    total += got
    if done == n_slots and not has_data(q):
        done = t + 1
    return total, done


def fly_leg(
    q: np.ndarray,
    departing: np.ndarray,
    prefer: int,
    leg_rates: np.ndarray,
    first_row: int,
    has_rates: bool,
    n_leg_slots: int,
    none: int,
    slot_s: float,
    t: int,
    n_slots: int,
    total: float,
    done: int,
) -> tuple[int, float, int]:
    """The slots of one flight leg from slot ``t``: the departure slot serves at the rates of
    the point left (``prefer`` first), the others at the leg's en-route rates (rows
    ``first_row``.. of ``leg_rates``), until the leg or the mission ends."""
    total, done = serve(q, departing, prefer, slot_s, t, n_slots, total, done)
    t += 1
    for k in range(n_leg_slots - 1):
        if t >= n_slots:
            break
        if has_rates:
            total, done = serve(q, leg_rates[first_row + k], none, slot_s, t, n_slots, total, done)
        t += 1
    return t, total, done


@cache
def plans_kernel() -> Callable[..., None]:
    """:func:`simulate_plans`, compiled by numba when it is installed (else plain Python)."""
    if not compiled.available():
        return simulate_plans
    return compiled.jit(simulate_plans, (contract.served_bits, has_data, serve, fly_leg))
