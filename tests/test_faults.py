"""Fault models on hand-worked cases (issue 15): what each one marks, and its long-run law."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skymule.energy import propulsion_power_w
from skymule.errors import ScenarioError
from skymule.faults import (
    Battery,
    FaultDraws,
    Wind,
    draw_faults,
    fault_rng,
    no_faults,
    stack_draws,
)
from skymule.faults.models import stationary_bad_share, two_state_chain
from skymule.faults.motion import leg_seconds
from skymule.radio.rates import BUILTIN_RATE_TABLES
from skymule.scenario import load_scenario
from skymule.sim.batch_faults import BatchFaults, apply_faults

NAMES = ("LW1", "LW2", "LW3", "LW4")


@dataclass(frozen=True)
class Entry:
    kind: str
    params: dict[str, Any] = field(default_factory=dict)


def _draw(*entries: Entry, n_slots: int = 500, slot_s: float = 1.0, seed: int = 7) -> FaultDraws:
    return draw_faults(list(entries), n_slots, NAMES, slot_s, fault_rng(seed))


def _seen_snr_db(draws: FaultDraws, true_snr_db: np.ndarray) -> np.ndarray:
    """(T, N) the SNR a policy sees under ``draws`` in each slot: the engines' fault view
    (``sim.batch_faults.apply_faults``) of one mission."""
    table = BUILTIN_RATE_TABLES["aadm-lte-cqi"]
    faults = BatchFaults(
        np.zeros(1, np.int64), draws.deliverable()[None], draws.snr_error_db[None],
        np.zeros(1, np.int64), ((table, 1.4e6),),
    )  # fmt: skip
    rate = np.zeros((len(NAMES), 1))
    return np.stack(
        [
            apply_faults(faults, t, rate, true_snr_db[t][:, None])[1][:, 0]
            for t in range(len(true_snr_db))
        ]
    )


# --- outages -------------------------------------------------------------------------------


def test_fixed_outage_marks_exactly_its_slots_of_that_tower() -> None:
    draws = _draw(Entry("outage", {"sensors": ["LW2"], "start_s": 100, "duration_s": 60}))
    expected = np.zeros((500, 4), dtype=bool)
    expected[100:160, 1] = True
    assert np.array_equal(draws.outage, expected)
    assert np.array_equal(draws.link_up, ~expected)
    served_ok = draws.deliverable()
    assert not served_ok[100:160, 1].any() and served_ok[:, [0, 2, 3]].all()


def test_outage_window_uses_slot_start_times() -> None:
    # 2-s slots: slot t starts at 2t; the window [101, 161) covers starts 102..160 -> t = 51..80
    draws = _draw(Entry("outage", {"start_s": 101, "duration_s": 60}), n_slots=100, slot_s=2.0)
    down = np.flatnonzero(draws.outage[:, 0])
    assert down.tolist() == list(range(51, 81))
    assert (draws.outage == draws.outage[:, :1]).all()  # every tower when none is listed


def test_random_outages_have_their_mean_length() -> None:
    params = {"sensors": ["LW1"], "mean_duration_s": 20.0, "windows": 1}
    draws = [_draw(Entry("outage", params), n_slots=2000, seed=s) for s in range(300)]
    lengths = [int(d.outage[:, 0].sum()) for d in draws]
    # exponential(20 s) windows placed uniformly over 2000 s: few are cut by the end
    assert np.mean(lengths) == pytest.approx(20.0, rel=0.15)
    assert all(not d.outage[:, 1:].any() for d in draws)


# --- Gilbert-Elliott -----------------------------------------------------------------------


@pytest.mark.parametrize(("p", "r"), [(0.1, 0.1), (0.3, 0.45)])
def test_gilbert_elliott_long_run_loss_is_stationary_value(p: float, r: float) -> None:
    entry = Entry("gilbert-elliott", {"p_good_to_bad": p, "p_bad_to_good": r, "sensors": ["LW3"]})
    draws = draw_faults([entry], 1_000_000, NAMES, 1.0, fault_rng(3))
    lost = draws.burst_loss[:, 2]
    assert lost.mean() == pytest.approx(p / (p + r), rel=0.01)
    assert not draws.burst_loss[:, [0, 1, 3]].any()
    # bursts: bad runs last 1/r slots on average (geometric sojourns, not i.i.d. losses)
    edges = np.diff(np.r_[0, lost.astype(np.int8), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    assert runs.mean() == pytest.approx(1.0 / r, rel=0.03)


def test_two_state_chain_matches_a_slot_by_slot_chain_in_law() -> None:
    """P(bad at t+1 | bad at t) = 1 - r and P(bad at t+1 | good at t) = p."""
    p, r = 0.2, 0.35
    bad = two_state_chain(np.random.default_rng(11), p, r, (50, 20_000))
    now, nxt = bad[:, :-1].ravel(), bad[:, 1:].ravel()
    assert nxt[now].mean() == pytest.approx(1 - r, abs=0.01)
    assert nxt[~now].mean() == pytest.approx(p, abs=0.01)
    assert bad[:, 0].mean() == pytest.approx(stationary_bad_share(p, r), abs=0.1)


def test_partial_loss_in_each_state() -> None:
    params = {"p_good_to_bad": 0.5, "p_bad_to_good": 0.5, "loss_good": 0.1, "loss_bad": 0.5}
    draws = _draw(Entry("gilbert-elliott", params), n_slots=200_000)
    assert draws.burst_loss.mean() == pytest.approx(0.5 * 0.1 + 0.5 * 0.5, abs=0.005)


# --- what the policy sees ------------------------------------------------------------------


def test_snr_error_changes_only_what_is_seen() -> None:
    true_snr = np.random.default_rng(0).uniform(-5, 30, (5000, 4))
    draws = _draw(Entry("snr-error", {"bias_db": -3.0, "std_db": 4.0}), n_slots=5000)
    assert draws.deliverable().all()  # no data is lost: the accounting is untouched
    error = _seen_snr_db(draws, true_snr) - true_snr
    assert np.allclose(error, draws.snr_error_db, rtol=0, atol=1e-12)
    assert error.mean() == pytest.approx(-3.0, abs=0.1)
    assert error.std() == pytest.approx(4.0, rel=0.03)
    assert draws.affected.all()


def test_correlated_errors_have_the_asked_correlation() -> None:
    params = {"std_m": 5.0, "correlation_s": 10.0, "bias_m": [1.0, -2.0]}
    draws = _draw(Entry("gps-error", params), n_slots=100_000, slot_s=2.0)
    noise = draws.gps_error_m - np.array([1.0, -2.0])
    assert noise.std(axis=0) == pytest.approx([5.0, 5.0], rel=0.05)
    lag1 = np.corrcoef(noise[:-1, 0], noise[1:, 0])[0, 1]
    assert lag1 == pytest.approx(math.exp(-2.0 / 10.0), abs=0.02)
    assert not draws.outage.any() and not draws.snr_error_db.any()


def test_observed_snr_is_minus_inf_where_nothing_can_be_delivered() -> None:
    draws = _draw(
        Entry("outage", {"sensors": ["LW1"], "start_s": 0, "duration_s": 10}),
        Entry("missed-polls", {"probability": 0.2}),
        n_slots=1000,
    )
    seen = _seen_snr_db(draws, np.full((1000, 4), 12.0))
    assert np.isneginf(seen[:10, 0]).all()
    assert np.isneginf(seen[draws.poll_missed]).all()
    open_slots = ~draws.poll_missed
    assert (seen[open_slots, 1:] == 12.0).all()
    assert draws.poll_missed.mean() == pytest.approx(0.2, abs=0.04)


def test_bursty_missed_polls() -> None:
    params = {"p_good_to_bad": 0.05, "p_bad_to_good": 0.2}
    draws = _draw(Entry("missed-polls", params), n_slots=400_000)
    assert draws.poll_missed.mean() == pytest.approx(0.2, rel=0.05)
    assert draws.link_up.all()


# --- wind and battery ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("from_deg", "speed", "step", "expected"),
    [
        (90.0, 5.0, (10.0, 0.0), (5.0, 0.0)),  # headwind from the east halves 10 m/s east
        (270.0, 5.0, (10.0, 0.0), (10.0, 0.0)),  # tailwind: never faster than commanded
        (0.0, 6.0, (10.0, 0.0), (8.0, 0.0)),  # crosswind: sqrt(10^2 - 6^2) along the course
        (90.0, 5.0, (3.0, 0.0), (3.0, 0.0)),  # short step still reachable against the wind
        (90.0, 5.0, (0.0, 0.0), (0.0, 0.0)),  # holding position
        (0.0, 5.0, (0.0, 20.0), (0.0, 10.0)),  # 2-s slot north into a northerly: 5 m/s
    ],
)
def test_wind_achieved_step(
    from_deg: float, speed: float, step: tuple[float, float], expected: tuple[float, float]
) -> None:
    slot_s = 2.0 if step == (0.0, 20.0) else 1.0
    achieved = Wind(speed, from_deg).achieved_step_m(np.array(step), slot_s, 10.0)
    assert achieved == pytest.approx(expected, abs=1e-9)


def test_wind_is_vectorised_over_steps() -> None:
    steps = np.array([[10.0, 0.0], [-10.0, 0.0], [0.0, 10.0]])
    achieved = Wind(5.0, 90.0).achieved_step_m(steps, 1.0, 10.0)
    assert achieved[:, 0] == pytest.approx([5.0, -10.0, 0.0])
    assert achieved[2, 1] == pytest.approx(math.sqrt(75.0))


def test_battery_allows_a_move_only_if_the_way_home_still_fits() -> None:
    battery = Battery(capacity_j=3600.0 * 10, reserve_fraction=0.5, return_speed_mps=10.0)
    hover = float(propulsion_power_w(0.0))
    cruise = float(propulsion_power_w(10.0))
    distance = 600.0  # 60 s home at 10 m/s
    home_j = float(battery.return_energy_j(distance))
    assert home_j == pytest.approx(cruise * 60.0)
    limit = 18000.0 - home_j - cruise  # one more slot out at 10 m/s, then the way home
    assert battery.affords(limit - 1.0, cruise, home_j)
    assert not battery.affords(limit + 0.5, cruise, home_j)
    flags = battery.affords(np.array([0.0, limit + 0.5]), cruise, np.array([home_j] * 2))
    assert flags.tolist() == [True, False]
    assert battery.exhausted(18000.0) and not battery.exhausted(17999.0)
    assert battery.slot_energy_j(0.0, 2.0) == pytest.approx(2 * hover)


def test_flight_energy_is_each_legs_power_for_its_time_then_hover() -> None:
    battery = Battery(capacity_j=3600.0)
    bent = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 5.0]])
    speeds = np.array([10.0, 5.0])
    p10, p5, hover = (float(propulsion_power_w(v)) for v in (10.0, 5.0, 0.0))
    assert leg_seconds(bent, 2.0, speeds) == pytest.approx([2.0, 0.0])
    assert leg_seconds(bent, 3.5, speeds) == pytest.approx([3.0, 0.5])
    assert leg_seconds(bent, 6.0, speeds) == pytest.approx([3.0, 1.0])  # ends after 4 s
    assert battery.flight_energy_j(bent, 3.5, speeds) == pytest.approx(3 * p10 + 0.5 * p5)
    assert battery.flight_energy_j(bent, 6.0, speeds) == pytest.approx(3 * p10 + p5 + 2 * hover)
    landing = battery.flight_energy_j(bent, 6.0, speeds, hover_rest=False)
    assert landing == pytest.approx(3 * p10 + p5)
    # a whole path flown, landing at its end, costs what the way is priced at
    assert landing == pytest.approx(battery.path_energy_j(bent, speeds))


# --- drawing: seeds, independence, batches -------------------------------------------------


def test_no_faults_draws_nothing_and_leaves_the_generator_alone() -> None:
    rng = fault_rng(5)
    before = rng.bit_generator.state
    draws = draw_faults([], 300, NAMES, 1.0, rng)
    assert rng.bit_generator.state == before
    assert draws.is_empty and not draws.affected.any()
    assert np.array_equal(draws.link_up, no_faults(300, 4).link_up)


def test_same_seed_same_draws_and_entries_draw_independently() -> None:
    ge = Entry("gilbert-elliott", {"p_good_to_bad": 0.1, "p_bad_to_good": 0.3})
    noise = Entry("snr-error", {"std_db": 2.0})
    first = _draw(ge, noise, seed=9)
    assert np.array_equal(first.burst_loss, _draw(ge, noise, seed=9).burst_loss)
    assert not np.array_equal(first.burst_loss, _draw(ge, noise, seed=10).burst_loss)
    # removing the second entry leaves the first's draws as they were
    assert np.array_equal(first.burst_loss, _draw(ge, seed=9).burst_loss)


def test_stacked_draws_round_trip_and_are_read_only() -> None:
    ge = Entry("gilbert-elliott", {"p_good_to_bad": 0.1, "p_bad_to_good": 0.3})
    each = [_draw(ge, seed=s) for s in range(3)]
    batch = stack_draws(each)
    assert batch.link_up.shape == (3, 500, 4) and batch.affected.shape == (3, 500)
    assert np.array_equal(batch.mission(1).burst_loss, each[1].burst_loss)
    with pytest.raises(ValueError, match="read-only"):
        each[0].burst_loss[0, 0] = True


def test_uav_faults_become_objects() -> None:
    draws = _draw(
        Entry("wind", {"speed_mps": 4.0, "from_deg": 270.0}),
        Entry("battery", {"capacity_wh": 50.0}),
    )
    assert draws.wind == Wind(4.0, 270.0) and draws.wind.vector_mps == pytest.approx([4.0, 0.0])
    assert draws.battery is not None and draws.battery.capacity_j == 50.0 * 3600
    assert not draws.is_empty and not draws.affected.any()


# --- the [[faults]] section of a scenario --------------------------------------------------

BASE = """
name = "f"
[trajectory]
speed_mps = 10.0
[[sensors]]
name = "A"
x_m = 0
y_m = 0
buffer_mbit = 10
[[sensors]]
name = "B"
x_m = 100
y_m = 0
buffer_mbit = 10
"""


def _scenario(tmp_path: Path, faults: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(BASE + faults)
    return path


def test_scenario_faults_load_and_draw(tmp_path: Path) -> None:
    scenario = load_scenario(
        _scenario(
            tmp_path,
            '[[faults]]\nkind = "outage"\nparams = { sensors = ["B"], start_s = 5, '
            "duration_s = 3 }\n",
        )
    )
    assert scenario.faults is not None and scenario.faults[0].kind == "outage"
    names = [s.name for s in scenario.sensors]
    draws = draw_faults(scenario.faults, 10, names, 1.0, fault_rng(scenario.seed))
    assert np.flatnonzero(draws.outage[:, 1]).tolist() == [5, 6, 7]
    assert "faults" in scenario.to_toml_dict()


def test_presets_have_no_faults_and_serialise_as_before() -> None:
    scenario = load_scenario("paper-sim-fixed")
    assert scenario.faults is None and "faults" not in scenario.to_toml_dict()


@pytest.mark.parametrize(
    ("faults", "expected"),
    [
        ('kind = "hail"', "faults[0]: kind = 'hail' is not a fault; allowed: outage,"),
        (
            'kind = "gilbert-elliott"\nparams = { p_good_to_bad = 1.5, p_bad_to_good = 0.1 }',
            "faults[0]: gilbert-elliott: params.p_good_to_bad = 1.5: Input should be less",
        ),
        (
            'kind = "gilbert-elliott"\nparams = { p_good_to_bad = "0.1", p_bad_to_good = 0.1 }',
            "params.p_good_to_bad = '0.1': must be a number",
        ),
        ('kind = "snr-error"\nparams = { std = 3 }', "snr-error: unknown parameter 'params.std'"),
        ('kind = "outage"\nparams = { start_s = 3 }', "give exactly one of duration_s"),
        (
            'kind = "outage"\nparams = { sensors = ["C"], duration_s = 3 }',
            "faults[0] (outage): sensor 'C' is not in the scenario; allowed: A, B",
        ),
        ('kind = "wind"\nparams = { speed_mps = 12 }', "must be below the UAV's speed (10.0"),
        ('kind = "missed-polls"\nparams = { p_good_to_bad = 0.1 }', "need both p_good_to_bad"),
        ('kind = "battery"', "battery: params.capacity_wh is required"),
        (
            'kind = "battery"\nparams = { capacity_wh = 1 }',  # ignored there, so refused
            "faults[0] (battery): a battery limit needs trajectory.mode = 'autonomous'",
        ),
    ],
)
def test_bad_fault_entries_are_one_line(tmp_path: Path, faults: str, expected: str) -> None:
    with pytest.raises(ScenarioError) as caught:
        load_scenario(_scenario(tmp_path, f"[[faults]]\n{faults}\n"))
    assert expected in str(caught.value) and "\n" not in str(caught.value)


def test_one_battery_only(tmp_path: Path) -> None:
    battery = '[[faults]]\nkind = "battery"\nparams = { capacity_wh = 10 }\n'
    autonomous = 'trajectory.mode = "autonomous"\n'
    with pytest.raises(ScenarioError, match="at most one 'battery' entry"):
        load_scenario(_scenario(tmp_path, battery * 2), [autonomous.strip()])
    assert load_scenario(_scenario(tmp_path, battery), [autonomous.strip()]).faults


# --- any valid parameters draw, quickly, arrays of the documented shapes ---------------------

probabilities = st.one_of(st.sampled_from([0.0, 5e-324, 1e-300, 1e-6, 0.5, 1.0]), st.floats(0, 1))
seconds = st.one_of(st.sampled_from([0.0, 1e-9, 0.5, 3.0, 1e7]), st.floats(0, 1e7))
fault_entries = st.one_of(
    st.builds(
        lambda start, length, mean, windows: Entry(
            "outage",
            {"windows": windows}
            | ({"duration_s": length} if mean is None else {"mean_duration_s": mean})
            | ({} if start is None or windows != 1 else {"start_s": start}),
        ),
        st.none() | seconds,
        seconds.filter(lambda s: s > 0),
        st.none() | seconds.filter(lambda s: s > 0),
        st.integers(1, 4),
    ),
    st.builds(
        lambda p, r, g, b: Entry(
            "gilbert-elliott",
            {"p_good_to_bad": p, "p_bad_to_good": r, "loss_good": g, "loss_bad": b},
        ),
        probabilities,
        probabilities,
        probabilities,
        probabilities,
    ).filter(lambda e: e.params["p_good_to_bad"] + e.params["p_bad_to_good"] > 0),
    st.builds(
        lambda bias, std, corr: Entry(
            "snr-error", {"bias_db": bias, "std_db": std, "correlation_s": corr}
        ),
        st.floats(-100, 100),
        st.floats(0, 100),
        seconds,
    ),
    st.builds(lambda p: Entry("missed-polls", {"probability": p}), probabilities),
    st.builds(
        lambda p, r: Entry("missed-polls", {"p_good_to_bad": p, "p_bad_to_good": r}),
        probabilities,
        probabilities,
    ).filter(lambda e: e.params["p_good_to_bad"] + e.params["p_bad_to_good"] > 0),
    st.builds(
        lambda std, corr: Entry("gps-error", {"std_m": std, "correlation_s": corr}),
        st.floats(0, 1e4),
        seconds,
    ),
)


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(
    st.lists(fault_entries, max_size=4),
    st.integers(0, 300),
    st.sampled_from([1e-12, 0.01, 1.0, 7.5]),
)
def test_any_valid_faults_draw_arrays_of_the_documented_shapes(
    entries: list[Entry], n_slots: int, slot_s: float
) -> None:
    draws = _draw(*entries, n_slots=n_slots, slot_s=slot_s)
    assert draws.link_up.shape == draws.snr_error_db.shape == (n_slots, 4)
    assert draws.poll_missed.shape == (n_slots,) and draws.gps_error_m.shape == (n_slots, 2)
    assert np.isfinite(draws.snr_error_db).all() and np.isfinite(draws.gps_error_m).all()
