"""The autonomous ``planner`` policy: search pieces, invariants, gains over HGAD."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from conftest import preset_mission
from skymule.bounds.autonomous import autonomous_bound
from skymule.errors import SkymuleError
from skymule.metrics.summary import aadm_score, completion_time_s
from skymule.policies import HGAD, make_policy
from skymule.policies.planner import Planner, allocate_hover, held_karp, two_opt_order
from skymule.scenario import load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission
from test_autonomous import _assert_invariants
from test_autonomous_bound import random_scenario

PRESET = "paper-sim-autonomous"


def _brute_force(start, pair, end, mask):
    members = [j for j in range(len(start)) if (mask >> j) & 1]
    best = np.inf
    for order in itertools.permutations(members):
        cost = start[order[0]] + sum(pair[a, b] for a, b in itertools.pairwise(order))
        best = min(best, cost + end[order[-1]])
    return best


def test_held_karp_matches_brute_force_over_every_subset():
    rng = np.random.default_rng(3)
    n = 5
    pts = rng.uniform(0, 100, (n + 2, 2))
    dist = np.ceil(np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1)))
    start, pair, end = dist[n, :n], dist[:n, :n], dist[n + 1, :n]
    cost, orders = held_karp(start, pair, end)
    for mask in range(1, 1 << n):
        assert cost[mask] == pytest.approx(_brute_force(start, pair, end, mask))
        order = orders[mask]
        assert sorted(order) == [j for j in range(n) if (mask >> j) & 1]
        travel = start[order[0]] + sum(pair[a, b] for a, b in itertools.pairwise(order))
        assert travel + end[order[-1]] == pytest.approx(cost[mask])
    heuristic = two_opt_order(start, pair, end)
    travel = start[heuristic[0]] + sum(pair[a, b] for a, b in itertools.pairwise(heuristic))
    assert travel + end[heuristic[-1]] <= cost[-1] * 1.2


def test_hover_allocation_is_a_rate_ordered_knapsack():
    rates = np.array([1.0, 3.0, 2.0])
    need = np.array([10.0, 6.0, 100.0])
    # the fastest sensor first (2 slots), then the next (the 8 slots left)
    assert allocate_hover(rates, need, 10, 1.0).tolist() == [0, 2, 8]
    assert allocate_hover(rates, need, 0, 1.0).tolist() == [0, 0, 0]


def test_planner_finishes_the_preset_sooner_than_hgad():
    """HGAD already gets all 3000 Mbit here: the planner gets them too, sooner."""
    mission = preset_mission(PRESET)
    hgad, planner = run_mission(mission, HGAD()), run_mission(mission, Planner())
    _assert_invariants(mission, planner)
    assert planner.downloaded_bit.sum() == pytest.approx(3000e6)
    assert completion_time_s(planner) < completion_time_s(hgad)
    assert aadm_score(planner) > aadm_score(hgad)


@pytest.mark.parametrize(
    "update",
    [{"duration_s": 300.0}, {"buffers": (1500, 1500, 1500, 1500)}],
    ids=["300s", "1500Mbit"],
)
def test_planner_beats_hgad_where_not_everything_fits(update):
    scenario = load_scenario(PRESET)
    changes = {}
    if "duration_s" in update:
        changes["mission"] = scenario.mission.model_copy(update=update)
    else:
        changes["sensors"] = [
            s.model_copy(update={"buffer_mbit": float(b)})
            for s, b in zip(scenario.sensors, update["buffers"], strict=True)
        ]
    mission = build_mission(scenario.model_copy(update=changes))
    bound = autonomous_bound(mission).upper_bound_bit
    hgad = run_mission(mission, HGAD()).downloaded_bit.sum()
    log = run_mission(mission, Planner())
    _assert_invariants(mission, log)
    assert hgad < log.downloaded_bit.sum() <= bound * (1 + 1e-9)


def test_planner_keeps_every_invariant_on_random_missions():
    rng = np.random.default_rng(11)
    for case in range(6):
        scenario = random_scenario(rng)
        if case % 2:  # observations depart from the (fading-free) prediction: re-planning
            scenario = scenario.model_copy(
                update={"radio": scenario.radio.model_copy(update={"fading": "rayleigh"})}
            )
        mission = build_mission(scenario)
        log = run_mission(
            mission, make_policy(scenario.policy.model_copy(update={"name": "planner"}))
        )
        if scenario.trajectory.return_home:
            _assert_invariants(mission, log)
        assert (log.remaining_bit >= 0).all()


def test_many_sensors_use_the_heuristic_search():
    rng = np.random.default_rng(1)
    mission = build_mission(random_scenario(rng, n_sensors=9))
    log = run_mission(mission, Planner(exact_max=7))
    assert log.downloaded_bit.sum() <= autonomous_bound(mission).upper_bound_bit * (1 + 1e-9)
    if mission.scenario.trajectory.return_home:
        _assert_invariants(mission, log)


def test_planner_on_a_fixed_path_is_a_one_line_error():
    mission = preset_mission("paper-sim-fixed")
    with pytest.raises(SkymuleError) as info:
        run_mission(mission, Planner())
    assert "autonomous" in str(info.value) and "\n" not in str(info.value)
