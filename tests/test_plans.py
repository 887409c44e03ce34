"""The planner's batched look-ahead: a batch equals its plans one at a time; compiled == Python."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine_cases import assert_logs_equal
from skymule.experiments.layouts import random_autonomous_scenario
from skymule.policies import planner as planner_module
from skymule.policies.planner import Planner
from skymule.scenario import load_scenario
from skymule.sim import compiled, plans
from skymule.sim.run import run_mission
from skymule.world import build_mission


def random_plans(rng: np.random.Generator, n: int, count: int) -> tuple[list, dict]:
    """``count`` random plans over ``n`` hover points, and a random leg table for them."""
    orders = [
        tuple(int(i) for i in rng.permutation(n)[: int(rng.integers(0, n + 1))])
        for _ in range(count)
    ]
    extras = [rng.integers(0, 6, len(order)) for order in orders]
    n_legs = 6
    slots = rng.integers(0, 5, n_legs)
    slots[0] = 0  # leg 0: no leg
    has_rates = rng.random(n_legs) < 0.8
    rows = np.concatenate([[0], np.cumsum(np.maximum(slots - 1, 0))[:-1]])
    leg_rates = rng.choice([0.0, 1e6, 2e6, 2e6, np.nan], size=(int(rows[-1] + slots[-1]) + 1, n))
    legs = [rng.integers(0, n_legs, len(order) + 1) for order in orders]
    table = {
        "slot": int(rng.integers(0, 5)),
        "n_slots": int(rng.integers(5, 40)),
        "slot_s": float(rng.choice([0.5, 1.0])),
        "return_home": bool(rng.integers(2)),
        "remaining": rng.choice([0.0, 1e6, 5e6, 2e7], size=n),
        "start_rates": rng.choice([0.0, 1e6, 3e6], size=n),
        "hover_rates": rng.choice([0.0, 2e6, 4e6], size=(n, n)),
        "home_rates": rng.choice([0.0, 1e6], size=n),
        "leg_slots": slots.astype(np.int64),
        "leg_has_rates": has_rates,
        "leg_row": rows.astype(np.int64),
        "leg_rates": leg_rates,
    }
    return [orders, extras, legs], table


def run_plans(kernel, orders, extras, legs, table) -> tuple[np.ndarray, ...]:
    lengths = np.array([len(o) for o in orders], np.int64)
    first = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    stops = int(lengths.sum())
    bits, done, arrival = np.zeros(len(orders)), np.zeros(len(orders), np.int64), np.zeros(stops)
    kernel(
        *table.values(),
        np.array([i for o in orders for i in o], np.int64),
        np.concatenate([np.zeros(0, np.int64), *extras]).astype(np.int64),
        first,
        lengths,
        np.concatenate(legs).astype(np.int64),
        bits,
        done,
        arrival,
    )
    return bits, done, arrival


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), count=st.integers(1, 8))
def test_a_batch_of_plans_equals_each_plan_alone(seed, n, count):
    rng = np.random.default_rng(seed)
    (orders, extras, legs), table = random_plans(rng, n, count)
    kernel = plans.plans_kernel()
    together = run_plans(kernel, orders, extras, legs, table)
    at = 0
    for p in range(count):
        alone = run_plans(kernel, [orders[p]], [extras[p]], [legs[p]], table)
        assert alone[0][0] == together[0][p] or np.isnan(together[0][p])
        assert alone[1][0] == together[1][p]
        np.testing.assert_array_equal(alone[2], together[2][at : at + len(orders[p])])
        at += len(orders[p])
    # buffers only shrink: no plan downloads more than was buffered
    assert np.all(~(together[0] > table["remaining"].sum() * (1 + 1e-12)))


@pytest.mark.skipif(not compiled.available(), reason="numba not installed")
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), count=st.integers(1, 8))
def test_compiled_plans_equal_plain_python(seed, n, count):
    rng = np.random.default_rng(seed)
    (orders, extras, legs), table = random_plans(rng, n, count)
    got = run_plans(plans.plans_kernel(), orders, extras, legs, table)
    want = run_plans(plans.simulate_plans, orders, extras, legs, table)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b, strict=True)


@pytest.mark.skipif(not compiled.available(), reason="numba not installed")
def test_planner_runs_the_same_with_and_without_the_compiler(monkeypatch):
    """Whole missions (the preset and random layouts): identical logs, slot for slot."""
    base = load_scenario("paper-sim-autonomous")
    rng = np.random.default_rng(11)
    scenarios = [base, *(random_autonomous_scenario(rng, base) for _ in range(3))]
    missions = [build_mission(s) for s in scenarios]
    fast = [run_mission(m, Planner()) for m in missions]
    monkeypatch.setattr(planner_module, "plans_kernel", lambda: plans.simulate_plans)
    for mission, log in zip(missions, fast, strict=True):
        assert_logs_equal(log, run_mission(mission, Planner()))


@pytest.mark.parametrize("kernel", ["python", "compiled"])
def test_look_ahead_matches_a_hand_worked_case(kernel):
    """An independent reference: two plans on two sensors, worked out slot by slot by hand
    from the rules (serve the stop while it has data, else the best rate with data, ties to
    the lowest index; y = min(R dt, Q); a stay that empties its buffer is the departure slot).

    Plan A: fly leg 1 (3 slots) to hover point 0, stay 2 slots, fly leg 2 (2 slots) home.
      t=0 departure at the start's rates [1, 0] Mbit/s: sensor 0, Q0 3 -> 2 Mbit;
      t=1 en route [0, 1]: sensor 1, Q1 2 -> 1;  t=2 en route [0.5, 0.5]: tie, sensor 0, Q0 -> 1.5;
      arrival at point 0 with Q0 = 1.5; t=3 stay at [2, 1]: Q0 -> 0 (emptied: departs in t=3);
      leg home: t=3 departs (nothing left at point 0's zero rates), t=4 en route [0, 1]: Q1 -> 0:
      everything (5 Mbit) downloaded by the end of slot 4, done = 5.
    Plan B: straight home (leg 3, 1 slot), then serve at home's rates [0, 1] to the end:
      t=0 sensor 0 (Q0 -> 2), t=1 and t=2 sensor 1 (Q1 -> 0); Q0 stays 2 (rate 0 at home):
      3 Mbit, never done (done = n_slots = 10).
    """
    if kernel == "compiled" and not compiled.available():
        pytest.skip("numba not installed")
    mbit = 1e6
    table = {
        "slot": 0,
        "n_slots": 10,
        "slot_s": 1.0,
        "return_home": True,
        "remaining": np.array([3.0, 2.0]) * mbit,
        "start_rates": np.array([1.0, 0.0]) * mbit,
        "hover_rates": np.array([[2.0, 1.0], [0.0, 1.0]]) * mbit,
        "home_rates": np.array([0.0, 1.0]) * mbit,
        "leg_slots": np.array([0, 3, 2, 1], np.int64),
        "leg_has_rates": np.array([False, True, True, False]),
        "leg_row": np.array([0, 0, 2, 0], np.int64),
        "leg_rates": np.array([[0.0, 1.0], [0.5, 0.5], [0.0, 1.0]]) * mbit,
    }
    orders, extras = [(0,), ()], [np.array([2]), np.array([], np.int64)]
    legs = [np.array([1, 2]), np.array([3])]
    run = plans.plans_kernel() if kernel == "compiled" else plans.simulate_plans
    bits, done, arrival = run_plans(run, orders, extras, legs, table)
    np.testing.assert_array_equal(bits, [5.0 * mbit, 3.0 * mbit])
    np.testing.assert_array_equal(done, [5, 10])
    np.testing.assert_array_equal(arrival, [1.5 * mbit])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6))
def test_serve_picks_as_rate_choice(seed, n):
    """The look-ahead's serve (no stop to prefer) is the contract's ``rate_choice``."""
    from skymule.rules import contract

    rng = np.random.default_rng(seed)
    q = rng.choice([0.0, 1e6, 3e6], size=n)
    rates = rng.choice([0.0, 1e6, 2e6, 2e6, 5e6], size=n)
    want = int(contract.rate_choice(rates[:, None], contract.servable(rates, q)[:, None])[0])
    left = q.copy()
    plans.serve(left, rates, -1, 1.0, 0, 10, 0.0, 10)
    served = np.flatnonzero(left != q)
    assert served.tolist() == ([] if want == contract.NO_SENSOR else [want])
