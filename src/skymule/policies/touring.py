"""The tour planner's building blocks (:mod:`skymule.policies.planner`): how many slots a leg
takes, visiting orders (Held-Karp over subsets, nearest neighbour + 2-opt), hover slots shared
by a fractional knapsack, and leg speeds under an estimated wind.

Held-Karp: M. Held and R. M. Karp, "A dynamic programming approach to sequencing problems",
J. SIAM 10(1), 1962. 2-opt: G. A. Croes, "A method for solving traveling-salesman problems",
Operations Research 6(6), 1958.
"""

from __future__ import annotations

import itertools

import numpy as np

from skymule.faults.motion import wind_triangle_ground_speed_mps
from skymule.rules.contract import served_bits, slots_to_cover

#: Positions closer than this [m] count as the same point.
SAME_POINT_M = 1e-6


def leg_slots(distance_m: float, step_m: float) -> int:
    """Slots to fly ``distance_m`` [m] at ``step_m`` [m] per slot: ceil(L / s)."""
    return int(slots_to_cover(distance_m, step_m)) if distance_m > SAME_POINT_M else 0


def allocate_hover(
    rate_bps: np.ndarray, need_bit: np.ndarray, budget_slots: int, slot_s: float
) -> np.ndarray:
    """(k,) extra slots per target: fractional knapsack by rate (highest first).

    ``rate_bps`` (k,) hover rates, ``need_bit`` (k,) bits left after the free departure slot.
    """
    extra = np.zeros(len(rate_bps), int)
    left = max(int(budget_slots), 0)
    for j in np.argsort(-rate_bps, kind="stable"):
        if left <= 0:
            break
        if rate_bps[j] <= 0 or need_bit[j] <= 0:
            continue
        want = int(slots_to_cover(need_bit[j], rate_bps[j] * slot_s))
        extra[j] = min(want, left)
        left -= extra[j]
    return extra


def knapsack_bits(
    rate_bps: np.ndarray, buffer_bit: np.ndarray, budget: int, slot_s: float
) -> float:
    """Bits from hovering: one free slot per target plus the knapsack's extra slots."""
    first = served_bits(rate_bps, buffer_bit, slot_s)
    extra = allocate_hover(rate_bps, buffer_bit - first, budget, slot_s)
    return float(served_bits(rate_bps, buffer_bit, slot_s * (1 + extra)).sum())


def held_karp(
    start: np.ndarray, pair: np.ndarray, end: np.ndarray
) -> tuple[np.ndarray, list[list[int]]]:
    """Fewest slots from here through every subset of targets and then to ``end``.

    ``start`` (n,), ``pair`` (n, n) and ``end`` (n,) are leg slot counts. Returns
    ``(cost (2^n,), order per subset)``; subset 0 costs 0 (go straight to the end; its cost is
    the caller's).
    """
    n = len(start)
    size = 1 << n
    dp = np.full((size, n), np.inf)
    parent = np.full((size, n), -1, int)
    for j in range(n):
        dp[1 << j, j] = start[j]
    for mask in range(1, size):
        row = dp[mask]
        for j in range(n):
            if not (mask >> j) & 1 or not np.isfinite(row[j]):
                continue
            for k in range(n):
                if (mask >> k) & 1:
                    continue
                new = mask | (1 << k)
                cost = row[j] + pair[j, k]
                if cost < dp[new, k]:
                    dp[new, k] = cost
                    parent[new, k] = j
    cost = np.zeros(size)
    orders: list[list[int]] = [[]]
    for mask in range(1, size):
        total = dp[mask] + end
        last = int(np.argmin(total))
        cost[mask] = total[last]
        order, current, node = [], mask, last
        while node >= 0:
            order.append(node)
            previous = int(parent[current, node])
            current &= ~(1 << node)
            node = previous
        orders.append(order[::-1])
    return cost, orders


def two_opt_order(start: np.ndarray, pair: np.ndarray, end: np.ndarray) -> list[int]:
    """Nearest-neighbour order from here, improved by 2-opt (segment reversals)."""
    n = len(start)
    left = set(range(n))
    order: list[int] = []
    costs = start
    while left:
        nxt = min(left, key=lambda k: costs[k])
        order.append(nxt)
        left.remove(nxt)
        costs = pair[nxt]

    def total(seq: list[int]) -> float:
        legs = sum(pair[a, b] for a, b in itertools.pairwise(seq))
        return float(start[seq[0]] + legs + end[seq[-1]])

    best = total(order)
    improved = True
    while improved:
        improved = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                trial = order[:i] + order[i : j + 1][::-1] + order[j + 1 :]
                cost = total(trial)
                if cost < best - 1e-9:
                    order, best, improved = trial, cost, True
    return order


def ground_speed_mps(direction: np.ndarray, wind_mps: np.ndarray, speed_mps: float) -> np.ndarray:
    """(K,) ground speed [m/s] along each (K, 2) direction under the wind ``wind_mps`` (2,).

    The wind triangle of ``docs/faults.md``: at most ``speed_mps`` (the commanded speed; a
    tailwind never speeds the UAV up), ``u.w + sqrt(V^2 - |w|^2 + (u.w)^2)`` with airspeed
    V = ``speed_mps``; never below 1 % of V, so that a leg always ends.
    """
    length = np.hypot(direction[:, 0], direction[:, 1])
    unit = direction / np.maximum(length, 1e-12)[:, None]
    reachable = wind_triangle_ground_speed_mps(unit, wind_mps, speed_mps)
    return np.clip(reachable, 0.01 * speed_mps, speed_mps)
